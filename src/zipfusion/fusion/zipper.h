#pragma once
//! \file
//! Zippering (paper Sections III-C, III-D): the per-camera SDC meshes of one frame set become one
//! connected mesh. For every overlapping camera pair: coarse-to-fine redundant boundary removal,
//! then clipping by re-triangulation of the seam; finally the kept triangles and the seam
//! triangles are assembled with shared vertices.
//!
//! Pairs are scheduled in rounds in which no camera appears twice; the pairs of a round run in
//! parallel. Thread safety: one ZipperScratch per concurrent call.

#include <chrono>
#include <cstdint>
#include <span>
#include <vector>

#include "zipfusion/core/mesh.h"
#include "zipfusion/depth/sdc_mesh.h"
#include "zipfusion/fusion/clipping.h"
#include "zipfusion/fusion/redundancy.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

//! Which camera keeps a surface that two see (redundancy.h, OwnershipScore).
enum class Ownership {
  kAuto,        // smoothness on unfiltered depth, border on filtered (ReconstructOptions::ownership; here: border)
  kBorder,      // the camera that sees it farther inside its own coverage (more frontally)
  kSmoothness,  // the camera whose own surface is smoother there (less noise)
};

struct ZipperOptions {
  double redundancy_distance_m = 0.03;  // d_r (III-C): triangles closer than this to another camera's are redundant
  int coarse_levels = 2;                // L (III-C2): FRBR starts on depth maps downsampled by 2^L
  double coarse_shrink = 0.85;          // β (III-C2): d_r at level l is β^l·d_r
  double clipping_distance_m = 0.008;   // d_c (III-D1): triangles this close to the other mesh are re-triangulated
  Ownership ownership = Ownership::kAuto;
  int hole_closing_px = 3;              // border: holes up to 2·this+1 pixels wide do not count as borders
  int smoothness_window_px = 250;       // smoothness: compared over windows this wide (pixels)
  double smoothness_exponent = 96;      // smoothness: exponent of the area ratio, how much smoother outweighs a mesh's border
  double max_seam_edge_m = 0.04;        // (III-D4) seam triangles with a longer edge are dropped
  // Seams: each point lies at the mean depth of its surface over (2·this+1)² pixels of the
  // meshes (SeamOptions::smoothing_radius); 0: as measured; −1: auto
  // (ReconstructOptions::seam_smoothing_px(): 2 on unfiltered depth, 1 on filtered; here: 2).
  int seam_smoothing_px = -1;
  int seam_fairing_iterations = 1;      // seams: rounds of smoothing their points along their rays, then the creases' corners (SeamOptions::fairing_iterations); 0: neither
  bool seam_crease_watch = true;        // seams: each step after the first looks for creases where they can be (SeamOptions::crease_watch); false: on every edge, the reference (tests)
  double min_overlap_share = 0.01;      // a pair overlaps when this share of one mesh lies within d_r of the other
  double sdc_max_depth_jump_m = 0.03;   // the SDC threshold of input meshes that give none (ZipperCamera); coarse levels scale it by 2^level
  double sdc_growth_depth_m = SdcOptions{}.growth_depth_m;  // the input meshes' SdcOptions::growth_depth_m (their coarse levels grow alike)
  int depth_level = 0;                  // the meshes' depth is subsampled by 2^this (ReconstructOptions::depth_level)
  int num_threads = 0;                  // 0 = all hardware threads

  void validate() const;  // throws InvalidInput naming the field
};

//! One camera's input: its full-resolution mesh (modified: removed triangles' bits are cleared),
//! its colour image, and its model.
struct ZipperCamera {
  DepthMesh* mesh = nullptr;  // null: the camera has no depth in this frame set
  const ColorImage* color = nullptr;  // null: the camera's vertices are grey
  const CameraModel* model = nullptr;
  double max_depth_jump_m = 0;  // the SDC threshold its mesh was made with; 0: ZipperOptions::sdc_max_depth_jump_m
};

struct ZipperStats {
  double pyramid_ms = 0;     // building the coarse levels
  double overlap_ms = 0;     // finding overlapping pairs
  double redundancy_ms = 0;  // FRBR at every level, with propagation
  double clipping_ms = 0;    // seams: detection, Delaunay, filtering
  double assemble_ms = 0;    // one mesh with shared vertices
  // The colours of the mesh's vertices (only those: most pixels' triangles are removed or
  // clipped), looked up beside assembly's serial last part: only the time after assembly ends.
  double color_ms = 0;
  int pairs = 0;
  int redundant_removed = 0;  // full-resolution triangles removed as redundant (incl. propagated)
  int seam_taken = 0;         // triangles replaced by seams
  int seam_added = 0;         // seam triangles created
  int seam_rejected = 0;      // seam triangles dropped for reusing a directed edge (overlap) or mirroring another seam's
  int seam_pca = 0;           // seams laid out on their PCA plane (a point behind the virtual camera)
  int seam_crease_gaps = 0;   // seam faces left out at a crease nothing else mended, each a one-triangle gap
};

