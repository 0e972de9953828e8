#pragma once
//! \file
//! How a seam reads a mesh's surface around a pixel: the least-squares plane through the depths
//! of a small window of pixels on the pixel's own surface (fit_surface), and their mean depth
//! (smoothed_depth). Each has an element function, for one window, and a form over many windows
//! of one view at once (fit_surfaces, smoothed_depths) that gathers each window's depths and
//! runs the sums as row kernels over the windows, with the same floats: a seam reads three
//! windows of 9–25 pixels for each of its points, and one window at a time that was 7 % of
//! zippering's instructions (docs/profile.md). Windows wider than 5 × 5 (seam smoothing radius 3
//! and up) go one at a time through the element functions.

#include <span>

#include "zipfusion/fusion/redundancy.h"

namespace zipfusion {

//! The least-squares plane z = depth + du·(x − cu) + dv·(y − cv) through the depths of a
//! window's pixels on one surface, x and y in pixels from the window's centre pixel: it passes
//! through their mean depth at their centroid (cu, cv). `sloped` is false where the pixels lie on
//! one line (no slope).
struct SurfaceFit {
  float depth = 0, du = 0, dv = 0, cu = 0, cv = 0;
  bool sloped = false;
  float depth_at(float x, float y) const { return depth + du * (x - cu) + dv * (y - cv); }
};

//! Element function: the plane through the depths of the pixels of `view` on a (2·radius + 1)²
//! grid around `pixel`, `spacing` pixels apart (the grid's part inside the image), that lie on
//! its surface (within the view's SDC threshold of its depth, which must be > 0).
SurfaceFit fit_surface(const MeshView& view, int pixel, int radius, int spacing = 1);

//! Element function: the mean depth of the pixels of `view` in the (2·radius + 1)² window around
//! `pixel` (its part inside the image) on the same surface (within the view's SDC threshold of
//! its depth, which must be > 0); the pixel's own depth for radius 0.
float smoothed_depth(const MeshView& view, int pixel, int radius);

//! out[k] = fit_surface(view, pixels[k], radius, spacing) for every k, the same floats.
void fit_surfaces(const MeshView& view, std::span<const int> pixels, int radius, int spacing, SurfaceFit* out);

//! out[k] = smoothed_depth(view, pixels[k], radius) for every k, the same floats.
void smoothed_depths(const MeshView& view, std::span<const int> pixels, int radius, float* out);

}  // namespace zipfusion
