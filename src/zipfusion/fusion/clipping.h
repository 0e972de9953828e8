#pragma once
//! \file
//! Mesh clipping by re-triangulation (paper Section III-D): after redundancy removal two meshes
//! face each other across a gap of about d_r. The triangles of each within d_c (> d_r) of the other
//! are taken out, their vertices (each pixel once) are projected to 2-D and triangulated by
//! Delaunay (CGAL); triangles with an edge longer than max_edge, or lying over a kept triangle of
//! either mesh, are dropped. What remains stitches the two meshes into one.
//!
//! Projection: the paper projects onto the seam's PCA plane. A seam that wraps around a body is
//! not planar, so the seam is projected instead through a virtual camera halfway between the two
//! cameras (centre at the midpoint, rotation halfway): every seam point is seen by both cameras,
//! so this projection is one-to-one over the seam however it curves. The PCA plane remains the
//! fallback when a point lies behind the virtual camera (cameras facing each other).
//!
//! The points are projected, and output, where the seam puts them: on their pixel's ray at the
//! mean depth of their surface around it (SeamOptions::smoothing_radius), moved to halfway
//! between the two meshes' layers (consensus), the same positions for both. A triangle that faces
//! the virtual camera in 2-D then faces it in 3-D too (on the PCA fallback: faces the side of the
//! plane the cameras are on), so no seam triangle turns over, as they did wherever a layout at
//! smoothed depth and output at measured depth differed (docs/design.md). The consensus brings
//! both meshes' points close together (a pixel that is a vertex of two seams keeps its place), so
//! the seam does not zigzag between the layers; after the triangulation the points are faired
//! along their rays (SeamOptions::fairing_iterations) without turning a face over in the layout,
//! and a crease left sharper than 60° is flipped out where the other diagonal of its quadrilateral
//! is smoother; the corners of any crease still left move towards their neighbours along the
//! layout's line of sight, off their pixel's ray but not so far that the pixel grid around them
//! folds in their own camera (keeps_pixel_grid_unfolded); a point at a crease left after that
//! leaves the triangulation, and a face at a crease still left is not output (a one-triangle gap
//! instead of a fold). A crease between a seam face and the kept triangle beyond a kept edge
//! counts as one between two seam faces, and no face lies on the kept triangle's side of a kept
//! edge (docs/design.md).

#include <array>
#include <cassert>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#include "zipfusion/fusion/redundancy.h"

