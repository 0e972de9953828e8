#pragma once
//! \file
//! Removal of redundant overlapping triangles (paper Section III-C and Appendix): the "Fast
//! Redundant Boundary Removal" (FRBR) iteration on the SDC bit matrices of two cameras, its
//! coarse-to-fine driver, and the detection of overlapping camera pairs.
//!
//! A boundary triangle t of mesh A is redundant with respect to mesh B when B holds the same
//! surface (a triangle of B lies within the redundancy distance d_r of t's centre) and B sees it
//! better. Neighbours are found by projecting the centre into camera B and
//! searching a small window of B's cells (Fig. 5 of the paper). FRBR peels one boundary layer of
//! A, then one of B, and repeats until neither changes.
//!
//! "Sees it better" goes beyond the paper, whose test is only "any triangle of B within d_r":
//! each camera has a score of how well it sees each point (`OwnershipScore`: how far inside its
//! own coverage the point is, or how smooth its surface is there), compared at the same point in
//! both images; the larger keeps the surface, ties to the lower camera index. With the paper's
//! test the meshes eat into the overlap from both sides and stop d_r apart; where both end at the
//! same place (a silhouette both see, or one camera seeing all the other sees) each border is
//! redundant against the other's next ring and the two peel each other away. With ownership the
//! overlap is split where both see equally well, the meshes meet there with no gap, and one mesh
//! is never removed where the other does not take over.

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "zipfusion/core/camera.h"
#include "zipfusion/core/geometry.h"
#include "zipfusion/core/row_kernel.h"
#include "zipfusion/depth/sdc_mesh.h"
#include "zipfusion/fusion/binary_image.h"

namespace zipfusion {

//! How well a camera sees each point of its image, for ownership: where two cameras see one
//! surface, the one with the larger score keeps it. Computed once per frame on one (coarse)
//! pyramid level and sampled bilinearly, so it is continuous over the image and the same at every
//! level; 0 off the mesh, so it falls to 0 over a mesh's last cell. Two scores (`Ownership`):
//! - *border*: the distance from the border of the mesh (its silhouette, or a hole wider than the
//!   closing), in full-resolution pixels: large where the camera sees the surface frontally and
//!   near, small at grazing angles;
//! - *smoothness*: (A_smooth / A)^exponent (smoothness_score), where A is the area of the camera's
//!   triangles in a window and A_smooth that of the same triangles on the locally averaged depth. Noise along a
//!   camera's rays roughens its sheet and raises its area: it is strongest where the camera sees
//!   the surface frontally, so unfiltered, the camera that sees a surface more obliquely measures
//!   it more smoothly, up to the grazing angles and mixed pixels at its silhouette.
struct OwnershipScore {
  // Per cell of `level`, 0 where the cell holds no triangle, with a border of one zero cell all
  // round, so that the bilinear lookup near the image's edges needs no bounds tests: cell (u, v)
  // is at (v + 1)·stride + u + 1.
  std::vector<float> cells;
  int width = 0;
  int height = 0;
  int stride = 0;  // width + 2
  int level = 0;
  float width_f = 0, height_f = 0;  // width and height as floats, for the lookup's range test
  // Rows of `cells` (counted from the border row) outside which every cell is 0: the next frame
  // clears only these.
  std::pair<int, int> written_rows{0, 0};

  //! Cell (u, v), u in [−1, width], v in [−1, height] (the border reads 0).
  float& cell(int u, int v) { return cells[static_cast<size_t>(v + 1) * stride + u + 1]; }
  const float& cell(int u, int v) const { return cells[static_cast<size_t>(v + 1) * stride + u + 1]; }

