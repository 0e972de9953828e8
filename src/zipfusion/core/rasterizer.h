#pragma once
//! \file
//! A z-buffer triangle rasterizer (synthetic captures, visibility in evaluation): the true depth (along the optical axis)
//! and colour that a pinhole camera sees of a triangle mesh, plus an analytic floor plane.
//! Pixel centres at integer coordinates (FORMATS.md); lens distortion is not rendered.

#include <limits>

#include "zipfusion/core/camera.h"
#include "zipfusion/core/geometry.h"
#include "zipfusion/core/image.h"
#include "zipfusion/core/mesh.h"

namespace zipfusion {

inline constexpr float kNoDepth = std::numeric_limits<float>::infinity();

//! What a camera sees: depth in metres along its optical axis (kNoDepth where nothing is hit) and,
//! when requested, the colour there.
struct RenderBuffers {
  Image<float> depth;
  ColorImage color;  // empty unless rendered with colour
  void reset(const Intrinsics& k, bool with_color, Rgb8 background = {});
};

//! Draws `mesh` (world coordinates) into the buffers of a camera at `cam_from_world`, keeping the
//! nearest surface per pixel. Colours are interpolated perspective-correctly from vertex colours
//! (grey when the mesh has none). Only what lies beyond `near_m` along the optical axis is drawn: a
//! triangle that reaches closer is clipped there, not dropped.
void rasterize_mesh(const TriangleMesh& mesh, const Intrinsics& k, const Rigid3d& cam_from_world, RenderBuffers& buffers,
                    float near_m = 0.05f);

//! Draws the floor z = 0, a square of half-size `half_extent_m` around the origin, with a
//! checkerboard of `tile_m` tiles when colour is rendered.
void rasterize_floor(const Intrinsics& k, const Rigid3d& cam_from_world, RenderBuffers& buffers, double half_extent_m = 3.0,
                     double tile_m = 0.5);

}  // namespace zipfusion
