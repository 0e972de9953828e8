#include "zipfusion/fusion/redundancy.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <opencv2/core/types.hpp>

#include "zipfusion/core/row_kernel.h"

namespace zipfusion {
namespace {


// Queues triangle `id` for the next worklist once per pass, and adds it to the frontier, the
// camera's later pairs' start: a triangle already queued in this pass is in both.
void enqueue(FrbrScratch& s, int id) {
  if (s.queued.test_and_set(id)) return;
  s.next.push_back(id);
  s.frontier.push_back(id);  // boundary now
}


// One FRBR sweep of `a` against `b` over a's worklist: removes the redundant ones and queues their
// neighbours (the new boundary) for the next sweep. Returns the number removed.
// The tests go in blocks (TriangleTestBlock), each in three passes: the candidates' centres and
// projections, then the ownership test, then the search for b's triangles near those b owns. The
// first two are row kernels over the block; each pass's reads (a's depth, then the score maps
// and b's depth near the projection) miss the cache at scattered boundary pixels, and within a
// pass they are independent and overlap. The tests read only the bit matrices as the sweep
// found them (its removals are cleared after it), so the passes give the removals a single loop
// gave, in the same order.
// Every triangle of a worklist that still exists is a boundary triangle, except in a whole first
// sweep (`whole_sweep`): the first worklist holds boundary triangles (start_worklist) and each
// later one neighbours of removed triangles, and a mesh only loses triangles, so none stops being
// boundary. Testing it again cost four reads a test.
int sweep(const MeshView& a, const MeshView& b, float distance, [[maybe_unused]] bool whole_sweep, const OverlapMask& mask, FrbrScratch& s) {
  DepthMesh& mesh = *a.mesh;
  const Rigid3f b_from_a_camera = b_from_a(a, b);
  s.removals.clear();
  TriangleTestBlock block;
  int owned[TriangleTestBlock::kCapacity];
  const size_t count = s.worklist.size();
  for (size_t first = 0; first < count; first += TriangleTestBlock::kCapacity) {
    const size_t last = std::min(count, first + TriangleTestBlock::kCapacity);
    block.count = 0;
    for (size_t k = first; k < last; ++k) {
      const int id = s.worklist[k];
      const int cell = cell_of(id);
      const TriangleBit bit = bit_of(id);
      if (!(mesh.triangles[cell] & bit)) continue;
      const int v = cell / mesh.width, u = cell - v * mesh.width;
      if (!mask.covers_at(u, v, a.level)) continue;
      assert(whole_sweep || is_boundary_triangle(mesh.triangles.data(), cell, mesh.width, bit));
      block.add(id, u, v);
    }
    project_triangle_centres(a, b, b_from_a_camera, block);
    const int m = select_owned_by_other(a, b, 2 * distance, block, owned);
    for (int k = 0; k < m; ++k) {
      if (has_triangle_near(b, block.centre(owned[k]), distance)) s.removals.push_back(block.id[owned[k]]);
    }
  }
  for (int id : s.worklist) s.queued.clear(id);  // queued by the previous pass
  s.next.clear();
  for (int id : s.removals) mesh.triangles[cell_of(id)] &= static_cast<std::uint8_t>(~bit_of(id));
  for (int id : s.removals) {
    int neighbours[3];
    const int n = triangle_neighbours(id, mesh.width, neighbours);
    for (int k = 0; k < n; ++k) {
      if (mesh.triangles[cell_of(neighbours[k])] & bit_of(neighbours[k])) enqueue(s, neighbours[k]);
    }
  }
  s.worklist.swap(s.next);
  return static_cast<int>(s.removals.size());
}

void start_worklist(const DepthMesh& mesh, bool all_triangles, FrbrScratch& s) {
  s.queued.reserve(mesh.triangles.size() * 2);
  s.worklist.clear();
  if (all_triangles) {
    for_each_triangle_id(mesh, [&](int id) { s.worklist.push_back(id); });
    return;
  }
  // The frontier holds ids more than once; the worklist each once, and it stays marked as queued
  // (the first sweep clears it). Each frontier triangle was boundary when it was added (the
  // level's boundary, or next to a removal) and stays so while it exists: only existence is tested.
  for (int id : s.frontier) {
    if (s.queued.test(id)) continue;
    if (mesh.triangles[cell_of(id)] & bit_of(id)) {
      assert(is_boundary_triangle(mesh.triangles.data(), cell_of(id), mesh.width, bit_of(id)));
      s.queued.test_and_set(id);
      s.worklist.push_back(id);
    }
  }
}

}  // namespace

namespace {

// is_boundary_triangle for cells 1..count−1 of a row at once, as bits per cell: `row` is the
// row's bit matrix from its first cell, `above` and `below` the rows next to it (cell 0 is left
// to the caller, whose left neighbour may not exist). Branch-free, so it vectorises.
ZF_ROW_KERNEL void boundary_row(const std::uint8_t* row, const std::uint8_t* above, const std::uint8_t* below, int count, std::uint8_t* out) {
  for (int i = 1; i < count; ++i) {
    const unsigned cell = row[i];
    // The upper triangle's neighbours are lower triangles (bit 2), the lower's upper ones (bit 1).
    const unsigned upper_inside = (cell & above[i] & row[i - 1] & kLowerTriangle) >> 1;
    const unsigned lower_inside = cell & below[i] & row[i + 1] & kUpperTriangle;
    out[i] = static_cast<std::uint8_t>((cell & kUpperTriangle & ~upper_inside) | (cell & kLowerTriangle & ~(lower_inside << 1)));
  }
}

}  // namespace

void collect_boundary_triangles(const DepthMesh& mesh, std::vector<int>& boundary, std::vector<std::uint8_t>& rows) {
  boundary.clear();
  const PixelBox box = mesh.box();
  // Triangles lie in the cells of the depth box but its last row and column (and none of the
  // image's last row or column).
  const int u0 = box.u0, u1 = std::min(box.u1, mesh.width - 1), v1 = std::min(box.v1, mesh.height - 1);
  if (u1 <= u0 || v1 <= box.v0) return;
  // A row's flags, then a row of no triangles (above the image's first).
  rows.assign(2 * (u1 - u0) + 1, 0);
  std::uint8_t *flags = rows.data(), *empty_row = rows.data() + (u1 - u0);
  const std::uint8_t* t = mesh.triangles.data();
  for (int v = box.v0; v < v1; ++v) {
    // Only the row's cells from its first triangle to its last (the subject, not the box).
    const auto [span_first, span_end] = nonzero_span(t + v * mesh.width + u0, u1 - u0);
    const int count = span_end - span_first;
    if (count == 0) continue;
    const int first = v * mesh.width + u0 + span_first;
    const std::uint8_t* above = v > 0 ? t + first - mesh.width : empty_row;
    boundary_row(t + first, above, t + first + mesh.width, count, flags);
    flags[0] = is_boundary_triangle(t, first, mesh.width, kUpperTriangle) * kUpperTriangle +
               is_boundary_triangle(t, first, mesh.width, kLowerTriangle) * kLowerTriangle;
    for_each_nonzero_byte(flags, count, [&](int i, std::uint8_t bits) {
      if (bits & kUpperTriangle) boundary.push_back(triangle_id(first + i, kUpperTriangle));
      if (bits & kLowerTriangle) boundary.push_back(triangle_id(first + i, kLowerTriangle));
    });
  }
}

namespace {

// Does b have, at one of the 2×2 pixels around p's projection, depth within `depth_tolerance` of
// p's, or (when `no_depth_counts`) no depth at all?
bool depth_near_projection(const MeshView& b, const ViewPoint& p, float depth_tolerance, bool no_depth_counts) {
  if (p.cell < 0) return false;
  const float* depth = b.mesh->depth.data() + p.cell;
  const int width = b.mesh->width;
  for (const float z : {depth[0], depth[1], depth[width], depth[width + 1]}) {
    if ((no_depth_counts && z <= 0) || std::abs(z - p.in_camera.z()) < depth_tolerance) return true;
  }
  return false;
}

// Does b see a surface at p? Unlike may_see_point, a pixel without depth does not count.
bool may_see_surface(const MeshView& b, const ViewPoint& p, float depth_tolerance) {
  return depth_near_projection(b, p, depth_tolerance, false);
}

}  // namespace

bool may_see_point(const MeshView& b, const ViewPoint& p, float depth_tolerance) {
  return depth_near_projection(b, p, depth_tolerance, true);  // no depth: cannot tell
}

bool owner_is_other(const MeshView& a, float a_x, float a_y, const MeshView& b, const ViewPoint& p, float depth_tolerance) {
  // Where b sees another surface, in front or behind, it owns nothing at p, and the costly search
  // for b's triangles near p is skipped. The ownership scores are compared first: they are small
  // coarse maps, b's full depth image is the cache miss, and most tests end there (a keeps what
  // it sees better).
  if (b.ownership == nullptr || p.cell < 0) return false;
  const float mine = a.score_at(a_x, a_y), theirs = b.score_at(p.x, p.y);
  if (!(theirs > mine || (theirs == mine && b.camera < a.camera))) return false;
  return may_see_point(b, p, depth_tolerance);
}

namespace {

// The row form of camera_triangle_centre, then of b_from_a_camera · centre and
// project_camera_point, over a block's tests (the same operations on each, in the same order):
// `upper` is 1 for an upper triangle; `m` the rotation row by row, `t` the translation.
ZF_ROW_KERNEL void project_centres_row(const float* __restrict depth, int a_width, float a_cx, float a_cy, float third_over_fx,
                                       float third_over_fy, const float* __restrict m, const float* __restrict t, float b_fx, float b_fy,
                                       float b_cx, float b_cy, float last_x, float last_y, int b_width, const int* __restrict u,
                                       const int* __restrict v, const unsigned* __restrict upper, int count, float* __restrict b_x,
                                       float* __restrict b_y, float* __restrict b_z, float* __restrict x, float* __restrict y,
                                       int* __restrict cell) {
  const float third = 1.0f / 3.0f;
  for (int i = 0; i < count; ++i) {
    const int k = v[i] * a_width + u[i];
    // Triangles lie in cells off the image's last row and column: the fourth depth exists.
    const float z00 = depth[k], z10 = depth[k + 1], z01 = depth[k + a_width], z11 = depth[k + a_width + 1];
    const float cu = static_cast<float>(u[i]) - a_cx, cv = static_cast<float>(v[i]) - a_cy;
    const float sum = select_if(upper[i], z00 + z01 + z10, z10 + z01 + z11);
    const float x_extra = select_if(upper[i], z10, z10 + z11), y_extra = select_if(upper[i], z01, z01 + z11);
    const float c0 = (cu * sum + x_extra) * third_over_fx, c1 = (cv * sum + y_extra) * third_over_fy, c2 = sum * third;
    const float p0 = m[0] * c0 + m[1] * c1 + m[2] * c2 + t[0];
    const float p1 = m[3] * c0 + m[4] * c1 + m[5] * c2 + t[1];
    const float p2 = m[6] * c0 + m[7] * c1 + m[8] * c2 + t[2];
    const unsigned in_front = p2 > 0;
    const float inv_z = 1.0f / select_if(in_front, p2, 1.0f);
    const float px = select_if(in_front, b_fx * p0 * inv_z + b_cx, 0.0f), py = select_if(in_front, b_fy * p1 * inv_z + b_cy, 0.0f);
    const unsigned inside = in_front & (px >= 0) & (py >= 0) & (px < last_x) & (py < last_y);
    b_x[i] = p0, b_y[i] = p1, b_z[i] = p2, x[i] = px, y[i] = py;
    // Truncated only where inside (the coordinates of an outside point may not fit an int).
    cell[i] = inside ? static_cast<int>(select_if(inside, py, 0.0f)) * b_width + static_cast<int>(select_if(inside, px, 0.0f)) : -1;
  }
}

// The row form of owner_is_other over a block's tests (b's score map and a's both exist): 1 where b
// owns the centre.
ZF_ROW_KERNEL void owned_by_other_row(const float* __restrict a_cells, int a_stride, float a_width_f, float a_height_f,
                                      float a_cells_per_pixel, const float* __restrict b_cells, int b_stride, float b_width_f,
                                      float b_height_f, float b_cells_per_pixel, unsigned b_wins_ties, const float* __restrict b_depth,
                                      int b_width, float depth_tolerance, const float* __restrict a_x, const float* __restrict a_y,
                                      const float* __restrict x, const float* __restrict y, const float* __restrict z,
                                      const int* __restrict cell, int count, unsigned* __restrict owned) {
  for (int i = 0; i < count; ++i) {
    const unsigned valid = cell[i] >= 0;
    const float mine = score_at_cells(a_cells, a_stride, a_width_f, a_height_f, a_cells_per_pixel, a_x[i], a_y[i]);
    const float theirs = score_at_cells(b_cells, b_stride, b_width_f, b_height_f, b_cells_per_pixel, x[i], y[i]);
    const unsigned theirs_wins = (theirs > mine) | ((theirs == mine) & b_wins_ties);
    // may_see_point: b has no depth, or depth near the centre's, at one of the 2×2 pixels.
    const int k = valid ? cell[i] : 0;
    const float z00 = b_depth[k], z10 = b_depth[k + 1], z01 = b_depth[k + b_width], z11 = b_depth[k + b_width + 1];
    const unsigned may_see = (z00 <= 0) | (std::abs(z00 - z[i]) < depth_tolerance) | (z10 <= 0) | (std::abs(z10 - z[i]) < depth_tolerance) |
                             (z01 <= 0) | (std::abs(z01 - z[i]) < depth_tolerance) | (z11 <= 0) | (std::abs(z11 - z[i]) < depth_tolerance);
    owned[i] = valid & theirs_wins & may_see;
  }
}

}  // namespace

void project_triangle_centres(const MeshView& a, const MeshView& b, const Rigid3f& b_from_a_camera, TriangleTestBlock& block) {
  unsigned upper[TriangleTestBlock::kCapacity];
  for (int i = 0; i < block.count; ++i) {
    assert(block.u[i] >= 0 && block.v[i] >= 0 && block.u[i] < a.mesh->width - 1 && block.v[i] < a.mesh->height - 1);
    upper[i] = bit_of(block.id[i]) == kUpperTriangle;
  }
  float m[9], t[3];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m[r * 3 + c] = b_from_a_camera.linear()(r, c);
    t[r] = b_from_a_camera.translation()(r);
  }
  project_centres_row(a.mesh->depth.data(), a.mesh->width, a.cx, a.cy, a.third_over_fx, a.third_over_fy, m, t, b.fx, b.fy, b.cx, b.cy,
                      b.last_x, b.last_y, b.mesh->width, block.u, block.v, upper, block.count, block.b_x, block.b_y, block.b_z, block.x,
                      block.y, block.cell);
}

