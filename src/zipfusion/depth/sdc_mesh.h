#pragma once
//! \file
//! Step-discontinuity-constrained (SDC) triangulation of one depth map (paper Section III-B).
//!
//! Every pixel p = (u, v) with u < width−1, v < height−1 owns two triangles of its 2×2 cell:
//!
//!     p ------- r          upper triangle (bit kUpperTriangle): p, b, r
//!     |  U   /  |          lower triangle (bit kLowerTriangle): r, b, d
//!     |    /  L |          (counter-clockwise as the camera sees them, so normals face it)
//!     b ------- d
//!
//! A triangle exists when its three depths are valid and pairwise differ by less than
//! max_depth_jump_m (the paper compares depths rather than 3-D distances: the pixel spacing is far
//! below the threshold). The triangles are kept as this per-pixel bit matrix until assembly, so
//! boundary tests, coarse-to-fine and removal are array operations.

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <utility>
#include <vector>

#include "zipfusion/core/camera.h"
#include "zipfusion/core/geometry.h"
#include "zipfusion/core/image.h"
#include "zipfusion/core/mesh.h"

namespace zipfusion {

enum TriangleBit : std::uint8_t { kUpperTriangle = 1, kLowerTriangle = 2 };

//! The focal length, in pixels, for which ReconstructOptions::sdc gives the SDC threshold: a
//! Kinect v1's depth camera at 640×480. Neighbouring pixels of a camera with focal length f are
//! 580/f times as far apart in angle, and a surface's slope makes the depth step between them grow
//! alike; so does the disparity's quantisation where disparity is measured at the delivered
//! resolution (as `synth` renders it). sdc_depth_jump gives each camera its threshold.
inline constexpr double kSdcReferenceFocalPx = kKinectV1DepthFocalPx;

//! The SDC threshold of a camera with intrinsics k, from `reference_jump_m`, the threshold for a
//! focal length of kSdcReferenceFocalPx: scaled by 580/f (f = max(fx, fy), the closer-spaced
//! direction) where f is shorter; kept where it is longer. That floor is a modelling choice: there
//! the threshold must clear the sensor's noise between neighbours, which `synth`'s Kinect model
//! does not lower with finer pixels (halving the threshold split a 1280×960 ring's meshes apart,
//! docs/design.md, "SDC triangulation"); a real sensor's may shrink, and --max-depth-jump sets it.
inline double sdc_depth_jump(double reference_jump_m, const Intrinsics& k) {
  const double f = std::max(k.fx, k.fy);
  return f > 0 ? reference_jump_m * std::max(1.0, kSdcReferenceFocalPx / f) : reference_jump_m;
}

struct SdcOptions {
  // metres, the threshold applied to the depth map triangulated; paper Section III-B (see
  // docs/design.md for the choice). FrameReconstructor sets it per camera (sdc_depth_jump).
  double max_depth_jump_m = 0.03;
  // metres: beyond this depth the threshold grows with the square of depth, as a structured-light
  // or stereo sensor's depth step does (the Kinect v1's disparity step is 1.8 cm at 2.5 m and
  // 4.6 cm at 4 m): max_depth_jump_m holds up to it, then max_depth_jump_m·(z/this)². 0: constant.
  double growth_depth_m = 3.0;

  void validate() const;  // throws InvalidInput naming the field
};

//! The SDC threshold as a function of depth (SdcOptions): `at_least_m`, or `per_depth2`·z² where
//! that is larger. Plain data, for the per-pixel kernels.
struct DepthJump {
  float at_least_m = 0.03f;
  float per_depth2 = 0;  // 1/m: at_least_m / growth_depth_m²; 0 = constant
  //! Element function: the threshold between two depths, taken at the nearer one (where the
  //! sensor's step is finer: a real step in depth is not excused by the farther surface's noise).
  float between(float a, float b) const {
    const float z = a < b ? a : b;
    const float grown = per_depth2 * z * z;
    return grown > at_least_m ? grown : at_least_m;
  }
  //! The threshold for pixels `factor` times as far apart (a coarse level).
  DepthJump scaled(float factor) const { return {at_least_m * factor, per_depth2 * factor}; }
};

//! The threshold SdcOptions describe.
inline DepthJump depth_jump(double max_depth_jump_m, double growth_depth_m) {
  return {static_cast<float>(max_depth_jump_m),
          growth_depth_m > 0 ? static_cast<float>(max_depth_jump_m / (growth_depth_m * growth_depth_m)) : 0.0f};
}
inline DepthJump depth_jump(const SdcOptions& options) { return depth_jump(options.max_depth_jump_m, options.growth_depth_m); }

//! Columns [u0, u1) and rows [v0, v1) of an image.
struct PixelBox {
  int u0 = 0, v0 = 0, u1 = 0, v1 = 0;
  bool empty() const { return u1 <= u0 || v1 <= v0; }
};

//! One camera's triangulated depth map. Thread safety: plain data.
struct DepthMesh {
  int width = 0;
  int height = 0;
  std::vector<float> depth;                // per pixel, metres along the camera axis; 0 = none
  std::vector<std::uint8_t> triangles;     // per pixel, TriangleBit flags; none in the last row and column
  // The pixels' rays in the world: a pixel's world point is formed from its depth where it is
  // needed (point()), not stored for every pixel: most are never read (their triangles are
  // removed as redundant), and the array was three times the depth's memory to write. Set by
  // triangulate_sdc (and downsample_mesh, steps scaled); a mesh made by hand must set it too,
  // or its points are (0, 0, depth).
  PixelRays rays;
  // Every pixel with depth lies in this box (a person fills a fraction of a depth image, and
  // per-pixel work outside it is skipped). Set by triangulate_sdc; the default is the whole image.
  PixelBox depth_box{0, 0, 1 << 30, 1 << 30};