  // Not part of the score: buffers compute_smoothness reuses from one frame to the next.
  std::vector<float> padded_depth, row_sums, row_counts, smooth_depth, ray_x, area, smooth_area, area_sums, smooth_sums;
  std::vector<double> area_table, smooth_area_table, padded_columns, powers, results;
  std::vector<std::pair<int, int>> cell_spans;  // per row of the box, its cells with triangles [first, end)
  // And compute_border_distance's: the closed mask of the box, its distances, the passes' buffers.
  std::vector<std::uint8_t> border_mask;
  std::vector<float> border_distance;
  BinaryImageScratch binary_image;
};

//! Fills `out` with the border score of `mesh`, a view at `level`: the distance transform of its
//! cells with triangles, after closing holes up to 2·close_cells+1 cells wide (noise dropouts do
//! not make a border).
void compute_border_distance(const DepthMesh& mesh, int level, int close_cells, OwnershipScore& out);

//! Element function: the smoothness score of the area ratio A_smooth / A of a window:
//! (ratio / 0.6)^exponent, a ratio above 1 counted as 1 (no sheet is smoother than its average).
//! The reference 0.6 (a Kinect v1 sheet at 2–3 m) keeps exponents up to 128 in float range, the
//! smoothest at (1/0.6)^128 ≈ 2.5·10^28; a ratio below lowest_ratio = 0.6·2^(−120/exponent) (0.25
//! for 96), whose power would no longer be a normal float, counts as that, so two cameras both
//! that rough tie (and the lower camera index keeps the surface).
inline constexpr float kSmoothnessReference = 0.6f;
inline float smoothness_lowest_ratio(float exponent) { return kSmoothnessReference * std::exp2(-120.0f / exponent); }
//! base^exponent in double. A whole exponent is multiplied out by repeated squaring: for 96, 4.0
//! against 13.9 ns a call for std::pow of the float (docs/profile.md), and, rounded to float, more
//! exact: the correctly rounded power of every float base from 0.41 to 1.67 (every ratio from 0.25
//! to 1, checked against quadruple precision), where std::pow of the float missed it by one unit
//! in the last place for 0.2 % of them.
//! smoothness_score_row takes the same steps over a row.
inline double smoothness_power(double base, float exponent) {
  if (exponent != std::floor(exponent)) return std::pow(base, static_cast<double>(exponent));
  double result = 1.0;
  for (unsigned e = static_cast<unsigned>(exponent);; base *= base) {
    if (e & 1u) result *= base;
    e >>= 1;
    if (e == 0) break;
  }
  return result;
}
inline float smoothness_score(float ratio, float exponent, float lowest_ratio) {
  return static_cast<float>(smoothness_power(std::clamp(ratio, lowest_ratio, 1.0f) / kSmoothnessReference, exponent));
}
inline float smoothness_score(float ratio, float exponent) { return smoothness_score(ratio, exponent, smoothness_lowest_ratio(exponent)); }

struct SmoothnessOptions {
  int window_cells = 125;       // areas are summed over windows this wide, cells of the score's level (odd)
  float exponent = 96;          // smoothness_score's: how much a smoother surface outweighs the fall of the score over a mesh's last cell
  float same_surface_m = 0.06f; // metres: depths this close are averaged together (the level's SDC threshold)
};

//! Fills `out` with the smoothness score of `mesh`, a view at `level` with intrinsics `k` (of that
//! level): A is the area of the triangles, A_smooth that of the same triangles on the depth
//! averaged over 5×5 cells of the same surface, both summed over windows, and the ratio scored by
//! smoothness_score (docs/design.md). Reuses `out`'s buffers.
void compute_smoothness(const DepthMesh& mesh, const Intrinsics& k, int level, const SmoothnessOptions& options, OwnershipScore& out);

//! Element function: the summed area (square metres) of the triangles `bits` of a cell whose
//! corners lie at depths z00 (top left), z10 (top right), z01 (bottom left) and z11 on the rays
//! (x0, y0, 1), (x1, y0, 1), (x0, y1, 1), (x1, y1, 1), xi = (ui − cx)/fx, yi = (vi − cy)/fy.
//! Both areas are formed and an absent triangle's replaced by +0 (select_if), without a branch,
//! so that a row of cells vectorises; whatever the corners' depths, the sum is that of the
//! existing triangles alone.
inline float cell_triangle_area(float x0, float x1, float y0, float y1, std::uint8_t bits, float z00, float z10, float z01, float z11) {
  const Eigen::Vector3f p(x0 * z00, y0 * z00, z00), r(x1 * z10, y0 * z10, z10), b(x0 * z01, y1 * z01, z01), d(x1 * z11, y1 * z11, z11);
  const float upper = 0.5f * std::sqrt((b - p).cross(r - p).squaredNorm());
  const float lower = 0.5f * std::sqrt((b - r).cross(d - r).squaredNorm());
  // Summed from 0 in this order, as the branching version did, for the same floats.
  return 0.0f + select_if(bits & kUpperTriangle, upper, 0.0f) + select_if((bits & kLowerTriangle) >> 1, lower, 0.0f);
}

//! Element function: the score at (x, y) in pixels of a level whose pixels are 1/cells_per_pixel
//! cells of the score's level (cells_per_pixel = 2^(level − score level), a power of two, so the
//! result is exactly that of the full-resolution coordinates), bilinear between cell centres; 0
//! outside the image. On a score map's cells as OwnershipScore keeps them (with their zero
//! border, `stride` a row, `width_f` × `height_f` cells inside it), so that FRBR's row kernel
//! calls it too. Branch-free: outside the image it reads the cells around cell (0, 0) and answers
//! 0, so the map must have been filled (compute_border_distance, compute_smoothness).
inline float score_at_cells(const float* cells, int stride, float width_f, float height_f, float cells_per_pixel, float x, float y) {
  const float cx = x * cells_per_pixel - 0.5f, cy = y * cells_per_pixel - 0.5f;
  const unsigned inside = (cx > -1.0f) & (cy > -1.0f) & (cx < width_f) & (cy < height_f);
  // Inside, u, v ≥ −1 and u + 1, v + 1 ≤ the size: all four cells are in the padded map.
  const float sx = select_if(inside, cx, 0.0f), sy = select_if(inside, cy, 0.0f);
  const int u = floor_to_int(sx), v = floor_to_int(sy);
  const float fu = sx - static_cast<float>(u), fv = sy - static_cast<float>(v);
  const int k = (v + 1) * stride + u + 1;  // cell (u, v); cell (u, v + 1) is a row further
  const float top = cells[k] + fu * (cells[k + 1] - cells[k]);
  const float bottom = cells[k + stride] + fu * (cells[k + stride + 1] - cells[k + stride]);
  return select_if(inside, top + fv * (bottom - top), 0.0f);
}

//! The same on an OwnershipScore.
inline float ownership_score_at(const OwnershipScore& q, float x, float y, float cells_per_pixel) {
  return score_at_cells(q.cells.data(), q.stride, q.width_f, q.height_f, cells_per_pixel, x, y);
}

//! The same at full-resolution pixel coordinates.
inline float ownership_score_at(const OwnershipScore& q, float x, float y) {
  return ownership_score_at(q, x, y, 1.0f / static_cast<float>(1 << q.level));
}

//! One camera's mesh at one pyramid level and how to project into it.
struct MeshView {
  DepthMesh* mesh = nullptr;
  Intrinsics intrinsics;       // of this level (focal length and centre scaled by 2^-level)
  Rigid3f depth_from_world = Rigid3f::Identity();
  const OwnershipScore* ownership = nullptr;  // null: this view never owns what another sees
  int camera = 0;                          // breaks ownership ties
  int level = 0;                           // pyramid level: cells are 2^level pixels
  float same_surface = 0.03f;              // metres: neighbouring pixels this close in depth are one surface (the level's SDC threshold)
  // The intrinsics as the element functions use them, converted once per view rather than at
  // every call (each conversion and division sat on a search's critical path).
  float fx = static_cast<float>(intrinsics.fx), fy = static_cast<float>(intrinsics.fy);
  float cx = static_cast<float>(intrinsics.cx), cy = static_cast<float>(intrinsics.cy);
  float inv_fx = 1.0f / fx, inv_fy = 1.0f / fy;
  float third_over_fx = (1.0f / 3.0f) / fx, third_over_fy = (1.0f / 3.0f) / fy;
  // The range of projections whose 2×2 pixels lie in the image, for project_camera_point.
  float last_x = mesh != nullptr ? static_cast<float>(mesh->width - 1) : 0.0f;
  float last_y = mesh != nullptr ? static_cast<float>(mesh->height - 1) : 0.0f;

