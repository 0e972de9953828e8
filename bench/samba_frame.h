#pragma once
// One frame set of samba-4cam (or of another capture given) with the true poses, prepared as the
// reconstruction prepares it: foreground depth, bilateral-filtered depth, the SDC meshes of both
// and per-pixel colours. Shared by the kernel benchmarks and zf_zipper_repeat; samba-4cam is
// found through ZF_SOURCE_DIR.

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "zipfusion/depth/bilateral.h"
#include "zipfusion/depth/color_lookup.h"
#include "zipfusion/depth/foreground.h"
#include "zipfusion/depth/sdc_mesh.h"
#include "zipfusion/io/capture.h"

namespace zipfusion {

struct SambaFrame {
  Rig rig;
  FrameSet frames;
  std::vector<Image<float>> foreground, filtered;
  std::vector<DepthMesh> meshes, filtered_meshes;
  std::vector<std::vector<Rgb8>> colors;
  std::vector<SdcOptions> sdc;  // each camera's SDC threshold, as FrameReconstructor gives it (sdc_depth_jump)
};

inline std::filesystem::path samba_capture_path() { return std::filesystem::path(ZF_SOURCE_DIR) / ".." / "shared" / "data" / "samba-4cam"; }

//! `capture_path`: another capture to prepare the same way (a synthetic ring, for the scaling with cameras).
inline SambaFrame load_samba_frame(int frame, const std::filesystem::path& capture_path = samba_capture_path()) {
  const Capture capture = Capture::open(capture_path);
  if (frame < 0 || frame >= capture.frame_count()) {
    throw std::out_of_range(capture_path.string() + ": frame " + std::to_string(frame) + ": the capture has frames 0 to " +
                            std::to_string(capture.frame_count() - 1));
  }
  SambaFrame out;
  out.rig = capture.ground_truth_rig().value_or(capture.rig());
  out.rig.volume = capture.rig().volume;
  out.frames = capture.load_frame(frame);
  const int n = capture.camera_count();
  out.foreground.resize(n);
  out.filtered.resize(n);
  out.meshes.resize(n);
  out.filtered_meshes.resize(n);
  out.colors.resize(n);
  const BilateralKernel kernel(BilateralOptions{});
  for (int c = 0; c < n; ++c) {
    const CameraModel& camera = out.rig.cameras[c];
    const SdcOptions& sdc = out.sdc.emplace_back(SdcOptions{.max_depth_jump_m = sdc_depth_jump(SdcOptions{}.max_depth_jump_m, camera.depth_intrinsics)});
    extract_foreground(out.frames.cameras[c].depth, out.rig.depth_unit_m, camera, out.rig.volume, {}, out.foreground[c]);
    bilateral_filter(out.foreground[c], kernel, out.filtered[c]);
    triangulate_sdc(out.foreground[c], camera.depth_intrinsics, camera.world_from_depth.cast<float>(), sdc, out.meshes[c]);
    triangulate_sdc(out.filtered[c], camera.depth_intrinsics, camera.world_from_depth.cast<float>(), sdc, out.filtered_meshes[c]);
    lookup_colors(out.meshes[c], camera, &out.frames.cameras[c].color, out.colors[c]);
  }
  return out;
}

}  // namespace zipfusion