struct ZipperResult {
  TriangleMesh mesh;
  ZipperStats stats;
};

//! Camera pairs grouped into rounds in which no camera appears twice, as CSR of the pairs'
//! indices (in the list given to schedule_pairs): round r is by_round[round_begin[r]] up to
//! by_round[round_begin[r + 1]].
struct PairRounds {
  std::vector<int> by_round;                  // the pairs' indices by round, each round's in their given order
  std::vector<int> round_begin;               // one more than there are rounds
  std::vector<int> round_of_pair;             // per pair as given, its round
  std::vector<int> next;                      // scratch of schedule_pairs
  std::vector<std::uint8_t> camera_in_round;  // scratch of schedule_pairs: whether camera c is in round r

  size_t count() const { return round_begin.empty() ? 0 : round_begin.size() - 1; }
  std::span<const int> round(size_t r) const {
    return {by_round.data() + round_begin[r], static_cast<size_t>(round_begin[r + 1] - round_begin[r])};
  }
};

//! Scratch space reused across frames.
struct ZipperScratch {
  struct Camera {
    std::vector<DepthMesh> levels;                       // levels 1..L (index level−1)
    OwnershipScore ownership;                            // on one coarse level, for ownership at every level
    std::vector<std::vector<std::uint8_t>> bits_before;  // per level 1..L, the SDC bits before any removal
    FrbrScratch frbr;
    SeamScratch seam;
    std::vector<std::uint8_t> taken_round;  // clipping: per triangle id, the 1-based round of the seam that took it, else 0
    std::vector<std::uint16_t> seam_at_pixel;  // clipping: per pixel, the seam it is a vertex of (SeamPixelMap::seam)
    std::vector<int> seam_vertex_at_pixel;     // clipping: per pixel of one seam, its index among the seam's vertices
    std::vector<std::uint8_t> used;       // assembly: per pixel, whether a kept or seam triangle uses it
    std::vector<int> vertex_of_pixel;     // assembly: per used pixel, its index among the camera's vertices
    std::vector<std::uint8_t> boundary_rows;  // collect_boundary_triangles' scratch
  };
  std::vector<Camera> cameras;
  // Per overlapping pair (in `pairs` order): where the second camera sees the first's
  // coarsest level, and the reverse.
  std::vector<std::pair<OverlapMask, OverlapMask>> masks;
  std::vector<TakenSeam> taken;       // clipping: per pair, its seam between taking and stitching
  std::vector<StitchScratch> stitch;  // clipping: per pair, stitch_seam's work space
  // zipper_meshes' own lists, kept for their capacity: the cameras with a mesh, each camera's view
  // at each level, the candidate pairs and whether each overlaps, the pairs' rounds, counts of
  // removals, per camera its output's vertex and triangle counts and offsets, per seam when it
  // was stitched, and the seams by size.
  std::vector<int> active;
  std::vector<std::vector<MeshView>> views;
  std::vector<std::pair<int, int>> candidates;
  std::vector<char> overlaps;
  std::vector<std::pair<int, int>> pairs;  // the overlapping ones, as found by the last call
  PairRounds rounds;
  std::vector<int> propagated_to_full, removed_at_full;
  std::vector<int> vertex_count, triangle_count, vertex_offset, triangle_offset;
  std::vector<std::chrono::steady_clock::time_point> stitched_at;
  std::vector<int> by_size;
  std::vector<int> seam_slot;                // assembly: per output vertex, its slot (index among seam vertices) or -1
  std::vector<PixelVertex> seam_vertices;    // assembly: per slot, its pixel
  std::vector<int> slot_vertex;              // assembly: per slot, its output vertex
  std::vector<int> local_slot;               // assembly: per seam vertex of each seam in turn, its slot
  struct DirectedEdge {
    int to;     // the slot the edge ends at
    int third;  // the slot of its triangle's third corner, or -1 (a kept triangle's corner that is no seam vertex)
  };
  std::vector<std::vector<DirectedEdge>> outgoing;  // assembly: per slot, its directed edges (those of kept and seam triangles)
};

//! `reuse`: a mesh whose buffers the result's mesh is built in (its contents are dropped).
ZipperResult zipper_meshes(const std::vector<ZipperCamera>& cameras, const ZipperOptions& options, ZipperScratch& scratch,
                           TriangleMesh reuse = {});

//! Greedy edge colouring: each pair goes into the first round that has neither of its cameras.
//! The first form reuses `rounds`' arrays.
void schedule_pairs(const std::vector<std::pair<int, int>>& pairs, PairRounds& rounds);
PairRounds schedule_pairs(const std::vector<std::pair<int, int>>& pairs);

}  // namespace zipfusion
