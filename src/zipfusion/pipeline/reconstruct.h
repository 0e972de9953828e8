#pragma once
//! \file
//! One frame set in, one mesh out: foreground, bilateral filter and SDC triangulation per camera
//! (paper Section III-B), then zippering (which colours the vertices it keeps) or, for separate
//! meshes, colour per camera and assembly. `FrameReconstructor` keeps every per-camera
//! buffer between frames, and the output meshes handed back to it (recycle()), so steady-state
//! frames allocate no output mesh either.
//!
//! Thread safety: reconstruct() and set_poses() from one thread at a time (reconstruct() is not
//! reentrant); recycle() from any thread. Neither copyable nor movable (it holds a mutex).

#include <cassert>
#include <mutex>
#include <string>
#include <vector>

#include "zipfusion/core/mesh.h"
#include "zipfusion/depth/bilateral.h"
#include "zipfusion/depth/foreground.h"
#include "zipfusion/depth/sdc_mesh.h"
#include "zipfusion/fusion/zipper.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

enum class ReconstructMode {
  kZipper,    // one connected mesh: redundancy removal and clipping (paper Sections III-C, III-D)
  kSeparate,  // one mesh per camera, concatenated (the paper's baseline)
};

struct ReconstructOptions {
  ReconstructMode mode = ReconstructMode::kZipper;
  bool bilateral = true;  // filter depth before triangulation (paper Section III-B)
  ForegroundOptions foreground;
  BilateralOptions filter;
  // The SDC threshold for a camera of focal length kSdcReferenceFocalPx (a Kinect at 640×480);
  // each camera's is sdc_depth_jump of it (and its focal length at the level of detail).
  SdcOptions sdc;
  ZipperOptions zipper;  // each camera's SDC threshold is given with it (ZipperCamera)
  // Level of detail: reconstruct from every 2^depth_level-th depth pixel, each the mean of the
  // pixels around it on its surface (subsample_depth; 0 = full resolution; 1 gives a quarter of
  // the triangles). Thresholds in pixels shrink and the SDC depth jump grows with the pixel
  // spacing (sdc_depth_jump); colour is still sampled from the full colour image.
  int depth_level = 0;
  // Connected pieces of fewer triangles are dropped from the mesh (specks of noise at
  // silhouettes, bits of floor a high camera's noise lifts into the volume); 0 keeps every piece.
  int min_component_triangles = 0;
  int num_threads = 0;  // 0 = all hardware threads

  void validate() const;  // throws InvalidInput naming the field

  //! zipper.ownership with kAuto resolved: unfiltered, noise decides which of two layers is the
  //! better measurement (smoothness); filtered, the layers are about as smooth and the one seen
  //! more frontally (finer, better colour) wins (border).
  Ownership ownership() const {
    if (zipper.ownership != Ownership::kAuto) return zipper.ownership;
    return bilateral ? Ownership::kBorder : Ownership::kSmoothness;
  }
  //! zipper.seam_smoothing_px with −1 (auto) resolved: unfiltered, the seam's points need the
  //! mean of their surface over 5×5 pixels to lie as regularly as the pixel grid (noise shifts
  //! them sideways in the seam's view by more than the pixel spacing); filtered depth is regular
  //! already, and a 3×3 mean (with the 5×5 plane that comes with any smoothing) takes out what
  //! is left of the noise: samba-4cam frames 0–39, true poses, folded edges 2.95 → 2.23 a frame
  //! set, accuracy 1.098 → 1.102 mm (5×5: 2.10 folds, 1.110 mm; docs/design.md); 1.23 → 1.10
  //! since the points at the creases left are dropped (clipping.cc, drop_crease_points).
  int seam_smoothing_px() const {
    if (zipper.seam_smoothing_px >= 0) return zipper.seam_smoothing_px;
    return bilateral ? 1 : 2;
  }
};