  //! The score map's cells per pixel of this level: 2^(level − ownership level), made from its
  //! exponent bits (no division; levels are small). Only where `ownership` is set.
  float score_cells_per_pixel() const { return std::bit_cast<float>(static_cast<std::uint32_t>(127 + level - ownership->level) << 23); }

  //! The ownership score at (x, y) in this level's pixel coordinates.
  float score_at(float x, float y) const {
    if (ownership == nullptr) return 0.0f;
    return ownership_score_at(*ownership, x, y, score_cells_per_pixel());
  }
};

//! A world point as a view sees it: in the view's camera frame, and the cell its projection falls
//! in (the pixel up and left of it), or cell −1 when the point is behind the camera or its 2×2
//! pixels are not all in the image. One projection serves all of a test's lookups.
struct ViewPoint {
  Eigen::Vector3f in_camera = Eigen::Vector3f::Zero();
  float x = 0, y = 0;  // pixel coordinates at the view's level
  int cell = -1;
};

//! Element function: projects point p, given in the view's camera frame, into `view`.
inline ViewPoint project_camera_point(const MeshView& view, const Eigen::Vector3f& p_in_camera) {
  ViewPoint out;
  out.in_camera = p_in_camera;
  if (!(out.in_camera.z() > 0)) return out;
  const float inv_z = 1.0f / out.in_camera.z();
  out.x = view.fx * out.in_camera.x() * inv_z + view.cx;
  out.y = view.fy * out.in_camera.y() * inv_z + view.cy;
  // Compare as floats before converting: far outside points must not overflow the int.
  if (!(out.x >= 0 && out.y >= 0 && out.x < view.last_x && out.y < view.last_y)) {
    return out;
  }
  out.cell = static_cast<int>(out.y) * view.mesh->width + static_cast<int>(out.x);
  return out;
}

//! Element function: t · p, each row's products added left to right, then the translation. This
//! fixes the order that project_centres_row (FRBR's row kernel) repeats: Eigen's own product adds
//! in an order of its choosing, and fuses the multiply-adds where the instruction set has them.
inline Eigen::Vector3f transform_point(const Rigid3f& t, const Eigen::Vector3f& p) {
  const Eigen::Matrix4f& m = t.matrix();
  return {m(0, 0) * p.x() + m(0, 1) * p.y() + m(0, 2) * p.z() + m(0, 3), m(1, 0) * p.x() + m(1, 1) * p.y() + m(1, 2) * p.z() + m(1, 3),
          m(2, 0) * p.x() + m(2, 1) * p.y() + m(2, 2) * p.z() + m(2, 3)};
}

//! Element function: projects world point p into `view`.
inline ViewPoint project_into(const MeshView& view, const Eigen::Vector3f& p) { return project_camera_point(view, view.depth_from_world * p); }

//! The transform from view a's camera frame to view b's.
inline Rigid3f b_from_a(const MeshView& a, const MeshView& b) { return b.depth_from_world * a.depth_from_world.inverse(Eigen::Isometry); }

//! Element function: the centre of triangle `bit` of cell `cell` of `view` in its camera frame,
//! from the depth of its three pixels alone (the searches are bound by memory reads: one array
//! read per pixel, and no world point to form).
//! The cell is given by its column and row (a sweep has them already: an integer division costs
//! more than all of this arithmetic).
inline Eigen::Vector3f camera_triangle_centre(const MeshView& view, int cell_u, int cell_v, TriangleBit bit) {
  const DepthMesh& mesh = *view.mesh;
  const int width = mesh.width;
  const float* d = mesh.depth.data() + cell_v * width + cell_u;
  const float z00 = d[0], z10 = d[1], z01 = d[width];
  const float u = static_cast<float>(cell_u) - view.cx;
  const float v = static_cast<float>(cell_v) - view.cy;
  const float third = 1.0f / 3.0f;
  float sum, x_extra, y_extra;  // the three depths; the corners' extra pixel offsets weighted by depth
  if (bit == kUpperTriangle) {  // (u, v), (u, v + 1), (u + 1, v)
    sum = z00 + z01 + z10;
    x_extra = z10;
    y_extra = z01;
  } else {  // (u + 1, v), (u, v + 1), (u + 1, v + 1)
    const float z11 = d[width + 1];
    sum = z10 + z01 + z11;
    x_extra = z10 + z11;
    y_extra = z01 + z11;
  }
  return {(u * sum + x_extra) * view.third_over_fx, (v * sum + y_extra) * view.third_over_fy, sum * third};
}

//! The same for cell index `cell`.
inline Eigen::Vector3f camera_triangle_centre(const MeshView& view, int cell, TriangleBit bit) {
  const int width = view.mesh->width;
  return camera_triangle_centre(view, cell % width, cell / width, bit);
}
//! Where, coarsely, another camera sees the surface of a camera's mesh: per cell of a coarse view
//! of the mesh, whether the other camera has depth close to the mesh's point there, dilated by
//! one cell (so the window searches at the other mesh's border stay inside). Redundancy tests and
//! seam seeds outside the mask cannot succeed, so they are skipped without a search: most of a
//! mesh's boundary (silhouettes, noise holes) lies outside every other camera's overlap.
//! An empty mask covers everything.
struct OverlapMask {
  std::vector<std::uint8_t> cells;
  int width = 0;
  int level = 0;
  BinaryImageScratch binary_image;  // not part of the mask: the dilation's buffers, reused