int select_owned_by_other(const MeshView& a, const MeshView& b, float depth_tolerance, const TriangleTestBlock& block, int* owned) {
  int n = 0;
  if (b.ownership == nullptr) return 0;
  if (a.ownership == nullptr) {  // a scores 0 everywhere: the element function
    for (int i = 0; i < block.count; ++i) {
      if (owner_is_other(a, block.a_x[i], block.a_y[i], b, block.centre(i), depth_tolerance)) owned[n++] = i;
    }
    return n;
  }
  const OwnershipScore &qa = *a.ownership, &qb = *b.ownership;
  unsigned flags[TriangleTestBlock::kCapacity];
  owned_by_other_row(qa.cells.data(), qa.stride, qa.width_f, qa.height_f, a.score_cells_per_pixel(), qb.cells.data(), qb.stride,
                     qb.width_f, qb.height_f, b.score_cells_per_pixel(), b.camera < a.camera, b.mesh->depth.data(), b.mesh->width,
                     depth_tolerance, block.a_x, block.a_y, block.x, block.y, block.b_z, block.cell, block.count, flags);
  for (int i = 0; i < block.count; ++i) {
    if (flags[i]) owned[n++] = i;
  }
  return n;
}

namespace {

// Resets `out` to 0 over `mesh`'s cells at `level` and returns the box the score is computed in:
// the mesh's depth box (a person fills a fraction of a depth image) padded by `pad` cells, so that
// neighbourhood operations inside it come out as on the whole image; empty without depth.
// The caller then writes every cell of the box.
cv::Rect start_score(const DepthMesh& mesh, int level, int pad, OwnershipScore& out) {
  const size_t size = static_cast<size_t>(mesh.width + 2) * (mesh.height + 2);
  if (out.width != mesh.width || out.height != mesh.height || out.cells.size() != size) {
    out.cells.assign(size, 0.0f);
  } else {
    // Only the rows of the previous box can hold anything but 0 (a person fills a fraction of the
    // image: clearing it all was a sixth of the score's memory traffic).
    std::fill(out.cells.begin() + static_cast<std::ptrdiff_t>(out.written_rows.first) * out.stride,
              out.cells.begin() + static_cast<std::ptrdiff_t>(out.written_rows.second) * out.stride, 0.0f);
  }
  out.width = mesh.width;
  out.height = mesh.height;
  out.stride = mesh.width + 2;
  out.width_f = static_cast<float>(mesh.width);
  out.height_f = static_cast<float>(mesh.height);
  out.level = level;
  out.written_rows = {0, 0};
  const PixelBox depth_box = mesh.box();
  if (depth_box.empty()) return {};
  const cv::Rect box(cv::Point(std::max(0, depth_box.u0 - pad), std::max(0, depth_box.v0 - pad)),
                     cv::Point(std::min(mesh.width, depth_box.u1 + pad), std::min(mesh.height, depth_box.v1 + pad)));
  out.written_rows = {box.y + 1, box.y + box.height + 1};  // rows of `cells`, past the zero border
  return box;
}

}  // namespace