namespace zipfusion {

//! A vertex of the final mesh: a pixel of a camera's depth mesh.
struct PixelVertex {
  int camera = 0;
  int pixel = 0;
  friend bool operator==(const PixelVertex&, const PixelVertex&) = default;
};

struct SeamOptions {
  float clipping_distance = 0.03f;  // d_c, metres
  float max_edge = 0.04f;           // longest edge of a seam triangle, metres
  float ownership_distance = 0.02f; // d_r: a seam point of one mesh is dropped where the other owns the surface this close, and moved towards it within this depth
  int smoothing_radius = 2;         // a seam point lies at the mean depth of its surface over (2·this+1)² pixels; 0: as measured
  int fairing_iterations = 1;       // rounds of smoothing the seam's points along their rays (fair_seam), then the creases' corners (relax_creases); 0: neither
  bool crease_watch = true;         // each step after the first looks for creases only where they can be; false: on every edge (the same seams, slower; the tests' reference)
};

struct Seam {
  std::vector<PixelVertex> vertices;
  // Per vertex, world: where the seam puts it (stitch_seam), the output mesh's position; empty
  // for a seam of fewer than 3 vertices (no triangles: its vertices keep their measured points).
  std::vector<Eigen::Vector3f> positions;
  std::vector<Eigen::Vector3i> triangles;  // indices into `vertices`, facing the cameras
  int triangles_taken = 0;                 // original triangles replaced by the seam
  bool used_pca = false;                   // the PCA fallback projection was used
  int creased_faces_dropped = 0;           // faces left out at a crease nothing else mended (each a one-triangle gap)
};

//! Scratch space of one camera for clipping, reused across frames.
struct SeamScratch {
  // Per triangle id while the seam is found (cleared through `visited`), then per pixel: the
  // taken triangles' pixels, until the kept edges are found (cleared through `taken`).
  MarkBits marks;
  std::vector<int> visited;
  std::vector<int> taken;
  std::vector<int> seam_index;  // per pixel: index in Seam::vertices (valid where marked)
  // Candidate boundary triangles, the seeds of the seams: set once per frame before clipping by
  // collect_boundary_triangles (instead of scanning the whole bit matrix for every pair) and
  // grown by each clipping.
  std::vector<int> boundary;
  std::vector<int> seeds;  // the current pair's: boundary triangles inside its overlap mask
  std::vector<ViewPoint> seeds_in_other;  // their centres projected into the pair's other camera
};

//! Which triangles of a mesh count as kept when a seam is triangulated after later seams have
//! already taken theirs out of the same mesh: those still in its bit matrix, and those a later
//! seam took (`taken_round`, per triangle id: the 1-based round of the seam that took it, 0 for
//! none; a seam of round r sees the ones with a later round as kept). Default: the bit matrix.
struct KeptAt {
  const std::uint8_t* taken_round = nullptr;
  int round = 0;
  bool taken_later(int id) const { return taken_round != nullptr && taken_round[id] > round; }
};

//! The seam's neighbour search reaches this many cells each way: after redundancy removal the two
//! meshes meet within a pixel or two, so the other mesh's triangles near a seam triangle lie
//! within 2 cells of its projection; wider windows (up to 4) found the same seams on samba-4cam
//! at 25 % more time.
inline constexpr int kSeamWindow = 2;
static_assert(kSeamWindow == 2, "seam_window_has_triangle reads five cells a row: four bytes as one word, and one more");

//! Element function: false when no cell of `mesh` within kSeamWindow cells of the cell of p (a
//! point projected into the mesh's view, p.cell ≥ 0) holds a triangle, so that a
//! has_triangle_near search with that window cannot find one; true otherwise, and near the
//! image's edges or where p is outside it. Most seam seeds that find no triangle of the other mesh
//! lie where redundancy removal cleared it: this reads five rows of five cells (bytes) instead of
//! searching them (samba-4cam unfiltered: a third of the failed searches).
inline bool seam_window_has_triangle(const DepthMesh& mesh, const ViewPoint& p) {
  if (p.cell < 0) return true;  // p.x, p.y may be anything: the search decides
  const int cu = floor_to_int(p.x), cv = floor_to_int(p.y);
  if (cu < kSeamWindow || cv < kSeamWindow || cu + kSeamWindow > mesh.width - 2 || cv + kSeamWindow > mesh.height - 2) return true;
  const std::uint8_t* row = mesh.triangles.data() + static_cast<size_t>(cv - kSeamWindow) * mesh.width + cu - kSeamWindow;
  std::uint32_t any = 0;
  for (int k = 0; k <= 2 * kSeamWindow; ++k, row += mesh.width) {
    std::uint32_t four;
    std::memcpy(&four, row, sizeof four);
    any |= four | row[4];
  }
  return any != 0;
}

//! Element function: is point p (projected into `view`) covered by a kept triangle of `view`
//! (the triangle under its projection, with a mean depth within `tolerance` of p's)?
bool covered_by_triangle(const MeshView& view, const ViewPoint& p, float tolerance, const KeptAt& kept = {});

//! A camera's pixels that are vertices of the seams being stitched: per pixel, kNoSeam, the
//! number of the one seam it is a vertex of, or kManySeams; and where it is one seam's, its index
//! among that seam's vertices. Stitching reads it to see whether the grid triangles around a
//! point it moves have corners that another seam may move at the same time (a point of several
//! seams moves in none). Views of arrays the zipper fills before the seams are stitched and
//! leaves unchanged until all are: any number of threads may read them meanwhile.
struct SeamPixelMap {
  static constexpr std::uint16_t kNoSeam = 0, kManySeams = 0xFFFF;
  const std::uint16_t* seam = nullptr;  // null: not known (every other corner may be another seam's)
  const int* vertex = nullptr;
};

//! Which pixels of the pair's two cameras are vertices of which seam, and this seam's number.
struct SeamPixels {
  SeamPixelMap a, b;
  std::uint16_t own = SeamPixelMap::kNoSeam;
};

//! How far stitching may take a seam point off its pixel in its own camera, in pixels (the crease
//! relaxation, the one step that moves a point off its pixel's ray): where a grid triangle around
//! it has a corner of another seam, and anywhere. To turn over, a triangle of the pixel grid must
//! pass through a degenerate state, one corner on the segment between the other two; each corner
//! lies at least 1/√2 pixel from that segment and, with all three shifted 0.35 pixel at most,
//! comes at most 0.70 pixel closer to it. The other triangles are tested exactly, which keeps a
//! point within about a pixel of its own; the limit of 1.5 pixels makes sure it stays near the
//! pixel its colour is sampled at (on samba-4cam frames 0, 10, 20 and 30 the seams' folds were
//! the same with a limit of 1 pixel as with none).
inline constexpr float kMostPixelShiftBesideOtherSeam = 0.35f;
inline constexpr float kMostPixelShift = 1.5f;

//! Element function: may seam `own`'s vertex at `pixel` of `view` move to p (world) and leave the
//! pixel grid around it unfolded in the image? Not if one of the six triangles of the grid with
//! the pixel as a corner, kept or not, would turn over in the image: tested exactly where its
//! other corners are on their pixels (no seam's, or several seams', which none moves) or seam
//! `own`'s (at `positions`, indexed through `map`). While none turns over, the point stays inside
//! the polygon of its neighbours, so no kept triangle faces away from the camera or lies over
//! another. Nor if p projects farther than kMostPixelShift from the pixel, or than
//! kMostPixelShiftBesideOtherSeam where a triangle has a corner of another seam (which that seam
//! may move at the same time, under the same bound). `map.seam` null: every other corner counts
//! as another seam's.
bool keeps_pixel_grid_unfolded(const MeshView& view, const SeamPixelMap& map, std::uint16_t own, int pixel, const Eigen::Vector3f& p,
                               const Eigen::Vector3f* positions);

//! The kept triangle on one side of a kept edge (i, j) between seam vertices: its third corner,
//! a pixel of the edge's camera (−1 where both sides of the edge are kept), that corner's index
//! among the seam's vertices (−1 where it is not one), and whether the triangle runs from i to j
//! (else from j to i). Stitching weighs the seam face on the edge's other side against it.
struct KeptSide {
  int third_pixel = -1;
  int third_vertex = -1;
  bool forward = true;
};

//! A seam between its two phases: its vertices chosen and its triangles not yet made.
struct TakenSeam {
  Seam seam;                                      // vertices and triangles_taken; no triangles yet
  std::vector<std::pair<int, int>> constraints;   // the kept edges between seam vertices
  std::vector<KeptSide> kept_sides;               // per constraint: the kept triangle beside it
  std::vector<std::array<int, 3>> kept_triangles; // kept triangles whose corners are all seam vertices (their indices, each triangle once)
  std::vector<int> taken_a, taken_b;              // triangle ids taken out of each mesh
  // Per vertex of the seam: whether another seam has its pixel as a vertex too. Such a point keeps
  // its own place (the seams would move it towards different cameras' surfaces, and the output
  // has one position per pixel). Empty: none is.
  std::vector<std::uint8_t> shared;