  //! Does the mask cover cell (u, v) of a view at `view_level` (≤ level)?
  bool covers_at(int u, int v, int view_level) const {
    if (cells.empty()) return true;
    const int shift = level - view_level;
    return cells[(v >> shift) * width + (u >> shift)] != 0;
  }
  //! The same for cell index `cell` of a view `view_width` cells wide.
  bool covers(int cell, int view_width, int view_level) const { return covers_at(cell % view_width, cell / view_width, view_level); }
};

//! Fills `mask` for view `a` (a coarse level) against camera `b` (any level): a cell is set where
//! a's point there projects into b onto depth within `depth_tolerance` of its own, then the mask
//! is dilated by one cell.
void compute_overlap_mask(const MeshView& a, const MeshView& b, float depth_tolerance, OverlapMask& mask);

//! Triangle id: cell index · 2 + (0 upper, 1 lower).
inline int triangle_id(int cell, TriangleBit bit) { return cell * 2 + (bit == kLowerTriangle ? 1 : 0); }
inline int cell_of(int id) { return id >> 1; }
inline TriangleBit bit_of(int id) { return (id & 1) ? kLowerTriangle : kUpperTriangle; }

//! Ids of the (up to three) edge neighbours of triangle `id`, whether they exist or not (see
//! is_boundary_triangle, whose bit-matrix layout lets this skip bounds tests); returns how many.
inline int triangle_neighbours(int id, int width, int out[3]) {
  const int cell = cell_of(id);
  int n = 0;
  if (bit_of(id) == kUpperTriangle) {
    out[n++] = triangle_id(cell, kLowerTriangle);
    if (cell >= width) out[n++] = triangle_id(cell - width, kLowerTriangle);
    if (cell > 0) out[n++] = triangle_id(cell - 1, kLowerTriangle);
  } else {
    out[n++] = triangle_id(cell, kUpperTriangle);
    out[n++] = triangle_id(cell + width, kUpperTriangle);
    out[n++] = triangle_id(cell + 1, kUpperTriangle);
  }
  return n;
}

//! Element function: does `view` hold a triangle within `distance` of point p (projected by
//! project_into)? Searches the cells around p's projection, wide enough to cover `distance` at p's
//! depth (at most max_window cells each way). Centres are computed from the view's depth in its
//! camera frame (the same points as in the world, one array read instead of three), and a
//! triangle whose mean depth already differs by `distance` is rejected before its centre is
//! formed.
bool has_triangle_near(const MeshView& view, const ViewPoint& p, float distance, int max_window = 4);

//! A block of FRBR's tests of triangles of a against b, in the form its row kernels read and
//! write (a column per test): the triangles, then their centres as b sees them.
struct TriangleTestBlock {
  static constexpr int kCapacity = 128;  // a few kilobytes: the block stays in the first-level cache
  int count = 0;
  int id[kCapacity], u[kCapacity], v[kCapacity];  // the triangle and its cell
  float a_x[kCapacity], a_y[kCapacity];            // its centre's pixel coordinates in a
  // project_triangle_centres: the centre in b's camera frame, its pixel coordinates and cell in b
  float b_x[kCapacity], b_y[kCapacity], b_z[kCapacity], x[kCapacity], y[kCapacity];
  int cell[kCapacity];

