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
    const std::string &ours = rig.cameras[c].name, &theirs = other.cameras[c].name;
    if (theirs != ours) throw InvalidInput(source + ": cameras[" + std::to_string(c) + "].name: \"" + theirs + "\" is not the capture's \"" + ours + "\"");
    take_camera_calibration(result.cameras[c], other, static_cast<int>(c), source, "the capture's");
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

//! The rig to reconstruct or register a capture with: its own, or (`rig_path`, --rig, not empty)
//! the calibration of that rig.json put into it. Throws InvalidInput naming the file the poses
//! came from when two cameras share one pose (check_poses_distinct: an uncalibrated rig).
inline const Rig& calibrated_rig(Capture& capture, const std::string& rig_path) {
  const Rig& rig = rig_path.empty() ? capture.rig() : use_calibration_from(capture, rig_path);
  check_poses_distinct(rig, rig_path.empty() ? (capture.dir() / "rig.json").string() : rig_path);
  return rig;
}

}  // namespace zipfusion::cli