  //! Empties it, keeping its arrays' capacity.
  void clear() {
    seam.vertices.clear();
    seam.positions.clear();
    seam.triangles.clear();
    seam.triangles_taken = 0;
    seam.used_pca = false;
    seam.creased_faces_dropped = 0;
    constraints.clear();
    kept_sides.clear();
    kept_triangles.clear();
    taken_a.clear();
    taken_b.clear();
    shared.clear();
  }
};

//! Work space of stitch_seam, reused across frames: one for each seam stitched at the same time.
class StitchScratch {
 public:
  StitchScratch();
  ~StitchScratch();
  StitchScratch(StitchScratch&&) noexcept;
  StitchScratch& operator=(StitchScratch&&) noexcept;
  struct Buffers;  // clipping.cc: arrays of types it keeps to itself (CGAL's handles among them)
  Buffers& buffers() {
    assert(buffers_ != nullptr);  // not moved from
    return *buffers_;
  }

 private:
  std::unique_ptr<Buffers> buffers_;
};

//! The first phase: takes the triangles of `a` within d_c of `b` and of `b` within d_c of `a` out
//! of both meshes and chooses the seam's vertices (labelled with the views' camera indices) and
//! the kept edges it must contain. `mask_a` (`mask_b`): where b sees a (a sees b); seams start
//! only inside. Seams of pairs that share a camera must take in a fixed order. `taken` is
//! emptied first (its arrays are kept between frames).
void take_seam(const MeshView& a, const MeshView& b, const SeamOptions& options, const OverlapMask& mask_a, const OverlapMask& mask_b,
               SeamScratch& scratch_a, SeamScratch& scratch_b, TakenSeam& taken);

//! The second phase: the seam's triangles (Delaunay), into taken.seam. Reads the meshes only, so
//! any number run at once; `kept_a`, `kept_b` say which triangles counted as kept when the seam
//! was taken. `centre_a`, `centre_b`: the cameras' centres in the world. `pixels`: which seam
//! each pixel of the two cameras is a vertex of, for every seam being stitched at the same time,
//! and this seam's number there (a default SeamPixels knows none: every point is then held
//! within kMostPixelShiftBesideOtherSeam of its pixel).
void stitch_seam(const MeshView& a, const Eigen::Vector3f& centre_a, const MeshView& b, const Eigen::Vector3f& centre_b,
                 const SeamOptions& options, const KeptAt& kept_a, const KeptAt& kept_b, const SeamPixels& pixels, TakenSeam& taken,
                 StitchScratch& scratch);

}  // namespace zipfusion