  void add(int triangle, int cell_u, int cell_v) {
    assert(count < kCapacity);
    // The centre lies a third (upper) or two thirds (lower) into the cell.
    const float offset = bit_of(triangle) == kUpperTriangle ? 1.0f / 3.0f : 2.0f / 3.0f;
    id[count] = triangle, u[count] = cell_u, v[count] = cell_v;
    a_x[count] = static_cast<float>(cell_u) + offset, a_y[count] = static_cast<float>(cell_v) + offset;
    ++count;
  }
  ViewPoint centre(int i) const {
    ViewPoint p;
    p.in_camera = {b_x[i], b_y[i], b_z[i]};
    p.x = x[i], p.y = y[i], p.cell = cell[i];
    return p;
  }
};

//! For every test of the block: centre(i) = project_camera_point(b, transform_point(b_from_a_camera,
//! camera_triangle_centre(a, u, v, bit))), the same floats, as a row kernel over the tests. Every
//! cell must hold triangles' room: u < width − 1 and v < height − 1 of a's mesh (all four of its
//! depths are read, for either triangle).
void project_triangle_centres(const MeshView& a, const MeshView& b, const Rigid3f& b_from_a_camera, TriangleTestBlock& block);

//! The tests i of the block with owner_is_other(a, a_x, a_y, b, centre(i), depth_tolerance), in
//! order, into `owned`; returns how many. The same answers, as a row kernel over the tests.
int select_owned_by_other(const MeshView& a, const MeshView& b, float depth_tolerance, const TriangleTestBlock& block, int* owned);

//! Calls f(id) for every existing triangle of `mesh`, in id order.
template <typename F>
void for_each_triangle_id(const DepthMesh& mesh, F&& f) {
  for_each_nonempty_cell(mesh.triangles, [&](int cell, std::uint8_t bits) {
    if (bits & kUpperTriangle) f(triangle_id(cell, kUpperTriangle));
    if (bits & kLowerTriangle) f(triangle_id(cell, kLowerTriangle));
  });
}

//! The boundary triangles of `mesh` (ids), in id order. `rows`: scratch, reused across calls.
void collect_boundary_triangles(const DepthMesh& mesh, std::vector<int>& boundary, std::vector<std::uint8_t>& rows);
inline void collect_boundary_triangles(const DepthMesh& mesh, std::vector<int>& boundary) {
  std::vector<std::uint8_t> rows;
  collect_boundary_triangles(mesh, boundary, rows);
}

//! Element function: false when camera `b` certainly does not see point p: it is outside b's
//! image, or every pixel next to its projection has a depth (of another surface) more than
//! `depth_tolerance` from p's. `p` is the point projected into b (its cell is where to look).
bool may_see_point(const MeshView& b, const ViewPoint& p, float depth_tolerance);

//! Element function: does `b` see the surface at point p, which lies at (a_x, a_y) in a's image
//! (this level's pixel coordinates), better than `a`? `b` must see p (a pixel next to p's
//! projection has p's depth within `depth_tolerance`, or no depth), and its ownership score there
//! must exceed a's (ties to the lower camera index). Both meshes evaluate the same point the same
//! way, so they meet without a gap. `p` is the point projected into b.
bool owner_is_other(const MeshView& a, float a_x, float a_y, const MeshView& b, const ViewPoint& p, float depth_tolerance);

//! Share (0..1) of `a`'s triangles that have a triangle of `b` within `distance` (estimated on
//! every other cell). The zipper only needs to know whether a minimum is reached and calls
//! overlap_reaches; this full figure is its definition, which the tests compare it with.
double overlap_share(const MeshView& a, const MeshView& b, float distance);

//! Whether overlap_share(a, b, distance) ≥ min_share, searching only until it is decided: a
//! pair of cameras that overlap reaches the minimum (ZipperOptions::min_overlap_share, 1 % by
//! default) after a small part of the sample; a pair below it searches the whole sample, as
//! overlap_share does (after a pass that counts the sample).
bool overlap_reaches(const MeshView& a, const MeshView& b, float distance, double min_share);

//! A set of marks on the integers [0, size) as bits, for visits: a test reads one of 64 times
//! fewer bytes than a per-item stamp (a 640×480 mesh's triangles in 77 kB, which stay in cache,
//! against 2.4 MB of stamps, whose reads missed). Cleared item by item by whoever set the marks.
class MarkBits {
 public:
  //! Makes room for items [0, size); all marks are clear after a resize that grows.
  void reserve(size_t size) {
    if (words_.size() * 64 < size) words_.assign((size + 63) / 64, 0);
  }
  //! Marks item i; returns whether it was marked already.
  bool test_and_set(int i) {
    std::uint64_t& word = words_[static_cast<size_t>(i) >> 6];
    const std::uint64_t bit = std::uint64_t{1} << (i & 63);
    const bool was = (word & bit) != 0;
    word |= bit;
    return was;
  }
  bool test(int i) const { return (words_[static_cast<size_t>(i) >> 6] >> (i & 63)) & 1; }
  void clear(int i) { words_[static_cast<size_t>(i) >> 6] &= ~(std::uint64_t{1} << (i & 63)); }

