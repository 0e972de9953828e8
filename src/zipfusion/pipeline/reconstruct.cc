#include "zipfusion/pipeline/reconstruct.h"

#include <algorithm>
#include <chrono>

#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/depth/color_lookup.h"

namespace zipfusion {
namespace {

using Clock = std::chrono::steady_clock;

// Meshes kept for reuse: as many as exist at once with the pipeline's default queue
// (PipelineOptions::queue_depth 2, the one in the sink, the one being built), so that none is
// freed when all come back at once (the reconstruction waiting for decoding) and made anew when the
// queue fills again; a deeper queue allocates the difference.
constexpr size_t kSpareMeshes = 4;

double elapsed_ms(Clock::time_point since) { return std::chrono::duration<double, std::milli>(Clock::now() - since).count(); }

const ReconstructOptions& validated(const ReconstructOptions& options) {
  options.validate();
  return options;
}

// The options for depth subsampled by 2^level: lengths in pixels shrink, and the zipper's pyramid
// starts at the same coarsest resolution as before. (The SDC threshold grows with the pixels'
// spacing through each camera's subsampled focal length: sdc_depth_jump.)
ReconstructOptions at_depth_level(ReconstructOptions options) {
  const int level = options.depth_level;
  if (level == 0) return options;
  const double scale = 1 << level;
  options.filter.spatial_sigma_px = std::max(0.5, options.filter.spatial_sigma_px / scale);
  options.filter.radius_px = std::max(1, static_cast<int>(options.filter.radius_px / scale));
  options.zipper.hole_closing_px >>= level;
  options.zipper.seam_smoothing_px = options.seam_smoothing_px() >> level;
  options.zipper.smoothness_window_px = std::max(1, options.zipper.smoothness_window_px >> level);
  options.zipper.coarse_levels = std::max(0, options.zipper.coarse_levels - level);
  options.zipper.depth_level = level;
  return options;
}

Rig at_depth_level(Rig rig, int level) {
  for (CameraModel& camera : rig.cameras) camera.depth_intrinsics = subsampled_intrinsics(camera.depth_intrinsics, level);
  return rig;
}

}  // namespace

void ReconstructOptions::validate() const {
  if (depth_level < 0 || depth_level > 3) throw InvalidInput("--lod: must be in [0, 3]");
  if (min_component_triangles < 0 || min_component_triangles > 1000000) throw InvalidInput("--min-component: must be in [0, 1000000] triangles");
  foreground.validate();
  filter.validate();
  sdc.validate();
  zipper.validate();
}

FrameReconstructor::FrameReconstructor(const Rig& rig, const ReconstructOptions& options)
    : rig_(at_depth_level(rig, validated(options).depth_level)),
      options_(at_depth_level(options)),
      kernel_(options_.filter),
      cameras_(rig.cameras.size()) {
  if (options_.depth_level > 0) full_resolution_cameras_ = rig.cameras;
  spare_meshes_.reserve(kSpareMeshes);
  for (size_t c = 0; c < cameras_.size(); ++c) {
    cameras_[c].sdc = options_.sdc;
    cameras_[c].sdc.max_depth_jump_m = sdc_depth_jump(options_.sdc.max_depth_jump_m, rig_.cameras[c].depth_intrinsics);
    // Same surface for subsample_depth: the SDC threshold of the full-resolution pixels.
    cameras_[c].subsample_same_surface_m = static_cast<float>(sdc_depth_jump(options_.sdc.max_depth_jump_m, rig.cameras[c].depth_intrinsics));
  }
}

void FrameReconstructor::set_poses(const std::vector<Rigid3d>& world_from_depth) {
  assert(world_from_depth.size() == rig_.cameras.size());
  for (size_t c = 0; c < rig_.cameras.size(); ++c) rig_.cameras[c].world_from_depth = world_from_depth[c];
  for (size_t c = 0; c < full_resolution_cameras_.size(); ++c) full_resolution_cameras_[c].world_from_depth = world_from_depth[c];
}

void FrameReconstructor::recycle(TriangleMesh&& mesh) {
  if (mesh.triangles.capacity() == 0) return;  // nothing worth keeping (moved from)
  std::lock_guard lock(spare_mutex_);
  if (spare_meshes_.size() < kSpareMeshes) spare_meshes_.push_back(std::move(mesh));
}

FrameResult FrameReconstructor::reconstruct(const FrameSet& frames) {
  const Clock::time_point start = Clock::now();
  FrameResult result;
  {
    // The longest-kept spare first, so that every mesh goes round and none lies unused until a
    // change of pace in the pipeline takes it (and grows it then).
    std::lock_guard lock(spare_mutex_);
    if (!spare_meshes_.empty()) {
      result.mesh = std::move(spare_meshes_.front());
      spare_meshes_.erase(spare_meshes_.begin());
    }
  }
  result.mesh.positions.clear();
  result.mesh.colors.clear();
  result.mesh.triangles.clear();
  // Grown at once to the largest mesh built so far: which mesh a frame set gets must not decide
  // whether it allocates (a mesh that last held a small frame set, taking a large one).
  result.mesh.positions.reserve(most_mesh_capacity_.positions);
  result.mesh.colors.reserve(most_mesh_capacity_.colors);
  result.mesh.triangles.reserve(most_mesh_capacity_.triangles);
  const int camera_count = static_cast<int>(rig_.cameras.size());
  std::vector<char>& active = active_;
  active.assign(camera_count, 0);
  for (int c = 0; c < camera_count; ++c) active[c] = c < static_cast<int>(frames.cameras.size()) && frames.cameras[c].has_depth;
  const int threads = options_.num_threads;

  auto stage = [&](double& ms, auto&& per_camera) {
    const Clock::time_point t = Clock::now();
    parallel_for(0, camera_count, [&](int c) {
      if (active[c]) per_camera(c, cameras_[c]);
    }, threads);
    ms = elapsed_ms(t);
  };

  stage(result.times.foreground_ms, [&](int c, CameraState& s) {
    const DepthImage& raw = frames.cameras[c].depth;
    if (options_.depth_level == 0) {
      extract_foreground(raw, rig_.depth_unit_m, rig_.cameras[c], rig_.volume, options_.foreground, s.foreground);
      return;
    }
    const Intrinsics& k = full_resolution_cameras_[c].depth_intrinsics;
    if (raw.width != k.width || raw.height != k.height) {
      throw InvalidInput(rig_.cameras[c].name + ": depth image " + std::to_string(raw.width) + "x" + std::to_string(raw.height) +
                         " does not match the rig's depth_intrinsics (" + std::to_string(k.width) + "x" + std::to_string(k.height) + ")");
    }
    extract_foreground(raw, rig_.depth_unit_m, full_resolution_cameras_[c], rig_.volume, options_.foreground, s.full_foreground);
    subsample_depth(s.full_foreground, options_.depth_level, s.subsample_same_surface_m, s.foreground);
  });
  if (options_.bilateral) {
    stage(result.times.filter_ms, [&](int, CameraState& s) { bilateral_filter(s.foreground, kernel_, s.filtered, s.filter_scratch, 1); });
  }
  stage(result.times.triangulate_ms, [&](int c, CameraState& s) {
    // The depth image is not needed after this: the mesh takes its buffer (extract_foreground and
    // the filter write every pixel of theirs next frame).
    Image<float>& depth = options_.bilateral ? s.filtered : s.foreground;
    triangulate_sdc_taking_depth(depth, rig_.cameras[c].depth_intrinsics, rig_.cameras[c].world_from_depth.cast<float>(), s.sdc, s.mesh);
  });
  auto color_of = [&](int c) { return frames.cameras[c].has_color ? &frames.cameras[c].color : nullptr; };
  if (options_.mode == ReconstructMode::kSeparate) {
    stage(result.times.color_ms, [&](int c, CameraState& s) { lookup_colors(s.mesh, rig_.cameras[c], color_of(c), s.colors); });
  }

  for (int c = 0; c < camera_count; ++c) result.cameras_used += active[c];
  if (options_.mode == ReconstructMode::kZipper) {
    // The zipper colours only the vertices it keeps.
    std::vector<ZipperCamera>& inputs = zipper_inputs_;
    inputs.assign(camera_count, ZipperCamera{});
    for (int c = 0; c < camera_count; ++c) {
      if (active[c]) inputs[c] = {&cameras_[c].mesh, color_of(c), &rig_.cameras[c], cameras_[c].sdc.max_depth_jump_m};
    }
    ZipperOptions zipper = options_.zipper;
    zipper.sdc_growth_depth_m = options_.sdc.growth_depth_m;
    zipper.ownership = options_.ownership();
    zipper.seam_smoothing_px = options_.seam_smoothing_px();
    zipper.num_threads = threads;
    ZipperResult zipped = zipper_meshes(inputs, zipper, zipper_scratch_, std::move(result.mesh));
    result.mesh = std::move(zipped.mesh);
    result.zipper = zipped.stats;
    result.times.overlap_ms = zipped.stats.pyramid_ms + zipped.stats.overlap_ms;
    result.times.redundancy_ms = zipped.stats.redundancy_ms;
    result.times.clipping_ms = zipped.stats.clipping_ms;
    result.times.assemble_ms = zipped.stats.assemble_ms;
    result.times.color_ms = zipped.stats.color_ms;
  } else {
    const Clock::time_point assemble_start = Clock::now();
    for (int c = 0; c < camera_count; ++c) {
      if (active[c]) append_depth_mesh(cameras_[c].mesh, cameras_[c].colors, result.mesh, vertex_of_pixel_);
    }
    result.times.assemble_ms = elapsed_ms(assemble_start);
  }
  if (options_.min_component_triangles > 1) {
    const Clock::time_point pieces_start = Clock::now();
    result.small_component_triangles = remove_small_components(result.mesh, options_.min_component_triangles, components_);
    result.times.assemble_ms += elapsed_ms(pieces_start);
  }
  most_mesh_capacity_.positions = std::max(most_mesh_capacity_.positions, result.mesh.positions.capacity());
  most_mesh_capacity_.colors = std::max(most_mesh_capacity_.colors, result.mesh.colors.capacity());
  most_mesh_capacity_.triangles = std::max(most_mesh_capacity_.triangles, result.mesh.triangles.capacity());
  result.times.total_ms = elapsed_ms(start);
  return result;
}

}  // namespace zipfusion
