#pragma once
// --rig FILE for the CLI: camera poses from another rig.json describing the same cameras.

#include <filesystem>
#include <string>

#include "zipfusion/core/error.h"
#include "zipfusion/io/rig.h"

namespace zipfusion::cli {

//! `rig` with the poses of the rig.json at `path`; throws InvalidInput naming that file and the
//! field when its cameras differ.
inline Rig rig_with_poses_from(const Rig& rig, const std::filesystem::path& path) {
  const Rig other = read_rig(path);
  if (other.cameras.size() != rig.cameras.size()) {
    throw InvalidInput(path.string() + ": cameras: has " + std::to_string(other.cameras.size()) + " cameras, the capture has " +
                       std::to_string(rig.cameras.size()));
  }
  Rig result = rig;
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    if (other.cameras[c].name != rig.cameras[c].name) {
      throw InvalidInput(path.string() + ": cameras[" + std::to_string(c) + "].name: \"" + other.cameras[c].name + "\" is not the capture's \"" +
                         rig.cameras[c].name + "\"");
    }
    result.cameras[c].world_from_depth = other.cameras[c].world_from_depth;
  }
  result.poses_trusted = other.poses_trusted;
  return result;
}

}  // namespace zipfusion::cli
