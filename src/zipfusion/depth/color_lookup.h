#pragma once
//! \file
//! Per-vertex colour (paper Section III-B): each depth pixel's 3-D point is projected into the
//! colour camera (color_from_depth, colour intrinsics and distortion) and the colour image is
//! sampled bilinearly. Points outside the colour image, and cameras without colour, get grey.

#include <algorithm>
#include <cstdint>
#include <vector>

#include "zipfusion/core/image.h"
#include "zipfusion/depth/sdc_mesh.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

inline constexpr Rgb8 kNoColor{128, 128, 128};

//! One channel of the bilinear mix of pixels a, b (to its right), c (below a) and d, with the
//! weights wx, wy in 1/256ths: in integers, rounded to nearest (sample_bilinear and its row kernel).
inline int bilinear_mix(int a, int b, int c, int d, int wx, int wy) {
  const int top = a * 256 + wx * (b - a), bottom = c * 256 + wx * (d - c);
  return (top * 256 + wy * (bottom - top) + 32768) >> 16;
}

//! Element function: bilinear sample at (x, y) (pixel centres at integers); kNoColor outside.
//! Fixed point: the weights in 1/256ths, as exact as the 8-bit channels they mix.
inline Rgb8 sample_bilinear(const ColorImage& image, float x, float y) {
  if (!(x >= 0.0f && y >= 0.0f && x <= image.width - 1.0f && y <= image.height - 1.0f)) return kNoColor;
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = x0 + 1 < image.width ? x0 + 1 : x0, y1 = y0 + 1 < image.height ? y0 + 1 : y0;
  const int wx = static_cast<int>((x - static_cast<float>(x0)) * 256.0f + 0.5f), wy = static_cast<int>((y - static_cast<float>(y0)) * 256.0f + 0.5f);
  const Rgb8* row0 = image.data.data() + static_cast<size_t>(y0) * image.width;
  const Rgb8* row1 = image.data.data() + static_cast<size_t>(y1) * image.width;
  const Rgb8 a = row0[x0], b = row0[x1], c = row1[x0], d = row1[x1];
  auto mix = [&](int pa, int pb, int pc, int pd) { return static_cast<unsigned char>(bilinear_mix(pa, pb, pc, pd, wx, wy)); };
  return {mix(a.r, b.r, c.r, d.r), mix(a.g, b.g, c.g, d.g), mix(a.b, b.b, c.b, d.b)};
}

//! The colour of a depth camera's pixels: each pixel's point goes into the colour camera and the
//! colour image is sampled there. Immutable once made: at() may be called from any number of
//! threads. Holds pointers: the camera model and the colour image must outlive it.
class ColorLookup {
 public:
  //! kNoColor for every pixel where `color` is null or empty or the camera has no colour camera.
  ColorLookup(const CameraModel& camera, const ColorImage* color)
      : rays_(camera.depth_intrinsics, camera.color_from_depth.cast<float>()),
        color_k_(camera.has_color() ? &*camera.color_intrinsics : nullptr),
        image_(color != nullptr && !color->empty() && camera.has_color() ? color : nullptr) {}

  //! How many pixels project_row takes at a time: callers' buffers are arrays of this size.
  static constexpr int kRowChunk = 256;

  //! Whether there is a colour image to sample (otherwise every pixel is kNoColor).
  bool has_image() const { return image_ != nullptr; }

  //! Element function: the colour of depth pixel (u, v) at depth z (metres, > 0).
  Rgb8 at(int u, int v, float z) const {
    if (image_ == nullptr) return kNoColor;
    const Eigen::Vector3f p_color = rays_.point(u, v, z);  // depth pixels straight into the colour camera's frame
    if (p_color.z() <= 0) return kNoColor;
    const Eigen::Vector2f pixel =
        color_k_->has_distortion ? project(*color_k_, p_color.cast<double>()).cast<float>() : project_pinhole(*color_k_, p_color);
    return sample_bilinear(*image_, pixel.x(), pixel.y());
  }

  //! Row form of at(), in two steps so that the first vectorises: project_row gives the
  //! colour-image coordinates of `count` (≤ kRowChunk) pixels u0, u0 + 1, … of row v at depths
  //! z[0..count), the same floats at() computes (−1 where the point is behind the colour
  //! camera); sample(x[i], y[i]) is then the colour at() gives for a depth > 0. Only where
  //! has_image(). The zipper's colours of samba-4cam took 29 ns a vertex through at(), 21 ns so
  //! (docs/profile.md); sample_row samples a chunk at once.
  void project_row(int v, int u0, int count, const float* z, float* x, float* y) const;
  Rgb8 sample(float x, float y) const { return sample_bilinear(*image_, x, y); }
  //! sample() at (x[i], y[i]) for i < count (≤ kRowChunk), the colours packed by pack_rgb: a
  //! row kernel, the same colours.
  void sample_row(const float* x, const float* y, int count, std::uint32_t* packed) const;
  static std::uint32_t pack_rgb(Rgb8 c) { return c.r | static_cast<std::uint32_t>(c.g) << 8 | static_cast<std::uint32_t>(c.b) << 16; }
  static Rgb8 unpack_rgb(std::uint32_t packed) {
    return {static_cast<unsigned char>(packed), static_cast<unsigned char>(packed >> 8), static_cast<unsigned char>(packed >> 16)};
  }

  //! The two steps over pixels u0 ≤ u < u1 of row v, `depth_row` the row's depths: calls
  //! emit(u, colour) for each u with keep(u) (whose depth must be > 0), in order. Only where
  //! has_image().
  template <typename Keep, typename Emit>
  void for_each_color_in_row(int v, int u0, int u1, const float* depth_row, Keep&& keep, Emit&& emit) const {
    float x[kRowChunk], y[kRowChunk];
    int kept[kRowChunk];
    std::uint32_t packed[kRowChunk];
    for (int first = u0; first < u1; first += kRowChunk) {
      const int count = std::min(kRowChunk, u1 - first);
      project_row(v, first, count, depth_row + first, x, y);
      // The kept pixels' coordinates moved to the front (branch-free), then sampled together.
      int n = 0;
      for (int i = 0; i < count; ++i) {
        kept[n] = i;
        x[n] = x[i];
        y[n] = y[i];
        n += keep(first + i) ? 1 : 0;
      }
      sample_row(x, y, n, packed);
      for (int k = 0; k < n; ++k) emit(first + kept[k], unpack_rgb(packed[k]));
    }
  }

 private:
  PixelRays rays_;
  const Intrinsics* color_k_;
  const ColorImage* image_;
};

//! Colour of every pixel of `mesh` that has depth (kNoColor elsewhere, or everywhere when
//! `color` is null or the camera has no colour). `out` is resized to the pixel count.
void lookup_colors(const DepthMesh& mesh, const CameraModel& camera, const ColorImage* color, std::vector<Rgb8>& out);

}  // namespace zipfusion