void compute_border_distance(const DepthMesh& mesh, int level, int close_cells, OwnershipScore& out) {
  const cv::Rect box = start_score(mesh, level, close_cells + 1, out);
  if (box.empty()) return;
  std::vector<std::uint8_t>& mask = out.border_mask;
  mask.resize(static_cast<size_t>(box.width) * box.height);
  for (int y = 0; y < box.height; ++y) {
    const std::uint8_t* row = mesh.triangles.data() + (box.y + y) * mesh.width + box.x;
    std::uint8_t* mask_row = mask.data() + static_cast<size_t>(y) * box.width;
    for (int x = 0; x < box.width; ++x) mask_row[x] = row[x] ? 255 : 0;
  }
  if (close_cells > 0) close_binary(mask.data(), mask.data(), box.width, box.height, close_cells, out.binary_image);
  std::vector<float>& distance = out.border_distance;
  distance.resize(mask.size());
  chamfer_distance(mask.data(), distance.data(), box.width, box.height, out.binary_image);
  const float pixels_per_cell = static_cast<float>(1 << level);
  for (int y = 0; y < box.height; ++y) {
    const float* d = distance.data() + static_cast<size_t>(y) * box.width;
    const int base = (box.y + y) * mesh.width + box.x;
    for (int x = 0; x < box.width; ++x) out.cell(box.x + x, box.y + y) = mesh.triangles[base + x] ? d[x] * pixels_per_cell : 0.0f;
  }
}