//! Wall-clock milliseconds per stage of one frame set (stages run over all cameras in parallel).
struct StageTimes {
  double foreground_ms = 0;
  double filter_ms = 0;
  double triangulate_ms = 0;
  double color_ms = 0;       // zipper: of the vertices only, what of it came after assembly (ZipperStats::color_ms)
  double overlap_ms = 0;     // zipper: coarse levels and overlapping pairs
  double redundancy_ms = 0;  // zipper: coarse-to-fine redundant boundary removal
  double clipping_ms = 0;    // zipper: seams re-triangulated
  double assemble_ms = 0;
  double total_ms = 0;
};

struct FrameResult {
  TriangleMesh mesh;      // world coordinates, per-vertex colour
  StageTimes times;
  int cameras_used = 0;   // cameras that had depth in this frame set
  ZipperStats zipper;     // zipper mode only
  int small_component_triangles = 0;  // triangles dropped in pieces under min_component_triangles
};

class FrameReconstructor {
 public:
  //! Throws InvalidInput when the options are invalid.
  FrameReconstructor(const Rig& rig, const ReconstructOptions& options);

  //! Reconstructs one frame set; a camera without depth in it is left out. The mesh is built in
  //! the buffers of a recycled one where there is one.
  FrameResult reconstruct(const FrameSet& frames);

  //! Hands back a mesh that reconstruct() returned, once its user is done with it: a later frame
  //! set's mesh is built in its buffers. A frame set's mesh is 4–7 MB at full resolution, and
  //! fresh memory costs a page fault every 4 kB as it is first written, so in steady state (the
  //! pipeline recycles every mesh after its sink) no output mesh is allocated. Thread-safe, unlike
  //! reconstruct().
  void recycle(TriangleMesh&& mesh);

  //! Replaces the camera poses (refined by registration) from the next frame on. Precondition: one
  //! pose per camera; not during reconstruct().
  void set_poses(const std::vector<Rigid3d>& world_from_depth);

  //! The options as applied: at a level of detail (depth_level > 0) the lengths in pixels and the
  //! coarse levels shrink with it (at_depth_level in reconstruct.cc).
  const ReconstructOptions& applied_options() const { return options_; }

  //! The SDC threshold camera `c` is triangulated with: ReconstructOptions::sdc scaled by its focal
  //! length at the level of detail (sdc_depth_jump).
  double max_depth_jump_m(int c) const {
    assert(c >= 0 && c < static_cast<int>(cameras_.size()));
    return cameras_[c].sdc.max_depth_jump_m;
  }

 private:
  struct CameraState {
    SdcOptions sdc;                       // this camera's threshold (sdc_depth_jump)
    float subsample_same_surface_m = 0;   // depth_level > 0: subsample_depth's same_surface
    Image<float> full_foreground;  // depth_level > 0: the foreground at full resolution, before subsample_depth
    Image<float> foreground;
    Image<float> filtered;
    BilateralScratch filter_scratch;
    DepthMesh mesh;
    std::vector<Rgb8> colors;  // per pixel, for separate meshes (the zipper colours its own vertices)
  };

  Rig rig_;
  std::vector<CameraModel> full_resolution_cameras_;  // depth_level > 0: rig_'s cameras with the depth images' own intrinsics
  ReconstructOptions options_;
  BilateralKernel kernel_;
  std::vector<CameraState> cameras_;
  std::vector<int> vertex_of_pixel_;
  std::vector<char> active_;                 // per camera: has depth in this frame set
  std::vector<ZipperCamera> zipper_inputs_;
  ZipperScratch zipper_scratch_;
  MeshComponents components_;  // remove_small_components' scratch
  std::mutex spare_mutex_;
  std::vector<TriangleMesh> spare_meshes_;  // recycled, at most kSpareMeshes, the longest kept first
  struct {
    size_t positions = 0, colors = 0, triangles = 0;
  } most_mesh_capacity_;  // the largest capacities a mesh has had (reconstruct() only)
};

}  // namespace zipfusion