 private:
  std::vector<std::uint64_t> words_;
};

//! Scratch space of one camera for FRBR, reused across frames.
struct FrbrScratch {
  std::vector<int> worklist, next, removals;
  // Candidate boundary triangles of this camera at the current level: its boundary when the level
  // began (collect_boundary_triangles) plus every triangle next to a removal since. Pairs start
  // from it instead of scanning the whole bit matrix.
  std::vector<int> frontier;
  MarkBits queued;  // per triangle id; clear between sweeps but for the worklist's ids
};

struct FrbrResult {
  int removed_a = 0;
  int removed_b = 0;
  int iterations = 0;
};

//! Runs FRBR between two views until neither mesh changes; clears redundant triangles' bits.
//! Without `whole_first_sweep` the sweeps start from the scratch spaces' `frontier`, which must
//! hold (at least) the meshes' boundary triangles and no other triangle that exists (only
//! existence is tested: a boundary triangle stays one while the mesh loses triangles). With it the first sweep tests every triangle, not only the boundary ones (used
//! on the coarsest level: it also removes doubled patches that noise or holes cut off from the
//! mesh's boundary, which peeling never reaches).
//! Not thread-safe for views that share a mesh; distinct pairs may run in parallel.
//! `mask_a` (`mask_b`): where b sees a (a sees b); triangles outside are never redundant.
FrbrResult remove_redundant_boundaries(const MeshView& a, const MeshView& b, float redundancy_distance, bool whole_first_sweep,
                                       const OverlapMask& mask_a, const OverlapMask& mask_b, FrbrScratch& scratch_a,
                                       FrbrScratch& scratch_b);

//! A coarser level of a full-resolution mesh: every 2^level-th pixel of `fine` (its depth, and
//! the rays of those pixels), triangulated by SDC with the depth-jump threshold scaled by 2^level.
void downsample_mesh(const DepthMesh& fine, int level, DepthJump max_depth_jump, DepthMesh& coarse);

//! Clears in `fine` (one level finer than `coarse`) the triangles covered by the triangles that
//! were present in `coarse_before` (its SDC bits before any removal) but are gone from `coarse`
//! (removed at the coarse level, directly or propagated from coarser ones).
//! Returns the number of fine triangles cleared.
int propagate_removals(const std::vector<std::uint8_t>& coarse_before, const DepthMesh& coarse, DepthMesh& fine);

}  // namespace zipfusion
