// libFuzzer target: rig.json (io/rig.h), the file every capture, outside tool and calibration
// writes, and the intrinsics files `calibrate extrinsics --intrinsics` reads. A parsed rig must
// come back field for field from what format_rig writes of it; parsed intrinsics likewise.

#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz/fuzz_check.h"
#include "zipfusion/io/rig.h"

namespace zipfusion::fuzz {
namespace {

bool same_pose(const Rigid3d& a, const Rigid3d& b) { return a.matrix() == b.matrix(); }

bool same_camera(const CameraModel& a, const CameraModel& b) {
  return a.name == b.name && a.depth_intrinsics == b.depth_intrinsics && a.color_intrinsics == b.color_intrinsics &&
         same_pose(a.color_from_depth, b.color_from_depth) && same_pose(a.world_from_depth, b.world_from_depth);
}

bool same_rig(const Rig& a, const Rig& b) {
  if (a.fps != b.fps || a.frame_count != b.frame_count || a.depth_unit_m != b.depth_unit_m || a.poses_trusted != b.poses_trusted) return false;
  if (a.volume.has_value() != b.volume.has_value()) return false;
  if (a.volume && (a.volume->min != b.volume->min || a.volume->max != b.volume->max)) return false;
  if (a.cameras.size() != b.cameras.size()) return false;
  for (size_t i = 0; i < a.cameras.size(); ++i) {
    if (!same_camera(a.cameras[i], b.cameras[i])) return false;
  }
  return true;
}

void check_rig(const std::string& text) {
  const auto rig = decoded_or_error("rig", [&] { return parse_rig(text, kSource); });
  if (!rig) return;
  if (rig->cameras.empty()) fail("a rig without cameras");
  const Rig again = must_decode([&] { return parse_rig(format_rig(*rig), kSource); }, "rig.json");
  if (!same_rig(again, *rig)) fail("rig.json round trip changed the rig");
}

void check_intrinsics_file(const std::string& text) {
  const auto k = decoded_or_error("intrinsics", [&] { return parse_intrinsics_file(text, kSource); });
  if (!k) return;
  const std::string written = std::string("{\"format\": \"") + kIntrinsicsFormat + "\", \"intrinsics\": " + format_intrinsics(*k) + "}";
  const Intrinsics again = must_decode([&] { return parse_intrinsics_file(written, kSource); }, "intrinsics file");
  if (!(again == *k)) fail("intrinsics file round trip changed the intrinsics");
}

}  // namespace
}  // namespace zipfusion::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  zipfusion::fuzz::check_rig(text);
  zipfusion::fuzz::check_intrinsics_file(text);
  return 0;
}