namespace {

// The same-surface average's half width: 5×5 cells.
constexpr int kSmoothRadius = 2;

// Adds to the sums and counts of `count` pixels (depths `centres`) their taps in one row of the
// window, the depths row[i − kSmoothRadius..i + kSmoothRadius] from left to right, that lie on the
// same surface: with depth, within `same_surface` of the pixel's. A row's five taps go in one pass,
// added in the order of one pass per tap (the same floats), which loaded and stored the sums and
// counts at every tap: 4.1 → 2.2 M instructions a frame set on samba-4cam unfiltered.
// Branch-free over the pixels of a row, so it vectorises.
ZF_ROW_KERNEL void add_same_surface_row(const float* centres, const float* row, int count, float same_surface_m, float* sums, float* counts) {
  for (int i = 0; i < count; ++i) {
    float sum = sums[i], n = counts[i];
    for (int dx = -kSmoothRadius; dx <= kSmoothRadius; ++dx) {
      const float z = row[i + dx];
      const float same = static_cast<float>(z > 0.0f) * static_cast<float>(std::abs(z - centres[i]) < same_surface_m);
      sum += same * z;
      n += same;
    }
    sums[i] = sum;
    counts[i] = n;
  }
}

// The areas of the triangles of `count` cells of a row (bits `bits`, corner depths z0 on the
// row's pixels and z1 on the next row's, column rays ray_x, row rays y0 and y1), 0 for a cell
// without triangles.
ZF_ROW_KERNEL void triangle_area_row(const std::uint8_t* bits, const float* ray_x, float y0, float y1, const float* z0, const float* z1, int count,
                                     float* area) {
  for (int x = 0; x < count; ++x) area[x] = cell_triangle_area(ray_x[x], ray_x[x + 1], y0, y1, bits[x], z0[x], z0[x + 1], z1[x], z1[x + 1]);
}

// The mean depth of `count` pixels from their sums and counts, 0 where none was added.
ZF_ROW_KERNEL void mean_depth_row(const float* sums, const float* counts, int count, float* mean) {
  // Every lane divides (so that the select vectorises), by at least 1; where the mean is used
  // the count is a whole number ≥ 1 and the max changes nothing.
  for (int x = 0; x < count; ++x) mean[x] = counts[x] > 0 ? sums[x] / std::max(counts[x], 1.0f) : 0.0f;
}

// The summed-area tables of two width × height maps: (width + 1) × (height + 1) sums each, entry
// (x, y) the sum of the cells left of x and above y, in double. Built together: each row's
// running sum is a chain of dependent additions, and two chains side by side take the time of one.
void build_summed_area_tables(const float* map_a, const float* map_b, int width, int height, std::vector<double>& table_a,
                              std::vector<double>& table_b) {
  const int table_width = width + 1;
  // Every entry is written below but the first row and column, the zeros.
  table_a.resize(static_cast<size_t>(table_width) * (height + 1));
  table_b.resize(static_cast<size_t>(table_width) * (height + 1));
  std::fill_n(table_a.begin(), table_width, 0.0);
  std::fill_n(table_b.begin(), table_width, 0.0);
  for (int y = 0; y < height; ++y) {
    const float* row_a = map_a + static_cast<size_t>(y) * width;
    const float* row_b = map_b + static_cast<size_t>(y) * width;
    const size_t above = static_cast<size_t>(y) * table_width, here = above + table_width;
    table_a[here] = 0.0;
    table_b[here] = 0.0;
    double sum_a = 0, sum_b = 0;
    for (int x = 0; x < width; ++x) {
      sum_a += row_a[x];
      sum_b += row_b[x];
      table_a[here + x + 1] = table_a[above + x + 1] + sum_a;
      table_b[here + x + 1] = table_b[above + x + 1] + sum_b;
    }
  }
}

// sums[i] = right[i] − left[i], rounded to float.
ZF_ROW_KERNEL void differences_row(const double* left, const double* right, int count, float* sums) {
  for (int i = 0; i < count; ++i) sums[i] = static_cast<float>(right[i] - left[i]);
}

// columns[j] = below[j] − above[j].
ZF_ROW_KERNEL void column_sums_row(const double* above, const double* below, int count, double* columns) {
  for (int j = 0; j < count; ++j) columns[j] = below[j] - above[j];
}

// The sums over windows of 2·radius + 1 cells, cut at the row's ends, of a row of `width` cells,
// from the summed-area table's rows above and below the window's band of rows. `padded` (width +
// 2·radius + 1 entries) gets the band's column sums (width + 1) with radius copies of the first
// before them and of the last after, so that each window's sum is the difference of two entries
// 2·radius + 1 apart: one loop without bounds tests, which vectorises. Where the sums are exact in
// double (compute_smoothness), the order of a window's four table entries does not change the
// float it rounds to.
// Only the `count` windows from cell `first` are summed (into sums[first..]).
void window_sums_row(const double* above, const double* below, int width, int radius, int first, int count, double* padded, float* sums) {
  column_sums_row(above, below, width + 1, padded + radius);
  std::fill_n(padded, radius, padded[radius]);
  std::fill_n(padded + radius + width + 1, radius, padded[radius + width]);
  differences_row(padded + first, padded + first + 2 * radius + 1, count, sums + first);
}

// The ratio of `count` windows' areas as smoothness_score clamps and scales it, in double (where
// a window has no area the ratio is not a number or infinite; smoothness_scores_row drops it).
ZF_ROW_KERNEL void smoothness_bases_row(const float* area_sums, const float* smooth_sums, int count, float lowest_ratio, double* bases) {
  for (int x = 0; x < count; ++x) bases[x] = std::min(std::max(smooth_sums[x] / area_sums[x], lowest_ratio), 1.0f) / kSmoothnessReference;
}

ZF_ROW_KERNEL void multiply_row(const double* factors, int count, double* products) {
  for (int x = 0; x < count; ++x) products[x] *= factors[x];
}

ZF_ROW_KERNEL void square_row(int count, double* values) {
  for (int x = 0; x < count; ++x) values[x] *= values[x];
}

// The scores where a cell has triangles and its window area, 0 elsewhere.
ZF_ROW_KERNEL void smoothness_scores_row(const std::uint8_t* bits, const float* area_sums, const double* powers, int count, float* scores) {
  for (int x = 0; x < count; ++x) {
    scores[x] = select_if(static_cast<unsigned>(bits[x] != 0) & static_cast<unsigned>(area_sums[x] > 0.0f), static_cast<float>(powers[x]), 0.0f);
  }
}

// smoothness_score of `count` cells from their windows' sums of area and smoothed area, 0 where a
// cell has no triangles (bits) or its window no area. A whole exponent takes smoothness_power's
// squarings and products, each a pass over the row; any other std::pow in double, cell by cell.
// `powers` and `results` hold `count` doubles each.
void smoothness_score_row(const std::uint8_t* bits, const float* area_sums, const float* smooth_sums, int count, float exponent,
                          float lowest_ratio, double* powers, double* results, float* scores) {
  smoothness_bases_row(area_sums, smooth_sums, count, lowest_ratio, powers);
  if (exponent != std::floor(exponent)) {
    for (int x = 0; x < count; ++x) results[x] = std::pow(powers[x], static_cast<double>(exponent));
  } else {
    std::fill_n(results, count, 1.0);
    for (unsigned e = static_cast<unsigned>(exponent);; square_row(count, powers)) {
      if (e & 1u) multiply_row(powers, count, results);
      e >>= 1;
      if (e == 0) break;
    }
  }
  smoothness_scores_row(bits, area_sums, results, count, scores);
}

}  // namespace

