#pragma once
//! \file
//! The synthetic scene as a fakenect dump (`synth --fakenect DIR`): one camera of the synth ring
//! (fakenect emulates one device) written as libfreenect's fakenect-record would have recorded
//! it, plus the truth to check a recording of its replay against.
//!
//! DIR/INDEX.txt, r-*.ppm, d-*.pgm (fakenect_dump.h): per frame i the colour image at
//! start_time_s + i/fps, then the depth 1 ms later, device timestamps first_timestamp +
//! i·timestamp_step (colour 60000 ticks earlier). Depth is the synth sensor model without its own
//! disparity quantisation, encoded to 11-bit raw values by kinect_mm_to_raw (kinect_disparity.h):
//! the raw encoding is the quantisation, so what a reader gets back is kinect_raw_to_mm of it.
//!
//! DIR/truth/: a rig capture (zipfusion.rig/1, one camera "cam0" with the true pose and Kinect v1
//! intrinsics, every frame even where INDEX.txt is truncated) whose depth is the millimetres
//! before raw encoding and whose colour (PNG) is the PPM's exactly; truth/timestamps.csv (as
//! recorder.h writes it) holds each depth frame's time since frame 0's depth, as written in the
//! file names, and its device timestamp.

#include <cstdint>
#include <filesystem>
#include <functional>

#include "zipfusion/synth/synth.h"

namespace zipfusion {

struct FakenectSceneOptions {
  int camera = 0;                           // which camera of the ring is recorded
  int truncate_at = -1;                     // INDEX.txt ends after frame N's colour (its depth and later frames are not listed), as a device unplugged mid-recording leaves it; -1 = complete
  double start_time_s = 1700000000.0;       // recording host time of frame 0's colour, seconds
  std::uint32_t first_timestamp = 1000000;  // device timestamp of frame 0's depth
  std::uint32_t timestamp_step = 2000000;   // device timestamp per frame

  void validate(const SynthOptions& synth) const;  // throws InvalidInput naming the field
};

struct FakenectSceneResult {
  int frames_listed = 0;  // depth frames listed in INDEX.txt
  Rig truth_rig;          // as written to DIR/truth/rig.json
};

//! Writes the dump to `dir`, which must not exist or be empty (InvalidInput naming --fakenect);
//! all of it appears at once (write_folder_atomic). `options` must describe 640×480 images.
FakenectSceneResult write_fakenect_scene(const std::filesystem::path& dir, const SynthOptions& options, const FakenectSceneOptions& scene,
                                         const std::function<void(int, int)>& progress = {});

}  // namespace zipfusion