  int triangle_count() const;
  //! Element function: the world point of pixel (u, v) (meaningful where it has depth).
  Eigen::Vector3f point(int u, int v) const { return rays.point(u, v, depth[static_cast<size_t>(v) * width + u]); }
  //! The same for pixel index `pixel`.
  Eigen::Vector3f point(int pixel) const { return point(pixel % width, pixel / width); }
  //! depth_box clipped to the image.
  PixelBox box() const {
    return {std::max(depth_box.u0, 0), std::max(depth_box.v0, 0), std::min(depth_box.u1, width), std::min(depth_box.v1, height)};
  }
};

//! Element function: the triangle bits of pixel (u, v) from the depth map.
inline std::uint8_t sdc_cell(int u, int v, const float* depth, int width, int height, DepthJump max_jump) {
  if (u >= width - 1 || v >= height - 1) return 0;
  const int index = v * width + u;
  const float p = depth[index], r = depth[index + 1], b = depth[index + width], d = depth[index + width + 1];
  auto close = [max_jump](float a, float c) { return (a > c ? a - c : c - a) < max_jump.between(a, c); };
  std::uint8_t bits = 0;
  if (p > 0 && r > 0 && b > 0 && close(p, r) && close(p, b) && close(r, b)) bits |= kUpperTriangle;
  if (r > 0 && b > 0 && d > 0 && close(r, b) && close(r, d) && close(b, d)) bits |= kLowerTriangle;
  return bits;
}

//! sdc_cell for `count` consecutive cells of one row, none in the last row or column of the image
//! (`depth` points at the first cell's pixel, `width` is the image's row length): one branch-free
//! loop that vectorises, for the CPU (a row has a few hundred cells, most without depth).
void sdc_row(const float* depth, int width, int count, DepthJump max_jump, std::uint8_t* bits);

//! sdc_row for the cells of row v − 1 of an image `width` wide (`depth`, `bits`: the whole image's)
//! that can hold a triangle, given the spans [first, end) of pixels with depth of rows v − 1
//! (`above`) and v (`here`), as positive_span finds them. Both triangles of a cell have the pixels
//! right of and below its own as corners, so such cells lie where `above`, one pixel to the left,
//! meets `here`; the others' bits are not written (the callers' are 0). A subject fills about a
//! quarter of its box, so triangulation goes row by row over these cells only.
void sdc_row_between_spans(const float* depth, int width, int v, std::pair<int, int> above, std::pair<int, int> here, DepthJump max_jump,
                           std::uint8_t* bits);

//! Element function: does a triangle use pixel p as a vertex, given the bits of p's own cell and
//! of the cells to its left, above and above-left (0 where a cell does not exist)? p is vertex p
//! of its own cell's upper triangle, r of both triangles of the cell to its left, b of both of the
//! cell above, and d of the lower triangle of the cell above-left (triangle_pixels).
inline bool pixel_used(std::uint8_t own, std::uint8_t left, std::uint8_t above, std::uint8_t above_left) {
  return ((own & kUpperTriangle) | left | above | (above_left & kLowerTriangle)) != 0;
}

//! The number of triangles in the bits of `count` consecutive cells (a loop that vectorises).
int count_triangles(const std::uint8_t* bits, int count);

//! Pixel indices of the three vertices of triangle `bit` of cell `index`, counter-clockwise as seen
//! from the camera.
inline void triangle_pixels(int index, int width, TriangleBit bit, int out[3]) {
  if (bit == kUpperTriangle) {
    out[0] = index;
    out[1] = index + width;
    out[2] = index + 1;
  } else {
    out[0] = index + 1;
    out[1] = index + width;
    out[2] = index + width + 1;
  }
}

//! Calls f(cell, bit, corners, k) for each of the (up to six) triangles of the pixel grid of a
//! width × height image that have pixel `pixel` as a corner, whether a mesh has them or not, in
//! cell order: `corners` as triangle_pixels gives them, corners[k] == pixel.
template <typename F>
void for_each_grid_triangle_at_pixel(int pixel, int width, int height, F&& f) {
  // The six, as the cell's offset from the pixel's own, the triangle and the pixel's corner
  // index in it: assembly asks this for every seam vertex, and a table is a few times faster
  // than finding the pixel among the corners of the four cells' eight triangles.
  struct Incident {
    int du, dv;
    TriangleBit bit;
    int k;
  };
  static constexpr Incident kIncident[6] = {{-1, -1, kLowerTriangle, 2}, {0, -1, kUpperTriangle, 1}, {0, -1, kLowerTriangle, 1},
                                            {-1, 0, kUpperTriangle, 2},  {-1, 0, kLowerTriangle, 0}, {0, 0, kUpperTriangle, 0}};
  const int u = pixel % width, v = pixel / width;
  for (const Incident& t : kIncident) {
    const int cell_u = u + t.du, cell_v = v + t.dv;
    if (cell_u < 0 || cell_v < 0 || cell_u > width - 2 || cell_v > height - 2) continue;
    const int cell = cell_v * width + cell_u;
    int corners[3];
    triangle_pixels(cell, width, t.bit, corners);
    f(cell, t.bit, static_cast<const int*>(corners), t.k);
  }
}

//! True when the triangle exists and one of its three edge neighbours does not.
//! Upper triangle of (u, v): neighbours are the lower triangles of (u, v−1), (u−1, v) and (u, v).
//! Lower triangle of (u, v): neighbours are the upper triangles of (u, v), (u+1, v) and (u, v+1).
//! No division and one bounds test: the last row and column of an SDC bit matrix hold no
//! triangles (sdc_cell), so the neighbour "left of column 0" (the previous row's last cell) and
//! those beyond the last triangle row or column read as absent, as they are.
inline bool is_boundary_triangle(const std::uint8_t* triangles, int index, int width, TriangleBit bit) {
  if (!(triangles[index] & bit)) return false;
  if (bit == kUpperTriangle) {
    return !(triangles[index] & kLowerTriangle) || index < width || !(triangles[index - width] & kLowerTriangle) ||
           !(triangles[index - 1] & kLowerTriangle);
  }
  return !(triangles[index] & kUpperTriangle) || !(triangles[index + width] & kUpperTriangle) || !(triangles[index + 1] & kUpperTriangle);
}

//! Calls f(k) for every nonzero byte k (0..7, in memory order) of `word`, found by its lowest set
//! bit rather than tested one by one (whose branches mispredicted where a boundary row has one or
//! two flags in a word).
template <typename F>
void for_each_nonzero_byte_in_word(std::uint64_t word, F&& f) {
  static_assert(std::endian::native == std::endian::little, "byte k of a word is bits 8k..8k+7");
  while (word != 0) {
    const int k = std::countr_zero(word) >> 3;
    f(k);
    word &= ~(std::uint64_t{0xff} << (8 * k));
  }
}

//! Calls f(i, bytes[i]) for every nonzero byte of bytes[0..count), in order, eight bytes at a
//! time: most cells of a depth camera's image hold no triangle (the subject fills a fraction of
//! it), and most of a mesh's cells are not on its boundary.
template <typename F>
void for_each_nonzero_byte(const std::uint8_t* bytes, int count, F&& f) {
  int i = 0;
  for (; i + 8 <= count; i += 8) {
    std::uint64_t word;
    std::memcpy(&word, bytes + i, sizeof word);
    for_each_nonzero_byte_in_word(word, [&](int k) { f(i + k, bytes[i + k]); });
  }
  for (; i < count; ++i) {
    if (bytes[i]) f(i, bytes[i]);
  }
}

//! [first, end) from the first nonzero byte of bytes[0..count) to one past the last, {0, 0} when
//! all are 0; the zero bytes before and after are skipped eight at a time. Passes over a row of
//! the depth box use it to skip the cells or pixels left and right of the subject.
inline std::pair<int, int> nonzero_span(const std::uint8_t* bytes, int count) {
  static_assert(std::endian::native == std::endian::little, "byte k of a word is bits 8k..8k+7");
  int first = 0;
  std::uint64_t word = 0;
  for (; first + 8 <= count; first += 8) {
    std::memcpy(&word, bytes + first, sizeof word);
    if (word != 0) break;
  }
  if (first + 8 <= count) {
    first += std::countr_zero(word) >> 3;
  } else {
    while (first < count && bytes[first] == 0) ++first;
    if (first == count) return {0, 0};
  }
  int end = count;
  for (; end - 8 >= first; end -= 8) {
    std::memcpy(&word, bytes + end - 8, sizeof word);
    if (word != 0) return {first, end - (std::countl_zero(word) >> 3)};
  }
  while (bytes[end - 1] == 0) --end;  // stops at bytes[first], which is not 0
  return {first, end};
}

//! Element function: is one of depth[0..8) > 0? Branch-free, so the eight compares go as vectors.
inline bool any_positive8(const float* depth) {
  unsigned any = 0;
  for (int i = 0; i < 8; ++i) any |= static_cast<unsigned>(depth[i] > 0);
  return any != 0;
}

//! [first, end) from the first pixel of depth[0..count) with depth (> 0) to one past the last,
//! {0, 0} when none has; the empty parts are skipped eight pixels at a time.
inline std::pair<int, int> positive_span(const float* depth, int count) {
  int first = 0, end = count;
  while (first + 8 <= count && !any_positive8(depth + first)) first += 8;
  while (first < count && !(depth[first] > 0)) ++first;
  if (first == count) return {0, 0};
  while (end - 8 > first && !any_positive8(depth + end - 8)) end -= 8;
  while (!(depth[end - 1] > 0)) --end;  // stops at depth[first], which is > 0
  return {first, end};
}

//! Calls f(cell, bits) for every cell with a triangle, in order.
template <typename F>
void for_each_nonempty_cell(const std::vector<std::uint8_t>& triangles, F&& f) {
  for_each_nonzero_byte(triangles.data(), static_cast<int>(triangles.size()), f);
}

//! Calls f(pixels) with the three pixel indices (as triangle_pixels gives them) of every existing
//! triangle in cells first..first+count−1 of `mesh`, in cell order.
template <typename F>
void for_each_triangle_in_cells(const DepthMesh& mesh, int first, int count, F&& f) {
  for_each_nonzero_byte(mesh.triangles.data() + first, count, [&](int i, std::uint8_t bits) {
    for (TriangleBit bit : {kUpperTriangle, kLowerTriangle}) {
      if (!(bits & bit)) continue;
      int pixels[3];
      triangle_pixels(first + i, mesh.width, bit, pixels);
      f(pixels);
    }
  });
}

//! The same for every existing triangle of `mesh`.
template <typename F>
void for_each_triangle(const DepthMesh& mesh, F&& f) {
  for_each_triangle_in_cells(mesh, 0, static_cast<int>(mesh.triangles.size()), f);
}

//! Sizes `mesh`'s depth and triangle bits for a width × height image, all 0. A mesh of that size
//! already is only cleared inside its depth box (every pixel with depth, and so every triangle,
//! lies in it): a person fills a fraction of the image, and clearing whole images took a
//! noticeable share of a frame set's memory traffic. `clear_depth`: false when the caller
//! overwrites every depth.
void reset_depth_mesh(DepthMesh& mesh, int width, int height, bool clear_depth = true);

//! Triangulates `depth_m` (metres, 0 = none) of a camera into `out`, reusing its buffers.
void triangulate_sdc(const Image<float>& depth_m, const Intrinsics& k, const Rigid3f& world_from_depth, const SdcOptions& options,
                     DepthMesh& out);
//! The same, but the mesh takes `depth_m`'s buffer instead of copying it (a Kinect frame set's
//! copies were 4.9 MB), and `depth_m` gets the mesh's previous one, of the same size: its
//! contents are unspecified, for a caller that overwrites every pixel of it next frame.
void triangulate_sdc_taking_depth(Image<float>& depth_m, const Intrinsics& k, const Rigid3f& world_from_depth, const SdcOptions& options,
                                  DepthMesh& out);

//! Appends the existing triangles of `mesh` to `out` with vertices compacted: each pixel used by a
//! triangle becomes one vertex, shared by its triangles. `colors` holds one colour per pixel
//! (ignored when empty: then `out` gets none either). `vertex_of_pixel` is scratch space.
void append_depth_mesh(const DepthMesh& mesh, const std::vector<Rgb8>& colors, TriangleMesh& out,
                       std::vector<int>& vertex_of_pixel);

}  // namespace zipfusion