void compute_smoothness(const DepthMesh& mesh, const Intrinsics& k, int level, const SmoothnessOptions& options, OwnershipScore& out) {
  // Cells outside the depth box have no triangles and add no area to a window: a window is cut
  // at the box's edges, so the box needs no room for the window (at 250 pixels that would be
  // most of the image), only for the averaging.
  const cv::Rect box = start_score(mesh, level, kSmoothRadius + 1, out);
  if (box.empty()) return;
  // The box's depth with kSmoothRadius cells of no depth all round, so the taps need no bounds tests.
  const int padded_width = box.width + 2 * kSmoothRadius;
  std::vector<float>& padded = out.padded_depth;
  padded.resize(static_cast<size_t>(padded_width) * (box.height + 2 * kSmoothRadius));
  auto padded_row = [&](int y) { return padded.data() + static_cast<size_t>(y + kSmoothRadius) * padded_width + kSmoothRadius; };
  // Only the border is set to 0 (the buffer is reused from frame to frame; clearing all of it
  // and the other buffers below that are written whole was a fifth of the score's time).
  std::fill_n(padded.begin(), static_cast<size_t>(kSmoothRadius) * padded_width, 0.0f);
  std::fill_n(padded.end() - static_cast<std::ptrdiff_t>(kSmoothRadius) * padded_width, static_cast<size_t>(kSmoothRadius) * padded_width, 0.0f);
  for (int y = 0; y < box.height; ++y) {
    float* row = padded_row(y);
    std::fill_n(row - kSmoothRadius, kSmoothRadius, 0.0f);
    std::copy_n(mesh.depth.data() + (box.y + y) * mesh.width + box.x, box.width, row);
    std::fill_n(row + box.width, kSmoothRadius, 0.0f);
  }
  // Each row's cells with triangles, [first, end) in the box (first = end: none). Every pass
  // below but the summed-area tables runs over these spans only: a person fills about a quarter
  // of the box's cells (samba-4cam at level 1: 8 000–12 400 of 23 000–49 000), and the cells
  // without triangles have area 0 and no score. Triangles lie in the box but its last row and
  // column (the areas below leave those 0).
  std::vector<std::pair<int, int>>& spans = out.cell_spans;
  spans.assign(box.height, {0, 0});
  for (int y = 0; y + 1 < box.height; ++y) spans[y] = nonzero_span(mesh.triangles.data() + (box.y + y) * mesh.width + box.x, box.width - 1);
  // The depth averaged over the 5×5 cells on the same surface (the SDC test's threshold): a plain
  // average mixes the depths of an arm and the torso behind it into steep slopes whose area says
  // nothing about noise (on noise-free synthetic depth it put the ratio anywhere in 0.8–2).
  // Needed at the corners of the triangles only: in row y, those of the cells of rows y − 1 and y.
  std::vector<float>& smooth_depth = out.smooth_depth;
  smooth_depth.resize(static_cast<size_t>(box.width) * box.height);  // read only where written below
  auto smooth_row = [&](int y) { return smooth_depth.data() + static_cast<size_t>(y) * box.width; };
  std::vector<float>& sums = out.row_sums;
  std::vector<float>& counts = out.row_counts;
  for (int y = 0; y < box.height; ++y) {
    std::pair<int, int> corners = spans[y];
    if (y > 0 && spans[y - 1].first < spans[y - 1].second) {
      corners = corners.first < corners.second ? std::pair{std::min(corners.first, spans[y - 1].first), std::max(corners.second, spans[y - 1].second)}
                                               : spans[y - 1];
    }
    if (corners.first >= corners.second) continue;
    const int first = corners.first, count = corners.second + 1 - corners.first;  // a cell's right corners too
    sums.assign(count, 0.0f);
    counts.assign(count, 0.0f);
    const float* centre = padded_row(y) + first;
    for (int dy = -kSmoothRadius; dy <= kSmoothRadius; ++dy) {
      add_same_surface_row(centre, padded_row(y + dy) + first, count, options.same_surface_m, sums.data(), counts.data());
    }
    mean_depth_row(sums.data(), counts.data(), count, smooth_row(y) + first);
  }
  // The triangles' areas per cell, on the depth and on the averaged depth (the last row and
  // column hold no triangle: 0).
  const size_t cells = static_cast<size_t>(box.width) * box.height;
  std::vector<float>& area = out.area;
  std::vector<float>& smooth_area = out.smooth_area;
  area.resize(cells);
  smooth_area.resize(cells);
  std::vector<float>& ray_x = out.ray_x;  // (u − cx)/fx of the box's columns
  ray_x.resize(box.width);
  for (int x = 0; x < box.width; ++x) ray_x[x] = static_cast<float>((box.x + x - k.cx) / k.fx);
  for (int y = 0; y < box.height; ++y) {
    float* area_row = area.data() + static_cast<size_t>(y) * box.width;
    float* smooth_area_row = smooth_area.data() + static_cast<size_t>(y) * box.width;
    std::fill_n(area_row, box.width, 0.0f);
    std::fill_n(smooth_area_row, box.width, 0.0f);
    const auto [first, end] = spans[y];
    if (first >= end) continue;
    const std::uint8_t* bits = mesh.triangles.data() + (box.y + y) * mesh.width + box.x + first;
    const float *z0 = padded_row(y) + first, *z1 = padded_row(y + 1) + first;
    const float *s0 = smooth_row(y) + first, *s1 = smooth_row(y + 1) + first;
    const float y0 = static_cast<float>((box.y + y - k.cy) / k.fy), y1 = static_cast<float>((box.y + y + 1 - k.cy) / k.fy);
    triangle_area_row(bits, ray_x.data() + first, y0, y1, z0, z1, end - first, area_row + first);
    triangle_area_row(bits, ray_x.data() + first, y0, y1, s0, s1, end - first, smooth_area_row + first);
  }
  // Window sums from summed-area tables (a box filter computed every cell of the box, through a
  // border as wide as the window). In double the sums are exact unless the box's areas span more
  // than about 29 binary orders of magnitude, so each window's sum rounds to the float that
  // OpenCV's box filter, which sums in double too, gave. Sums, ratios and powers (for a whole
  // exponent) go a row at a time in passes that vectorise, for every cell, and only the cells
  // with triangles keep a score:
  // scored cell by cell, with a branch on the triangles, eight scattered table reads and std::pow,
  // the smoothness score took 2.7 times as long (docs/profile.md).
  build_summed_area_tables(area.data(), smooth_area.data(), box.width, box.height, out.area_table, out.smooth_area_table);
  const int radius = options.window_cells / 2;
  const float lowest_ratio = smoothness_lowest_ratio(options.exponent);
  const int table_width = box.width + 1;
  out.area_sums.resize(box.width);
  out.smooth_sums.resize(box.width);
  out.padded_columns.resize(static_cast<size_t>(box.width) + 2 * radius + 1);
  out.powers.resize(box.width);
  out.results.resize(box.width);
  // Only the cells with triangles are scored; start_score left the others 0.
  for (int y = 0; y < box.height; ++y) {
    const auto [first, end] = spans[y];
    if (first >= end) continue;
    const int count = end - first;
    const size_t top = static_cast<size_t>(std::max(0, y - radius)) * table_width;
    const size_t bottom = static_cast<size_t>(std::min(box.height, y + radius + 1)) * table_width;
    window_sums_row(out.area_table.data() + top, out.area_table.data() + bottom, box.width, radius, first, count, out.padded_columns.data(),
                    out.area_sums.data());
    window_sums_row(out.smooth_area_table.data() + top, out.smooth_area_table.data() + bottom, box.width, radius, first, count,
                    out.padded_columns.data(), out.smooth_sums.data());
    smoothness_score_row(mesh.triangles.data() + (box.y + y) * mesh.width + box.x + first, out.area_sums.data() + first,
                         out.smooth_sums.data() + first, count, options.exponent, lowest_ratio, out.powers.data(), out.results.data(),
                         &out.cell(box.x + first, box.y + y));
  }
}

