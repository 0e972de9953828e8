#pragma once
//! \file
//! rig.json (`zipfusion.rig/1`, see docs/formats.md and ../shared/FORMATS.md): the cameras of a
//! capture, their intrinsics and poses. Reading validates everything and throws InvalidInput
//! ("FILE: FIELD: problem") or IoError; unknown keys are ignored.

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "zipfusion/core/camera.h"
#include "zipfusion/core/geometry.h"

namespace zipfusion {

inline constexpr const char* kRigFormat = "zipfusion.rig/1";
//! Frame files are numbered with six digits (000000.png to 999999.png).
inline constexpr int kMostFrames = 1000000;
//! Camera positions and the capture volume lie within this many metres of the origin on each
//! axis (a rig is a room, not a map; beyond, metres were probably millimetres).
inline constexpr double kMostWorldM = 1000;
//! Where a rig's world has its floor at z = 0 (`calibrate floor`, `synth`), the capture volume's
//! bottom lies this far above it, so that the floor stays background (FORMATS.md's example too).
inline constexpr double kVolumeFloorClearanceM = 0.02;

struct CameraModel {
  std::string name;                           // also the camera's folder in the capture
  Intrinsics depth_intrinsics;
  std::optional<Intrinsics> color_intrinsics;  // absent: the camera has no colour
  Rigid3d color_from_depth = Rigid3d::Identity();  // meaningful only with color_intrinsics
  Rigid3d world_from_depth = Rigid3d::Identity();

  bool has_color() const { return color_intrinsics.has_value(); }
};

struct Rig {
  double fps = 30;                // frames per second
  int frame_count = 0;            // frames per camera, at most kMostFrames
  double depth_unit_m = 0.001;    // metres per depth PNG unit
  std::optional<Box3d> volume;    // capture volume in world coordinates, metres
  // "poses_trusted" (optional, a zipfusion extension ignored by other tools): the poses come from
  // a calibration or a refinement (calibrate, register) or are exact (synth), so reconstruct does
  // not refine them unless asked. Absent: false.
  bool poses_trusted = false;
  std::vector<CameraModel> cameras;

  //! Index of the camera with that name, or -1.
  int camera_index(const std::string& name) const;
};

//! Parses rig.json text; `source` names the file in error messages.
Rig parse_rig(const std::string& json_text, const std::string& source);

//! Reads and validates a rig.json file.
Rig read_rig(const std::filesystem::path& path);

//! rig.json text: one camera per block, matrices one row per line; numbers round-trip exactly.
std::string format_rig(const Rig& rig);

//! Writes rig.json atomically.
void write_rig(const std::filesystem::path& path, const Rig& rig);

inline constexpr const char* kIntrinsicsFormat = "zipfusion.intrinsics/1";

//! One camera's intrinsics from a `zipfusion.intrinsics/1` file (what `calibrate intrinsics`
//! writes): its "intrinsics" object, validated as rig.json's are; the other keys (the per-view
//! report) are ignored. `source` names the file in error messages.
Intrinsics parse_intrinsics_file(const std::string& json_text, const std::string& source);
Intrinsics read_intrinsics_file(const std::filesystem::path& path);

//! Throws InvalidInput unless `path` is free for a file of `format` (kRigFormat,
//! kIntrinsicsFormat): missing, empty, or a JSON file of that format. A calibration's output
//! replaces an earlier one of its kind, never another file named by mistake (a capture's rig.json
//! given to `calibrate intrinsics`, an intrinsics file to `calibrate extrinsics`).
void check_replaces_only_format(const std::filesystem::path& path, const char* format, std::string_view option);

//! Intrinsics as a JSON object, as rig.json writes them; numbers round-trip exactly.
std::string format_intrinsics(const Intrinsics& k);

//! Every camera's world_from_depth, in rig order.
std::vector<Rigid3d> world_from_depth_poses(const Rig& rig);

//! Two cameras that physically stand in one place are not a rig: this close (1 cm, 1°), their
//! poses are a placeholder (record without --rig writes identity) or a copied entry.
inline constexpr double kSamePoseM = 0.01;
inline constexpr double kSamePoseDeg = 1.0;

//! The first two cameras (i < j, in rig order) whose world_from_depth poses lie within kSamePoseM
//! and kSamePoseDeg of each other, or nullopt: poses no reconstruction can use, as each camera's
//! mesh would be laid over the others' from the wrong place.
std::optional<std::pair<int, int>> cameras_sharing_a_pose(const Rig& rig);

//! Where cameras_sharing_a_pose finds two: "cameras[j].world_from_depth: the pose of cameras[i]
//! ...: the rig is not calibrated" and what to do; empty otherwise.
std::string shared_pose_problem(const Rig& rig);

//! Throws InvalidInput "`source`: " + shared_pose_problem(rig) where that is not empty.
void check_poses_distinct(const Rig& rig, const std::string& source);

//! Whether the rig's world looks z-up, as the volume's floor lift (ForegroundOptions::
//! floor_noise_sigmas) takes it. Either of two signs will do:
//! - more than half of the cameras stand upright (the image's "down" axis within 60° of the
//!   world's −z) or look steeply down (the viewing axis within about 45° of −z, overhead);
//! - the cameras stand around the subject at about one height: the plane through three or more
//!   of them lies within 30° of level, or the line through two within 30° of level.
//! The second also takes cameras mounted on their side (portrait) or upside down. A ring in a
//! y-up world, or in its first camera's own frame as other tools often write rigs, shows neither;
//! some worlds cannot be told from the poses (a y-up rig of cameras looking along −z from one
//! side, a z-down world), and a rig without cameras does not look z-up.
bool world_looks_z_up(const Rig& rig);

//! Puts camera `c` of `calibration` (a rig.json read from `source`: what `calibrate` and
//! `register` write) onto `camera`, the model of the camera whose frames are read: its depth and
//! colour intrinsics (distortion included), color_from_depth and world_from_depth. The name and
//! what belongs to the recording stay. Throws InvalidInput naming `source` and the field when the
//! image sizes or the presence of colour differ, for the frames are what they are; `owner` names
//! whose frames they are in that message ("the capture's", "the device's").
void take_camera_calibration(CameraModel& camera, const Rig& calibration, int c, const std::string& source, const std::string& owner);

}  // namespace zipfusion
