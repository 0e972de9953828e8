#pragma once
//! \file
//! Image<T>: a row-major 2-D array of pixels, the one image type of the library.

#include <cassert>
#include <cstddef>
#include <vector>

namespace zipfusion {

//! Row-major image; pixel (u, v) is at data[v * width + u]. Thread safety: like std::vector.
template <typename T>
struct Image {
  int width = 0;
  int height = 0;
  std::vector<T> data;

  Image() = default;
  Image(int w, int h, T fill = T{}) : width(w), height(h), data(static_cast<size_t>(w) * h, fill) {}

  bool empty() const { return data.empty(); }
  size_t size() const { return data.size(); }
  bool contains(int u, int v) const { return u >= 0 && v >= 0 && u < width && v < height; }

  T& operator()(int u, int v) {
    assert(contains(u, v));
    return data[static_cast<size_t>(v) * width + u];
  }
  const T& operator()(int u, int v) const {
    assert(contains(u, v));
    return data[static_cast<size_t>(v) * width + u];
  }

  void resize(int w, int h, T fill = T{}) {
    width = w;
    height = h;
    data.assign(static_cast<size_t>(w) * h, fill);
  }

  //! resize() without the fill, for a caller that writes every pixel: the buffer is reused where it
  //! is large enough (a decoder, frame after frame), and the pixels are unspecified until written.
  void resize_for_overwrite(int w, int h) {
    width = w;
    height = h;
    data.resize(static_cast<size_t>(w) * h);
  }

  friend bool operator==(const Image&, const Image&) = default;
};

//! 8-bit RGB pixel.
struct Rgb8 {
  unsigned char r = 0, g = 0, b = 0;
  friend bool operator==(const Rgb8&, const Rgb8&) = default;
};

using DepthImage = Image<unsigned short>;  // raw depth in units of the rig's depth_unit_m, 0 = none
using ColorImage = Image<Rgb8>;

}  // namespace zipfusion