namespace {

// Bit i (i < kLanes) set where column i of `rows` rows of a mesh holds a triangle whose mean depth
// lies within √distance2 of z: the columns of a search's window where a triangle may be near.
// `bits` and `depth` start at the first row's first cell and pixel, rows `width` apart; each row
// reads kLanes bits, and kLanes + 1 depths of it and of the row below. The mean depths are
// has_triangle_near's, the same floats, and so is the test on them.
template <int kLanes>
inline std::uint32_t near_depth_columns(const std::uint8_t* __restrict bits, const float* __restrict depth, int width, int rows, float z,
                                        float distance2) {
  const float third = 1.0f / 3.0f, none = std::numeric_limits<float>::infinity();
  std::uint32_t near[kLanes] = {};
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* __restrict row_bits = bits + static_cast<size_t>(r) * width;
    const float* __restrict z0 = depth + static_cast<size_t>(r) * width;
    const float* __restrict z1 = z0 + width;
    // Widened first: GCC vectorises the loop below only over lanes of one width.
    std::uint32_t cell_bits[kLanes];
    for (int i = 0; i < kLanes; ++i) cell_bits[i] = row_bits[i];
    for (int i = 0; i < kLanes; ++i) {
      const float upper = select_if(cell_bits[i] & kUpperTriangle, (z0[i] + z1[i] + z0[i + 1]) * third - z, none);
      const float lower = select_if((cell_bits[i] & kLowerTriangle) >> 1, (z0[i + 1] + z1[i] + z1[i + 1]) * third - z, none);
      near[i] |= static_cast<std::uint32_t>(upper * upper < distance2) | static_cast<std::uint32_t>(lower * lower < distance2);
    }
  }
  std::uint32_t columns = 0;
  for (int i = 0; i < kLanes; ++i) columns |= near[i] << i;
  return columns;
}

// The same over 8 columns (windows up to 3 cells each way) and 16 (up to 7).
ZF_ROW_KERNEL std::uint32_t near_depth_columns8(const std::uint8_t* __restrict bits, const float* __restrict depth, int width, int rows, float z,
                                                float distance2) {
  return near_depth_columns<8>(bits, depth, width, rows, z, distance2);
}
ZF_ROW_KERNEL std::uint32_t near_depth_columns16(const std::uint8_t* __restrict bits, const float* __restrict depth, int width, int rows,
                                                 float z, float distance2) {
  return near_depth_columns<16>(bits, depth, width, rows, z, distance2);
}

}  // namespace

