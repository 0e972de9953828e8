#pragma once
// --rig FILE for the CLI: the calibration of the same cameras from another rig.json (what
// calibrate and register write): poses, intrinsics, color_from_depth, the capture volume.
// use_calibration_from puts it into an open capture.

#include <filesystem>
#include <string>

#include "zipfusion/core/error.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/rig.h"

namespace zipfusion::cli {

//! `rig` (a capture's) with the calibration of the rig.json at `path`: every camera's pose,
//! intrinsics and color_from_depth, the volume when that file has one, and poses_trusted. What
//! belongs to the recording stays the capture's (frame rate and count, depth unit, image sizes).
//! Throws InvalidInput naming that file and the field when its cameras differ: other names or
//! image sizes, or colour where the capture has none (or none where it has). A capture reads its
//! frames through the result with Capture::use_calibration (its depth distortion included).
inline Rig rig_with_calibration_from(const Rig& rig, const std::filesystem::path& path) {
  const Rig other = read_rig(path);
  const std::string source = path.string();
  if (other.cameras.size() != rig.cameras.size()) {
    throw InvalidInput(source + ": cameras: has " + std::to_string(other.cameras.size()) + " cameras, the capture has " +
                       std::to_string(rig.cameras.size()));
  }
  Rig result = rig;
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    const CameraModel &ours = rig.cameras[c], &theirs = other.cameras[c];
    const std::string field = source + ": cameras[" + std::to_string(c) + "].";
    if (theirs.name != ours.name) throw InvalidInput(field + "name: \"" + theirs.name + "\" is not the capture's \"" + ours.name + "\"");
    auto same_size = [&](const Intrinsics& a, const Intrinsics& b, const std::string& key) {
      if (a.width != b.width || a.height != b.height) {
        throw InvalidInput(field + key + ": " + std::to_string(a.width) + "x" + std::to_string(a.height) + ", but the capture's images are " +
                           std::to_string(b.width) + "x" + std::to_string(b.height));
      }
    };
    same_size(theirs.depth_intrinsics, ours.depth_intrinsics, "depth_intrinsics");
    if (theirs.has_color() != ours.has_color()) {
      throw InvalidInput(field + "color_intrinsics: " + (ours.has_color() ? "missing, but the capture's camera has colour" : "given, but the capture's camera has no colour"));
    }
    if (ours.has_color()) same_size(*theirs.color_intrinsics, *ours.color_intrinsics, "color_intrinsics");
    CameraModel& model = result.cameras[c];
    model.depth_intrinsics = theirs.depth_intrinsics;
    model.color_intrinsics = theirs.color_intrinsics;
    model.color_from_depth = theirs.color_from_depth;
    model.world_from_depth = theirs.world_from_depth;
  }
  if (other.volume) result.volume = other.volume;
  result.poses_trusted = other.poses_trusted;
  return result;
}

//! The capture reads its frames through the calibration at `path` (rig_with_calibration_from):
//! its depth distortion undistorts the depth. Returns the capture's rig then.
inline const Rig& use_calibration_from(Capture& capture, const std::filesystem::path& path) {
  capture.use_calibration(rig_with_calibration_from(capture.rig(), path));
  return capture.rig();
}

}  // namespace zipfusion::cli
