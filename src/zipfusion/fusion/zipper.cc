#include "zipfusion/fusion/zipper.h"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <chrono>
#include <cmath>

#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/core/row_kernel.h"
#include "zipfusion/core/stopwatch.h"
#include "zipfusion/depth/color_lookup.h"

namespace zipfusion {
namespace {

using Clock = std::chrono::steady_clock;

// Calls `f` when it goes out of scope unless dismissed: clean-up that must also run when an
// exception passes.
template <typename F>
class OnScopeExit {
 public:
  explicit OnScopeExit(F f) : f_(std::move(f)) {}
  OnScopeExit(const OnScopeExit&) = delete;
  OnScopeExit& operator=(const OnScopeExit&) = delete;
  ~OnScopeExit() {
    if (armed_) f_();
  }
  void dismiss() { armed_ = false; }

 private:
  F f_;
  bool armed_ = true;
};


// Pyramid level of the ownership score. Level 1 (320×240 for a Kinect): for the border distance
// it scored as per-level distances did (samba-4cam: accuracy, completeness and components alike;
// the 3-camera ring of zipper_quality_test kept its 2 large components) at a quarter of the cost
// of level 0, and level 2 split that ring into 5 pieces; for the smoothness, level 0 left the
// area on samba-4cam as it was but doubled the seams' (docs/design.md).
constexpr int kScoreLevel = 1;

// pixel_used for the pixels u0..u1−1 of row v; the first column and row read no cell outside
// the image.
ZF_ROW_KERNEL void mark_used_pixels_row(const std::uint8_t* triangles, int width, int v, int u0, int u1, std::uint8_t* used_row) {
  const std::uint8_t* row = triangles + v * width;
  const std::uint8_t* above = v > 0 ? row - width : nullptr;
  int u = u0;
  if (u == 0 && u < u1) {
    used_row[0] = pixel_used(row[0], 0, above ? above[0] : 0, 0);
    ++u;
  }
  if (above == nullptr) {
    for (; u < u1; ++u) used_row[u] = pixel_used(row[u], row[u - 1], 0, 0);
    return;
  }
  for (; u < u1; ++u) used_row[u] = pixel_used(row[u], row[u - 1], above[u], above[u - 1]);
}

// The number of used pixels among `count`.
ZF_ROW_KERNEL int count_used_row(const std::uint8_t* used, int count) {
  int n = 0;
  for (int i = 0; i < count; ++i) n += used[i];
  return n;
}

// Calls task(k) for every k in [0, count), in order, each taken by whichever of up to
// num_threads threads (0 = all) is free: for a few tasks of unequal length, where parallel_for's
// contiguous blocks would leave a thread idle while another still has several.
void run_tasks_in_turn(int count, int num_threads, IndexFunctionRef task) {
  const int threads = std::max(1, std::min(count, num_threads > 0 ? num_threads : hardware_threads()));
  std::atomic<int> next{0};
  parallel_for(0, threads, [&](int) {
    for (int k; (k = next.fetch_add(1)) < count;) task(k);
  }, threads);
}

}  // namespace

void ZipperOptions::validate() const {
  // A tenth of a metre: 3σ of a Kinect's depth noise at its 4.5 m limit. Beyond it distinct parts
  // of a body (an arm beside the torso) count as one surface, seams web over the gaps between them
  // and fold (a review: --max-seam-edge 0.2 took the accuracy from 1.7 to 5.4 mm, 0.5 to 18.6 mm;
  // --redundancy-distance 0.2 the completeness from 95.6 to 72.2 %). Seams re-triangulated over
  // wider strips fold sooner: --clipping-distance 0.05 gave 51 folded edges (the separate meshes
  // 46, the default 15), 0.1 gave 200.
  constexpr double kLongestZipperDistance = 0.1, kLongestClippingDistance = 0.05;
  if (!(redundancy_distance_m > 0 && redundancy_distance_m <= kLongestZipperDistance)) throw InvalidInput("--redundancy-distance: must be in (0, 0.1] metres");
  if (coarse_levels < 0 || coarse_levels > 4) throw InvalidInput("--coarse-levels: must be in [0, 4]");
  if (!(coarse_shrink > 0 && coarse_shrink <= 1)) throw InvalidInput("--coarse-shrink: must be in (0, 1]");
  if (!(clipping_distance_m > 0 && clipping_distance_m <= kLongestClippingDistance)) throw InvalidInput("--clipping-distance: must be in (0, 0.05] metres");
  if (hole_closing_px < 0 || hole_closing_px > 32) throw InvalidInput("--hole-closing: must be in [0, 32] pixels");
  if (smoothness_window_px < 1 || smoothness_window_px > 256) throw InvalidInput("--smoothness-window: must be in [1, 256] pixels");
  if (!(smoothness_exponent > 0 && smoothness_exponent <= 128)) throw InvalidInput("--smoothness-exponent: must be in (0, 128]");
  if (!(max_seam_edge_m > 0 && max_seam_edge_m <= kLongestZipperDistance)) throw InvalidInput("--max-seam-edge: must be in (0, 0.1] metres");
  if (seam_smoothing_px < -1 || seam_smoothing_px > 4) throw InvalidInput("--seam-smoothing: must be in [0, 4] pixels, or -1 for auto");
  if (seam_fairing_iterations < 0 || seam_fairing_iterations > 8) throw InvalidInput("--seam-fairing: must be in [0, 8] rounds");
  if (!(min_overlap_share >= 0 && min_overlap_share < 1)) throw InvalidInput("--min-overlap: must be in [0, 1)");
}

void schedule_pairs(const std::vector<std::pair<int, int>>& pairs, PairRounds& rounds) {
  // Each pair into the first round that has neither of its cameras yet, found from the rounds
  // each camera is in. A camera of c pairs is in c rounds, so a pair's first free round comes
  // before the sum of its two cameras' pairs: fewer than twice the cameras.
  int cameras = 0;
  for (const auto& [a, b] : pairs) {
    assert(a >= 0 && b >= 0);
    cameras = std::max({cameras, a + 1, b + 1});
  }
  const int most_rounds = 2 * cameras;
  std::vector<std::uint8_t>& in_round = rounds.camera_in_round;
  in_round.assign(static_cast<size_t>(cameras) * most_rounds, 0);
  rounds.round_of_pair.assign(pairs.size(), 0);
  int round_count = 0;
  for (size_t k = 0; k < pairs.size(); ++k) {
    std::uint8_t* const rounds_of_a = in_round.data() + static_cast<size_t>(pairs[k].first) * most_rounds;
    std::uint8_t* const rounds_of_b = in_round.data() + static_cast<size_t>(pairs[k].second) * most_rounds;
    int round = 0;
    while (rounds_of_a[round] || rounds_of_b[round]) ++round;
    assert(round < most_rounds);
    rounds_of_a[round] = rounds_of_b[round] = 1;
    rounds.round_of_pair[k] = round;
    round_count = std::max(round_count, round + 1);
  }
  // Each round's pairs in their given order (a counting sort by round).
  rounds.round_begin.assign(round_count + 1, 0);
  for (const int round : rounds.round_of_pair) ++rounds.round_begin[round + 1];
  for (int r = 0; r < round_count; ++r) rounds.round_begin[r + 1] += rounds.round_begin[r];
  rounds.by_round.resize(pairs.size());
  rounds.next.assign(rounds.round_begin.begin(), rounds.round_begin.end() - 1);
  for (size_t k = 0; k < pairs.size(); ++k) rounds.by_round[rounds.next[rounds.round_of_pair[k]]++] = static_cast<int>(k);
}

PairRounds schedule_pairs(const std::vector<std::pair<int, int>>& pairs) {
  PairRounds rounds;
  schedule_pairs(pairs, rounds);
  return rounds;
}

ZipperResult zipper_meshes(const std::vector<ZipperCamera>& cameras, const ZipperOptions& options, ZipperScratch& scratch,
                           TriangleMesh reuse) {
  ZipperResult result;
  result.mesh = std::move(reuse);
  const int camera_count = static_cast<int>(cameras.size());
  const int levels = options.coarse_levels;
  scratch.cameras.resize(camera_count);
  std::vector<int>& active = scratch.active;
  active.clear();
  for (int c = 0; c < camera_count; ++c) {
    if (cameras[c].mesh != nullptr) active.push_back(c);
  }

  // Views of every camera at every level: level 0 is the full-resolution mesh itself.
  std::vector<std::vector<MeshView>>& views = scratch.views;
  views.resize(camera_count);
  for (std::vector<MeshView>& camera_views : views) camera_views.assign(levels + 1, MeshView{});
  Clock::time_point t = Clock::now();
  parallel_for(0, static_cast<int>(active.size()), [&](int i) {
    const int c = active[i];
    ZipperScratch::Camera& s = scratch.cameras[c];
    s.levels.resize(levels);
    s.bits_before.resize(levels);
    const Rigid3f depth_from_world = cameras[c].model->world_from_depth.inverse().cast<float>();
    assert(cameras[c].max_depth_jump_m >= 0);
    const DepthJump sdc = depth_jump(cameras[c].max_depth_jump_m > 0 ? cameras[c].max_depth_jump_m : options.sdc_max_depth_jump_m,
                                     options.sdc_growth_depth_m);
    // One surface for the same-surface tests: the SDC threshold where it does not grow (the
    // grown one excuses a far surface's depth steps, not a gap between two surfaces).
    const float jump = sdc.at_least_m;
    views[c][0] = {cameras[c].mesh, subsampled_intrinsics(cameras[c].model->depth_intrinsics, 0), depth_from_world, &s.ownership, c, 0, jump};
    for (int level = 1; level <= levels; ++level) {
      downsample_mesh(*cameras[c].mesh, level, sdc, s.levels[level - 1]);
      s.bits_before[level - 1] = s.levels[level - 1].triangles;  // what propagation compares against
      views[c][level] = {&s.levels[level - 1], subsampled_intrinsics(cameras[c].model->depth_intrinsics, level), depth_from_world, &s.ownership, c,
                         level, jump * static_cast<float>(1 << level)};
    }
    // Ownership at every level from one score, on level 1 of the full-resolution depth whatever
    // level of detail the meshes come from.
    const int score_level = std::min(levels, std::max(0, kScoreLevel - options.depth_level));
    if (options.ownership == Ownership::kSmoothness) {
      const SmoothnessOptions smoothness{.window_cells = std::max(1, options.smoothness_window_px >> score_level) | 1,
                                         .exponent = static_cast<float>(options.smoothness_exponent),
                                         .same_surface_m = views[c][score_level].same_surface};
      compute_smoothness(*views[c][score_level].mesh, views[c][score_level].intrinsics, score_level, smoothness, s.ownership);
    } else {
      compute_border_distance(*views[c][score_level].mesh, score_level, std::max(1, options.hole_closing_px >> score_level), s.ownership);
    }
  }, options.num_threads);
  result.stats.pyramid_ms = ms_since(t);

  // Overlapping pairs, judged on the coarsest level.
  t = Clock::now();
  std::vector<std::pair<int, int>>& candidates = scratch.candidates;
  candidates.clear();
  for (size_t i = 0; i < active.size(); ++i) {
    for (size_t j = i + 1; j < active.size(); ++j) candidates.emplace_back(active[i], active[j]);
  }
  std::vector<char>& overlaps = scratch.overlaps;
  overlaps.assign(candidates.size(), 0);
  const float d_r = static_cast<float>(options.redundancy_distance_m);
  parallel_for(0, static_cast<int>(candidates.size()), [&](int i) {
    const auto [a, b] = candidates[i];
    // max(share a→b, share b→a) ≥ the minimum, the second searched only when the first falls short.
    overlaps[i] = overlap_reaches(views[a][levels], views[b][levels], d_r, options.min_overlap_share) ||
                  overlap_reaches(views[b][levels], views[a][levels], d_r, options.min_overlap_share);
  }, options.num_threads);
  std::vector<std::pair<int, int>>& pairs = scratch.pairs;
  pairs.clear();
  for (size_t i = 0; i < candidates.size(); ++i) {
    if (overlaps[i]) pairs.push_back(candidates[i]);
  }
  result.stats.pairs = static_cast<int>(pairs.size());
  if (scratch.masks.size() < pairs.size()) scratch.masks.resize(pairs.size());  // only grows, as taken and stitch
  parallel_for(0, static_cast<int>(pairs.size()), [&](int i) {
    const auto [a, b] = pairs[i];
    compute_overlap_mask(views[a][levels], views[b][levels], 2 * d_r, scratch.masks[i].first);
    compute_overlap_mask(views[b][levels], views[a][levels], 2 * d_r, scratch.masks[i].second);
  }, options.num_threads);
  PairRounds& rounds = scratch.rounds;
  schedule_pairs(pairs, rounds);
  // Clipping marks taken triangles with their round in a byte (greedy colouring needs at most
  // 2n − 3 rounds for n cameras).
  if (rounds.count() > 254) throw InvalidInput("zipper: more than 254 rounds of camera pairs (too many cameras)");
  // Stitching numbers the seams from 1 in 16 bits (SeamPixelMap).
  if (pairs.size() >= SeamPixelMap::kManySeams) throw InvalidInput("zipper: more than 65 534 overlapping camera pairs");
  result.stats.overlap_ms = ms_since(t);

  // Coarse to fine FRBR.
  t = Clock::now();
  // Full-resolution triangles removed: propagated into level 0 and removed there (counted as they
  // go; counting the bit matrices before and after took a quarter of a millisecond on one thread).
  std::vector<int>&propagated_to_full = scratch.propagated_to_full, &removed_at_full = scratch.removed_at_full;
  propagated_to_full.assign(camera_count, 0);
  removed_at_full.assign(pairs.size(), 0);
  // Each finer level starts its frontier from its boundary; the coarsest level's sweeps (whole
  // first sweeps) only add to it, onto the previous frame's, which then grew it again.
  for (int c : active) scratch.cameras[c].frbr.frontier.clear();
  for (int level = levels; level >= 0; --level) {
    if (level < levels) {
      parallel_for(0, static_cast<int>(active.size()), [&](int i) {
        const int c = active[i];
        const int cleared = propagate_removals(scratch.cameras[c].bits_before[level], *views[c][level + 1].mesh, *views[c][level].mesh);
        if (level == 0) propagated_to_full[c] = cleared;
        collect_boundary_triangles(*views[c][level].mesh, scratch.cameras[c].frbr.frontier, scratch.cameras[c].boundary_rows);
      }, options.num_threads);
    }
    const float distance = d_r * static_cast<float>(std::pow(options.coarse_shrink, level));
    for (size_t r = 0; r < rounds.count(); ++r) {
      const std::span<const int> round = rounds.round(r);
      parallel_for(0, static_cast<int>(round.size()), [&](int i) {
        const int pair_index = round[i];
        const auto [a, b] = pairs[pair_index];
        const auto& masks = scratch.masks[pair_index];
        const FrbrResult removed = remove_redundant_boundaries(views[a][level], views[b][level], distance, level == levels, masks.first,
                                                               masks.second, scratch.cameras[a].frbr, scratch.cameras[b].frbr);
        if (level == 0) removed_at_full[pair_index] = removed.removed_a + removed.removed_b;
      }, options.num_threads);
    }
  }
  for (int n : propagated_to_full) result.stats.redundant_removed += n;
  for (int n : removed_at_full) result.stats.redundant_removed += n;
  result.stats.redundancy_ms = ms_since(t);

  // Clipping: seams per pair.
  t = Clock::now();
  parallel_for(0, static_cast<int>(active.size()), [&](int i) {
    const int c = active[i];
    collect_boundary_triangles(*cameras[c].mesh, scratch.cameras[c].seam.boundary, scratch.cameras[c].boundary_rows);
  }, options.num_threads);
  const SeamOptions seam_options{.clipping_distance = static_cast<float>(options.clipping_distance_m),
                                 .max_edge = static_cast<float>(options.max_seam_edge_m),
                                 .ownership_distance = d_r,
                                 .smoothing_radius = options.seam_smoothing_px < 0 ? 2 : options.seam_smoothing_px,
                                 .fairing_iterations = options.seam_fairing_iterations,
                                 .crease_watch = options.seam_crease_watch};
  // Two phases. The seams take their triangles out of the meshes in rounds (the pairs of a round
  // share no camera, so each mesh is edited in a fixed order); each taken triangle is marked
  // with its round. Then every seam is triangulated at once, the pairs spread over the threads by
  // their number of points: rounds of unequal pairs (or a round of one, with five pairs) left a
  // thread idle, and the Delaunay phase is about 70 % of clipping. A seam triangulated after
  // later rounds took more counts those later-taken triangles as kept, as they were for it.
  // Per pair; the scratch's lists only grow, so that a camera's pairs that come back after a
  // frame set without it find their arrays.
  if (scratch.taken.size() < pairs.size()) scratch.taken.resize(pairs.size());
  if (scratch.stitch.size() < pairs.size()) scratch.stitch.resize(pairs.size());
  const std::span<TakenSeam> taken(scratch.taken.data(), pairs.size());
  for (TakenSeam& seam : taken) seam.clear();  // the marks' clearing below reads them, even if taking fails half way
  // The seams mark the scratch's cameras (the round that took each triangle, the seam of each
  // pixel); the next call reads those marks as its own seams', so they are cleared after the
  // stitching, and also when an exception leaves it half done.
  auto clear_seam_marks = [&] {
    for (size_t i = 0; i < taken.size(); ++i) {
      const auto [a, b] = pairs[i];
      for (int id : taken[i].taken_a) scratch.cameras[a].taken_round[id] = 0;
      for (int id : taken[i].taken_b) scratch.cameras[b].taken_round[id] = 0;
      for (const PixelVertex& v : taken[i].seam.vertices) {
        std::vector<std::uint16_t>& seam_at_pixel = scratch.cameras[v.camera].seam_at_pixel;
        if (static_cast<size_t>(v.pixel) < seam_at_pixel.size()) seam_at_pixel[v.pixel] = SeamPixelMap::kNoSeam;
      }
    }
  };
  OnScopeExit clear_seam_marks_on_error(clear_seam_marks);
  for (int c : active) scratch.cameras[c].taken_round.resize(cameras[c].mesh->triangles.size() * 2, 0);
  for (size_t r = 0; r < rounds.count(); ++r) {
    const std::span<const int> round = rounds.round(r);
    parallel_for(0, static_cast<int>(round.size()), [&](int i) {
      const int pair_index = round[i];
      const auto [a, b] = pairs[pair_index];
      take_seam(views[a][0], views[b][0], seam_options, scratch.masks[pair_index].first, scratch.masks[pair_index].second,
                scratch.cameras[a].seam, scratch.cameras[b].seam, taken[pair_index]);
      for (int id : taken[pair_index].taken_a) scratch.cameras[a].taken_round[id] = static_cast<std::uint8_t>(r + 1);
      for (int id : taken[pair_index].taken_b) scratch.cameras[b].taken_round[id] = static_cast<std::uint8_t>(r + 1);
    }, options.num_threads);
  }
  // Which seam each pixel is a vertex of (SeamPixelMap), kept until every seam is stitched. Pixels
  // that are vertices of more than one seam (where three cameras' seams meet) keep their own
  // place: each seam would move them towards its other camera's surface.
  for (int c : active) {
    scratch.cameras[c].seam_at_pixel.resize(cameras[c].mesh->triangles.size(), SeamPixelMap::kNoSeam);
    scratch.cameras[c].seam_vertex_at_pixel.resize(cameras[c].mesh->triangles.size());
  }
  auto seam_at = [&](const PixelVertex& v) -> std::uint16_t& { return scratch.cameras[v.camera].seam_at_pixel[v.pixel]; };
  for (size_t k = 0; k < taken.size(); ++k) {
    const std::vector<PixelVertex>& vertices = taken[k].seam.vertices;
    for (size_t i = 0; i < vertices.size(); ++i) {
      std::uint16_t& seam = seam_at(vertices[i]);
      if (seam != SeamPixelMap::kNoSeam) {
        seam = SeamPixelMap::kManySeams;
        continue;
      }
      seam = static_cast<std::uint16_t>(k + 1);
      scratch.cameras[vertices[i].camera].seam_vertex_at_pixel[vertices[i].pixel] = static_cast<int>(i);
    }
  }
  for (TakenSeam& seam : taken) {
    seam.shared.resize(seam.seam.vertices.size());
    for (size_t k = 0; k < seam.seam.vertices.size(); ++k) seam.shared[k] = seam_at(seam.seam.vertices[k]) == SeamPixelMap::kManySeams;
  }
  const Clock::time_point taken_at = Clock::now();

  // The seams are triangulated while the kept triangles are written (assembly): the output's
  // vertices and kept triangles need only the seams' points, not their triangles. Kept and seam
  // triangles share pixel vertices; each camera's part is written at offsets from a prefix sum
  // of the cameras' counts, taken first.
  TriangleMesh& mesh = result.mesh;
  std::vector<int>&vertex_count = scratch.vertex_count, &triangle_count = scratch.triangle_count;
  vertex_count.assign(camera_count, 0);
  triangle_count.assign(camera_count, 0);
  // Each camera's used pixels (by kept triangles or seams) and triangles, counted.
  parallel_for(0, static_cast<int>(active.size()), [&](int i) {
    const int c = active[i];
    ZipperScratch::Camera& s = scratch.cameras[c];
    const DepthMesh& depth_mesh = *cameras[c].mesh;
    // Only the box is read, and every pixel of it is written below: no clearing.
    s.used.resize(depth_mesh.triangles.size());
    s.vertex_of_pixel.resize(depth_mesh.triangles.size());
    const PixelBox box = depth_mesh.box();
    int triangles = 0;
    for (int v = box.v0; v < box.v1; ++v) {
      const int row = v * depth_mesh.width;
      triangles += count_triangles(depth_mesh.triangles.data() + row + box.u0, box.u1 - box.u0);
      mark_used_pixels_row(depth_mesh.triangles.data(), depth_mesh.width, v, box.u0, box.u1, s.used.data() + row);
    }
    for (const TakenSeam& seam : taken) {
      for (const PixelVertex& v : seam.seam.vertices) {
        if (v.camera == c) s.used[v.pixel] = 1;
      }
    }
    int vertices = 0;
    for (int v = box.v0; v < box.v1; ++v) vertices += count_used_row(s.used.data() + v * depth_mesh.width + box.u0, box.u1 - box.u0);
    vertex_count[c] = vertices;
    triangle_count[c] = triangles;
  }, options.num_threads);
  std::vector<int>&vertex_offset = scratch.vertex_offset, &triangle_offset = scratch.triangle_offset;
  vertex_offset.assign(camera_count + 1, 0);
  triangle_offset.assign(camera_count + 1, 0);
  for (int c = 0; c < camera_count; ++c) {
    vertex_offset[c + 1] = vertex_offset[c] + vertex_count[c];
    triangle_offset[c + 1] = triangle_offset[c] + triangle_count[c];
  }
  // Room for the seam triangles first (reserving after the resize moved every kept triangle): a
  // triangulation of n points has fewer than 2n triangles.
  size_t seam_bound = 0;
  for (const TakenSeam& seam : taken) seam_bound += 2 * seam.seam.vertices.size();
  mesh.positions.clear();
  mesh.colors.clear();
  mesh.triangles.clear();
  mesh.triangles.reserve(triangle_offset[camera_count] + seam_bound);
  mesh.triangles.resize(triangle_offset[camera_count]);
  mesh.positions.resize(vertex_offset[camera_count]);
  mesh.colors.resize(vertex_offset[camera_count]);
  auto write_camera = [&](int c) {
    ZipperScratch::Camera& s = scratch.cameras[c];
    const DepthMesh& depth_mesh = *cameras[c].mesh;
    const int first = vertex_offset[c];
    const PixelBox box = depth_mesh.box();
    // Used pixels numbered in pixel order, written as they are numbered; each row of cells'
    // triangles written (in cell order) as soon as the two rows of pixels it joins are numbered,
    // so that their numbers are read back from the cache (numbering the whole box first, then
    // writing the triangles, read them back from memory: assembly took 2.6–2.7 ms on one thread
    // for samba-4cam, against 2.3–2.4 ms so).
    const int width = depth_mesh.width;
    int vertex = 0;
    auto number_row = [&](int v) {
      const int row = v * width;
      for_each_nonzero_byte(s.used.data() + row + box.u0, box.u1 - box.u0, [&](int k, std::uint8_t) {
        const int u = box.u0 + k;
        s.vertex_of_pixel[row + u] = vertex;
        mesh.positions[first + vertex] = depth_mesh.point(u, v);
        ++vertex;
      });
    };
    Eigen::Vector3i* out = mesh.triangles.data() + triangle_offset[c];
    if (box.v1 > box.v0) number_row(box.v0);
    for (int v = box.v0; v < box.v1; ++v) {
      if (v + 1 < box.v1) number_row(v + 1);
      // Triangles lie in the cells of the box but its last row and column.
      for_each_triangle_in_cells(depth_mesh, v * width + box.u0, std::min(box.u1, width - 1) - box.u0, [&](const int* p) {
        *out++ = Eigen::Vector3i(first + s.vertex_of_pixel[p[0]], first + s.vertex_of_pixel[p[1]], first + s.vertex_of_pixel[p[2]]);
      });
    }
  };
  std::vector<Clock::time_point>& stitched_at = scratch.stitched_at;
  stitched_at.assign(taken.size(), taken_at);
  auto stitch = [&](int i) {
    const auto [a, b] = pairs[i];
    auto pixel_map = [&](int c) { return SeamPixelMap{scratch.cameras[c].seam_at_pixel.data(), scratch.cameras[c].seam_vertex_at_pixel.data()}; };
    stitch_seam(views[a][0], cameras[a].model->world_from_depth.translation().cast<float>(), views[b][0],
                cameras[b].model->world_from_depth.translation().cast<float>(), seam_options,
                KeptAt{scratch.cameras[a].taken_round.data(), rounds.round_of_pair[i] + 1},
                KeptAt{scratch.cameras[b].taken_round.data(), rounds.round_of_pair[i] + 1},
                SeamPixels{pixel_map(a), pixel_map(b), static_cast<std::uint16_t>(i + 1)}, taken[i], scratch.stitch[i]);
    stitched_at[i] = Clock::now();
  };
  // One list the threads take tasks from in turn: the seams, longest first, then each camera's
  // writing. The seams are a few long tasks of unequal length (on samba-4cam a thread was left
  // without one for 6–7 % of the stitching), and the writing fills those gaps.
  std::vector<int>& by_size = scratch.by_size;
  by_size.resize(taken.size());
  for (size_t i = 0; i < taken.size(); ++i) by_size[i] = static_cast<int>(i);
  // Equal sizes in pair order (std::stable_sort would take a buffer from the heap).
  std::sort(by_size.begin(), by_size.end(), [&](int i, int j) {
    const size_t size_i = taken[i].seam.vertices.size(), size_j = taken[j].seam.vertices.size();
    return size_i != size_j ? size_i > size_j : i < j;
  });
  const int seam_count = static_cast<int>(taken.size());
  run_tasks_in_turn(seam_count + static_cast<int>(active.size()), options.num_threads, [&](int k) {
    if (k < seam_count) {
      stitch(by_size[k]);
    } else {
      write_camera(active[k - seam_count]);
    }
  });
  clear_seam_marks();
  clear_seam_marks_on_error.dismiss();
  for (const TakenSeam& seam : taken) {
    result.stats.seam_taken += seam.seam.triangles_taken;
    result.stats.seam_pca += seam.seam.used_pca;
    result.stats.seam_crease_gaps += seam.seam.creased_faces_dropped;
  }
  // Clipping ends with the last seam; the writing still running then, and what follows, is
  // assembly's (and the counting before, a few percent of it, clipping's).
  Clock::time_point clipped_at = taken_at;
  for (const Clock::time_point at : stitched_at) clipped_at = std::max(clipped_at, at);
  result.stats.clipping_ms = std::chrono::duration<double, std::milli>(clipped_at - t).count();
  t = clipped_at;

  // A seam triangle may not reuse a directed edge that a kept (or earlier seam) triangle already
  // has: that would put it on the same side of the edge as that triangle, overlapping it, and
  // make the edge non-manifold. Only edges between seam vertices need checking.
  // The seam triangles go in on one thread while the others, and then it too, look up the
  // cameras' colours: the seams' part is serial (each triangle's edges are tested against the
  // triangles before it), and the colours need only the used pixels. A camera's colours are
  // those of its used pixels in the order their positions were written.
  Clock::time_point assembled;
  auto add_seam_triangles = [&] {
    auto vertex = [&](const PixelVertex& v) { return vertex_offset[v.camera] + scratch.cameras[v.camera].vertex_of_pixel[v.pixel]; };
    // Directed edges between seam vertices, by slot (a seam vertex's index among them): per slot,
    // the slots its outgoing edges end at, each with its triangle's third corner (a vertex has a
    // handful). Other vertices are -1 in
    // seam_slot. Each seam's vertices are looked up once, here, as slots: the edge tests below
    // then touch only the seam vertices' own small arrays.
    std::vector<int>& seam_slot = scratch.seam_slot;
    std::vector<std::vector<ZipperScratch::DirectedEdge>>& outgoing = scratch.outgoing;
    std::vector<PixelVertex>& seam_vertices = scratch.seam_vertices;
    std::vector<int>& slot_vertex = scratch.slot_vertex;
    std::vector<int>& local_slot = scratch.local_slot;
    seam_slot.assign(mesh.positions.size(), -1);
    seam_vertices.clear();
    slot_vertex.clear();
    local_slot.clear();
    for (const TakenSeam& taken_seam : taken) {
      const Seam& seam = taken_seam.seam;
      // The seam's vertices where it put them (a pixel in two seams gets the same position from both).
      for (size_t k = 0; k < seam.positions.size(); ++k) mesh.positions[vertex(seam.vertices[k])] = seam.positions[k];
      for (const PixelVertex& v : seam.vertices) {
        const int id = vertex(v);
        int& slot = seam_slot[id];
        if (slot < 0) {
          slot = static_cast<int>(seam_vertices.size());
          seam_vertices.push_back(v);
          slot_vertex.push_back(id);
        }
        local_slot.push_back(slot);
      }
    }
    if (outgoing.size() < seam_vertices.size()) outgoing.resize(seam_vertices.size());
    // The kept triangles' edges from each seam vertex: those of the (up to six) triangles around
    // its pixel. Each slot's list is its own, so the slots are split over the threads.
    const int slots = static_cast<int>(seam_vertices.size());
    const int slot_blocks = std::min(slots, 64);
    parallel_for(0, slot_blocks, [&](int block) {
      for (int i = static_cast<int>(static_cast<long>(slots) * block / slot_blocks); i < static_cast<long>(slots) * (block + 1) / slot_blocks; ++i) {
        outgoing[i].clear();
        const PixelVertex& sv = seam_vertices[i];
        const DepthMesh& depth_mesh = *cameras[sv.camera].mesh;
        for_each_grid_triangle_at_pixel(sv.pixel, depth_mesh.width, depth_mesh.height, [&](int cell, TriangleBit bit, const int* pixels, int k) {
          if (!(depth_mesh.triangles[cell] & bit)) return;
          const int to = seam_slot[vertex({sv.camera, pixels[(k + 1) % 3]})];
          if (to >= 0) outgoing[i].push_back({to, seam_slot[vertex({sv.camera, pixels[(k + 2) % 3]})]});
        });
      }
    }, options.num_threads);
    auto has_edge = [&](int from, int to) {
      const std::vector<ZipperScratch::DirectedEdge>& edges = outgoing[from];
      return std::any_of(edges.begin(), edges.end(), [to](const ZipperScratch::DirectedEdge& e) { return e.to == to; });
    };
    // Two seams that share three vertices (where three cameras' seams meet) can lay a triangle on
    // them each, turned over against each other: every edge then has a face on either side, so
    // the edge test lets the second through. It is the first one's mirror (a, c, b).
    auto has_face = [&](int a, int b, int c) {
      const std::vector<ZipperScratch::DirectedEdge>& edges = outgoing[a];
      return std::any_of(edges.begin(), edges.end(), [b, c](const ZipperScratch::DirectedEdge& e) { return e.to == b && e.third == c; });
    };
    const int* seam_local_slot = local_slot.data();
    for (const TakenSeam& taken_seam : taken) {
      const Seam& seam = taken_seam.seam;
      for (const Eigen::Vector3i& local : seam.triangles) {
        const int a = seam_local_slot[local[0]], b = seam_local_slot[local[1]], c = seam_local_slot[local[2]];
        if (has_edge(a, b) || has_edge(b, c) || has_edge(c, a) || has_face(a, c, b)) {
          ++result.stats.seam_rejected;
          continue;
        }
        mesh.triangles.emplace_back(slot_vertex[a], slot_vertex[b], slot_vertex[c]);
        outgoing[a].push_back({b, c});
        outgoing[b].push_back({c, a});
        outgoing[c].push_back({a, b});
        ++result.stats.seam_added;
      }
      seam_local_slot += seam.vertices.size();
    }
    assembled = Clock::now();
  };
  // Colours are sampled at the measured depth: a seam vertex moved along its ray to its surface's
  // mean depth (millimetres) projects into the colour camera a small fraction of a pixel away; one
  // the crease relaxation took off its ray is at most kMostPixelShift (1.5) depth pixels away.
  auto color_camera = [&](int i) {
    const int c = active[i];
    const ZipperScratch::Camera& s = scratch.cameras[c];
    const DepthMesh& depth_mesh = *cameras[c].mesh;
    const ColorLookup lookup(*cameras[c].model, cameras[c].color);
    Rgb8* out = mesh.colors.data() + vertex_offset[c];
    if (!lookup.has_image()) {
      std::fill_n(out, vertex_count[c], kNoColor);
      return;
    }
    const PixelBox box = depth_mesh.box();
    for (int v = box.v0; v < box.v1; ++v) {
      const std::uint8_t* used = s.used.data() + v * depth_mesh.width;
      // Only the row's used pixels are projected: those of the subject, a fraction of the box.
      const auto [first, end] = nonzero_span(used + box.u0, box.u1 - box.u0);
      lookup.for_each_color_in_row(v, box.u0 + first, box.u0 + end, depth_mesh.depth.data() + v * depth_mesh.width,
                                   [&](int u) { return used[u] != 0; }, [&](int, Rgb8 color) { *out++ = color; });
    }
  };
  // Taken in turn: as parallel_for's contiguous blocks, the seam triangles' thread also had a
  // camera's colours (two threads: items 0–1 against 2–4), and it finished last while the other
  // waited.
  run_tasks_in_turn(static_cast<int>(active.size()) + 1, options.num_threads, [&](int item) {
    if (item == 0) {
      add_seam_triangles();
    } else {
      color_camera(item - 1);
    }
  });
  // Assembly until its seam triangles are in; colour for what of it came after.
  result.stats.assemble_ms = std::chrono::duration<double, std::milli>(assembled - t).count();
  result.stats.color_ms = ms_since(assembled);
  return result;
}

}  // namespace zipfusion