bool has_triangle_near(const MeshView& view, const ViewPoint& p, float distance, int max_window) {
  const Eigen::Vector3f& q = p.in_camera;
  if (!(q.z() > 0) || !(std::abs(p.x) < 1e6f && std::abs(p.y) < 1e6f)) return false;
  const DepthMesh& mesh = *view.mesh;
  const float fx = view.fx, cx = view.cx, cy = view.cy;
  const int window = std::clamp(ceil_to_int(distance * fx / q.z()), 1, max_window);
  // Triangle centres sit at 1/3 and 2/3 of a cell, so the cells whose index is within the window
  // of floor(pixel) hold every centre within `window` pixels. The same surface is usually found
  // in the first rings, so rings are searched from the centre outwards.
  const int cu = floor_to_int(p.x), cv = floor_to_int(p.y);
  const int width = mesh.width, last_u = mesh.width - 2, last_v = mesh.height - 2;
  const float distance2 = distance * distance;
  const float inv_fx = view.inv_fx, inv_fy = view.inv_fy, third = 1.0f / 3.0f;
  const float* depth = mesh.depth.data();
  const std::uint8_t* triangles = mesh.triangles.data();
  // Is the centre of a triangle with mean depth zc, whose centre lies `x_extra`, `y_extra` (in
  // depth-weighted pixels) right of and below the cell's pixel, within the distance?
  auto centre_near = [&](int u, int v, float zc, float x_extra, float y_extra) {
    const float dz = zc - q.z();
    if (dz * dz >= distance2) return false;
    const float dx = ((static_cast<float>(u) - cx) * zc + x_extra) * inv_fx - q.x();
    const float dy = ((static_cast<float>(v) - cy) * zc + y_extra) * inv_fy - q.y();
    return dx * dx + dy * dy + dz * dz < distance2;
  };
  // Most searches lie wholly inside the image: their cells need no bounds tests.
  const bool inside = cu - window >= 0 && cv - window >= 0 && cu + window <= last_u && cv + window <= last_v;
  auto cell_has_near = [&](int u, int v) {
    if (!inside && (u < 0 || v < 0 || u > last_u || v > last_v)) return false;
    const int cell = v * width + u;
    const std::uint8_t bits = triangles[cell];
    if (!bits) return false;
    const float z00 = depth[cell], z10 = depth[cell + 1], z01 = depth[cell + width], z11 = depth[cell + width + 1];
    // Upper (p, b, r): centre x = ((u − cx)·3zc + z10) / 3fx; lower (r, b, d) likewise.
    return ((bits & kUpperTriangle) && centre_near(u, v, (z00 + z01 + z10) * third, z10 * third, z01 * third)) ||
           ((bits & kLowerTriangle) && centre_near(u, v, (z10 + z01 + z11) * third, (z10 + z11) * third, (z01 + z11) * third));
  };
  if (cell_has_near(cu, cv)) return true;
  // A window wholly off the image holds no cell (one that reaches into it from outside is
  // scanned: a ring off the image does not mean the next one is).
  if (cu + window < 0 || cu - window > last_u || cv + window < 0 || cv - window > last_v) return false;
  // Where the scan goes on past the rings most searches end in (p's cell for narrow windows, the
  // first ring for wide ones), the columns of the window that hold a triangle whose mean depth is
  // near p's are found first, a row at a time as vectors, and only their cells are scanned: most
  // of the searches that get this far find nothing (on samba-4cam two in three of the seams' and
  // nine in ten of FRBR's), and most of those find no such column. Searches wholly inside the
  // image, far enough from its right edge for the rows' reads, and no wider than one read (16
  // columns; windows are at most 4 cells each way by default).
  const int span = 2 * window + 1, lanes = span <= 8 ? 8 : 16;
  const int filter_ring = window <= 2 ? 1 : 2;
  bool columns_known = false;
  std::uint32_t columns = 0;  // where known, bit k: column cu − window + k may hold a near triangle
  for (int ring = 1; ring <= window; ++ring) {
    if (ring == filter_ring && inside && span <= lanes && cu - window + lanes + 1 <= width) {
      const int first = (cv - window) * width + cu - window;
      columns = (lanes == 8 ? near_depth_columns8(triangles + first, depth + first, width, span, q.z(), distance2)
                            : near_depth_columns16(triangles + first, depth + first, width, span, q.z(), distance2)) &
                ((1u << span) - 1);
      if (columns == 0) return false;
      columns_known = true;
    }
    auto column_may_be_near = [&](int u) { return !columns_known || ((columns >> (u - cu + window)) & 1) != 0; };
    for (int d = -ring; d <= ring; ++d) {
      if (column_may_be_near(cu + d) && (cell_has_near(cu + d, cv - ring) || cell_has_near(cu + d, cv + ring))) return true;
    }
    if (column_may_be_near(cu - ring)) {
      for (int d = -ring + 1; d <= ring - 1; ++d) {
        if (cell_has_near(cu - ring, cv + d)) return true;
      }
    }
    if (column_may_be_near(cu + ring)) {
      for (int d = -ring + 1; d <= ring - 1; ++d) {
        if (cell_has_near(cu + ring, cv + d)) return true;
      }
    }
  }
  return false;
}

namespace {

// Calls f(cell, bits) for every other cell of `mesh`'s depth box (a checkerboard) that holds a
// triangle, in row order, until f returns true; the sample overlap_share counts.
template <typename F>
void for_each_sampled_cell(const DepthMesh& mesh, F&& f) {
  const PixelBox box = mesh.box();
  for (int v = box.v0; v < box.v1; ++v) {
    for (int u = box.u0 + ((v + box.u0) & 1); u < box.u1; u += 2) {
      const int cell = v * mesh.width + u;
      const std::uint8_t bits = mesh.triangles[cell];
      if (bits && f(cell, bits)) return;
    }
  }
}

// Does a sampled triangle of `a` (cell `cell`, bits `bits`: the upper triangle where there is
// one) have a triangle of b within `distance`? Points where b sees no surface near their depth
// (outside its image, or another surface in front or behind) are answered without a search.
bool sampled_triangle_near(const MeshView& a, const MeshView& b, const Rigid3f& b_from_a_camera, float distance, int cell,
                           std::uint8_t bits) {
  const TriangleBit bit = (bits & kUpperTriangle) ? kUpperTriangle : kLowerTriangle;
  const ViewPoint centre = project_camera_point(b, transform_point(b_from_a_camera, camera_triangle_centre(a, cell, bit)));
  return may_see_surface(b, centre, 2 * distance) && has_triangle_near(b, centre, distance);
}

}  // namespace

double overlap_share(const MeshView& a, const MeshView& b, float distance) {
  const Rigid3f b_from_a_camera = b_from_a(a, b);
  int total = 0, near = 0;
  for_each_sampled_cell(*a.mesh, [&](int cell, std::uint8_t bits) {
    ++total;
    near += sampled_triangle_near(a, b, b_from_a_camera, distance, cell, bits);
    return false;
  });
  return total ? static_cast<double>(near) / total : 0.0;
}

bool overlap_reaches(const MeshView& a, const MeshView& b, float distance, double min_share) {
  int total = 0;
  for_each_sampled_cell(*a.mesh, [&](int, std::uint8_t) {
    ++total;
    return false;
  });
  // A share of 0 (no sample, or nothing near) reaches only a minimum of 0 or less.
  if (total == 0 || 0.0 >= min_share) return 0.0 >= min_share;
  // The share only grows as the sample is searched: the test is decided at the first search that
  // brings it to min_share (the same comparison overlap_share's result would meet).
  const Rigid3f b_from_a_camera = b_from_a(a, b);
  int near = 0;
  bool reached = false;
  for_each_sampled_cell(*a.mesh, [&](int cell, std::uint8_t bits) {
    near += sampled_triangle_near(a, b, b_from_a_camera, distance, cell, bits);
    reached = static_cast<double>(near) / total >= min_share;
    return reached;
  });
  return reached;
}

FrbrResult remove_redundant_boundaries(const MeshView& a, const MeshView& b, float redundancy_distance, bool whole_first_sweep,
                                       const OverlapMask& mask_a, const OverlapMask& mask_b, FrbrScratch& scratch_a,
                                       FrbrScratch& scratch_b) {
  FrbrResult result;
  start_worklist(*a.mesh, whole_first_sweep, scratch_a);
  start_worklist(*b.mesh, whole_first_sweep, scratch_b);
  bool whole_sweep = whole_first_sweep;
  while (true) {
    const int removed_a = sweep(a, b, redundancy_distance, whole_sweep, mask_a, scratch_a);
    const int removed_b = sweep(b, a, redundancy_distance, whole_sweep, mask_b, scratch_b);
    whole_sweep = false;
    ++result.iterations;
    result.removed_a += removed_a;
    result.removed_b += removed_b;
    if (removed_a == 0 && removed_b == 0) break;
  }
  return result;
}

void compute_overlap_mask(const MeshView& a, const MeshView& b, float depth_tolerance, OverlapMask& mask) {
  const DepthMesh& mesh = *a.mesh;
  mask.width = mesh.width;
  mask.level = a.level;
  mask.cells.assign(mesh.depth.size(), 0);
  const Rigid3f b_from_a_camera = b_from_a(a, b);
  const PixelRays rays(a.intrinsics, b_from_a_camera);  // a's pixels straight into b's camera frame
  const PixelBox box = mesh.box();
  for (int v = box.v0; v < box.v1; ++v) {
    for (int u = box.u0; u < box.u1; ++u) {
      const int cell = v * mesh.width + u;
      const float z = mesh.depth[cell];
      if (z > 0 && may_see_surface(b, project_camera_point(b, rays.point(u, v, z)), depth_tolerance)) mask.cells[cell] = 255;
    }
  }
  // Dilated by the reach of the finest level's window search (4 pixels) in this level's cells.
  const int reach = (4 + (1 << a.level) - 1) >> a.level;
  dilate_binary(mask.cells.data(), mask.cells.data(), mesh.width, mesh.height, reach, mask.binary_image);
}

void downsample_mesh(const DepthMesh& fine, int level, DepthJump max_depth_jump, DepthMesh& coarse) {
  const int step = 1 << level;
  reset_depth_mesh(coarse, (fine.width - 1) / step + 1, (fine.height - 1) / step + 1);
  // Coarse pixel (u, v) is fine pixel (u·step, v·step): the same rays, steps scaled.
  coarse.rays = fine.rays;
  coarse.rays.ray_du = fine.rays.ray_du * static_cast<float>(step);
  coarse.rays.ray_dv = fine.rays.ray_dv * static_cast<float>(step);
  // The coarse pixels whose fine pixel lies in the fine mesh's depth box.
  const PixelBox fine_box = fine.box();
  if (fine_box.empty()) {
    coarse.depth_box = {};
    return;
  }
  const PixelBox box{(fine_box.u0 + step - 1) / step, (fine_box.v0 + step - 1) / step, (fine_box.u1 - 1) / step + 1,
                     (fine_box.v1 - 1) / step + 1};
  coarse.depth_box = box;
  // Row by row as triangulate_sdc goes: only the coarse pixels within the span of the fine row's
  // pixels with depth are copied (the others keep the 0 reset_depth_mesh left), and the cells of
  // the row above are formed where the spans meet (sdc_row_between_spans).
  const DepthJump threshold = max_depth_jump.scaled(static_cast<float>(step));
  std::pair<int, int> above{0, 0};
  for (int v = box.v0; v < box.v1; ++v) {
    const size_t source_row = static_cast<size_t>(v) * step * fine.width;
    const auto [fine_first, fine_end] = positive_span(fine.depth.data() + source_row + fine_box.u0, fine_box.u1 - fine_box.u0);
    std::pair<int, int> here{0, 0};
    if (fine_first < fine_end) here = {(fine_box.u0 + fine_first + step - 1) / step, (fine_box.u0 + fine_end + step - 1) / step};
    float* row = coarse.depth.data() + static_cast<size_t>(v) * coarse.width;
    for (int u = here.first; u < here.second; ++u) row[u] = fine.depth[source_row + static_cast<size_t>(u) * step];
    sdc_row_between_spans(coarse.depth.data(), coarse.width, v, above, here, threshold, coarse.triangles.data());
    above = here;
  }
}

int propagate_removals(const std::vector<std::uint8_t>& coarse_before, const DepthMesh& coarse, DepthMesh& fine) {
  // A coarse cell covers 2×2 fine cells. Its upper triangle (x + y < 2 in fine units) covers both
  // triangles of fine cell (0,0) and the upper ones of (1,0) and (0,1); its lower triangle the
  // lower ones of (1,0) and (0,1) and both of (1,1).
  int cleared = 0;
  auto clear = [&](int fu, int fv, std::uint8_t bits) {
    if (fu >= fine.width - 1 || fv >= fine.height - 1) return;
    std::uint8_t& cell = fine.triangles[fv * fine.width + fu];
    cleared += ((cell & bits & kUpperTriangle) ? 1 : 0) + ((cell & bits & kLowerTriangle) ? 1 : 0);
    cell &= static_cast<std::uint8_t>(~bits);
  };
  // A removed coarse triangle next to a kept one is not propagated: along the line where the two
  // meshes meet, a coarse cell straddles both owners, and clearing all its fine triangles would
  // cut a hole wider than the seam can close. The finer level decides there.
  auto next_to_kept = [&](int cell, TriangleBit bit) {
    int neighbours[3];
    const int n = triangle_neighbours(triangle_id(cell, bit), coarse.width, neighbours);
    for (int k = 0; k < n; ++k) {
      if (coarse.triangles[cell_of(neighbours[k])] & bit_of(neighbours[k])) return true;
    }
    return false;
  };
  auto propagate_cell = [&](int i) {
    std::uint8_t removed = coarse_before[i] & static_cast<std::uint8_t>(~coarse.triangles[i]);
    if (!removed) return;
    if ((removed & kUpperTriangle) && next_to_kept(i, kUpperTriangle)) removed &= static_cast<std::uint8_t>(~kUpperTriangle);
    if ((removed & kLowerTriangle) && next_to_kept(i, kLowerTriangle)) removed &= static_cast<std::uint8_t>(~kLowerTriangle);
    if (!removed) return;
    const int fu = 2 * (i % coarse.width), fv = 2 * (i / coarse.width);
    if (removed & kUpperTriangle) {
      clear(fu, fv, kUpperTriangle | kLowerTriangle);
      clear(fu + 1, fv, kUpperTriangle);
      clear(fu, fv + 1, kUpperTriangle);
    }
    if (removed & kLowerTriangle) {
      clear(fu + 1, fv, kLowerTriangle);
      clear(fu, fv + 1, kLowerTriangle);
      clear(fu + 1, fv + 1, kUpperTriangle | kLowerTriangle);
    }
  };
  // Few cells lost a triangle: eight cells at a time, those that did found from the word of
  // removed bits (propagation changes only the fine mesh, so the words can be formed first).
  const int cells = coarse.width * coarse.height;
  int i = 0;
  for (; i + 8 <= cells; i += 8) {
    std::uint64_t before, now;
    std::memcpy(&before, coarse_before.data() + i, sizeof before);
    std::memcpy(&now, coarse.triangles.data() + i, sizeof now);
    for_each_nonzero_byte_in_word(before & ~now, [&](int k) { propagate_cell(i + k); });
  }
  for (; i < cells; ++i) propagate_cell(i);
  return cleared;
}

}  // namespace zipfusion
