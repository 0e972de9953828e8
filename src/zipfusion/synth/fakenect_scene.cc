#include "zipfusion/synth/fakenect_scene.h"

#include <cinttypes>
#include <cstdio>
#include <cstdlib>

#include "zipfusion/core/error.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/image_io.h"
#include "zipfusion/live/fakenect_dump.h"
#include "zipfusion/live/kinect_disparity.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

// The time as it reads back from the file name (printf %f): what a reader of the dump sees.
double as_written(double time_s) {
  char text[64];
  std::snprintf(text, sizeof text, "%f", time_s);
  return std::strtod(text, nullptr);
}

}  // namespace

void FakenectSceneOptions::validate(const SynthOptions& synth) const {
  if (camera < 0 || camera >= synth.cameras) {
    throw InvalidInput("--camera: must be in [0, " + std::to_string(synth.cameras - 1) + "] (--cameras " + std::to_string(synth.cameras) + ")");
  }
  if (truncate_at < -1 || truncate_at >= synth.frames) {
    throw InvalidInput("--truncate: must be in [0, " + std::to_string(synth.frames - 1) + "] (a frame of --frames " + std::to_string(synth.frames) + ")");
  }
  if (!(start_time_s >= 0 && start_time_s < 1e10)) throw InvalidInput("fakenect.start_time_s: must be in [0, 1e10) seconds");
  const double last = first_timestamp + static_cast<double>(timestamp_step) * synth.frames;
  if (first_timestamp < 60000 || last > 4294967295.0) throw InvalidInput("fakenect.timestamp_step: timestamps must stay within 32 bits");
}

FakenectSceneResult write_fakenect_scene(const fs::path& dir, const SynthOptions& options_in, const FakenectSceneOptions& scene,
                                         const std::function<void(int, int)>& progress) {
  options_in.validate();
  scene.validate(options_in);
  if (options_in.depth_width != kFakenectWidth || options_in.depth_height != kFakenectHeight) {
    throw InvalidInput("--resolution: fakenect replays 640x480 only");
  }
  check_new_folder(dir, "--fakenect");
  SynthOptions options = options_in;
  options.noise.disparity_quantization = false;  // the raw encoding quantises

  const Rig true_rig = make_ring_rig(options);
  const TriangleMesh first_subject = subject_mesh(options, 0);
  FakenectSceneResult result;
  Rig& truth = result.truth_rig;
  truth = true_rig;
  truth.cameras = {true_rig.cameras[scene.camera]};
  truth.cameras[0].name = "cam0";
  truth.volume = synthetic_capture_volume(first_subject);

  write_folder_atomic(dir, [&](const fs::path& staging) {
    const fs::path truth_dir = staging / "truth";
    fs::create_directories(truth_dir / "cam0" / "depth");
    fs::create_directories(truth_dir / "cam0" / "color");
    std::vector<FakenectIndexEntry> index;
    std::string timestamps = "frame,camera,time_s,device_timestamp\n";
    double first_depth_time_s = 0;
    for (int frame = 0; frame < options.frames; ++frame) {
      const TriangleMesh subject = frame == 0 ? first_subject : subject_mesh(options, frame);
      const SyntheticView view = render_view(subject, true_rig, scene.camera, frame, options);
      const double color_time_s = scene.start_time_s + frame / options.fps;
      const std::uint32_t depth_timestamp = scene.first_timestamp + static_cast<std::uint32_t>(frame) * scene.timestamp_step;
      FakenectIndexEntry color{.type = 'r', .time_s = color_time_s, .timestamp = depth_timestamp - 60000, .file = ""};
      FakenectIndexEntry depth{.type = 'd', .time_s = color_time_s + 0.001, .timestamp = depth_timestamp, .file = ""};
      color.file = fakenect_file_name(color.type, color.time_s, color.timestamp);
      depth.file = fakenect_file_name(depth.type, depth.time_s, depth.timestamp);
      // Truncated: the colour of frame truncate_at is the last file, as if the device went then.
      const bool listed = scene.truncate_at < 0 || frame < scene.truncate_at;
      if (listed || frame == scene.truncate_at) {
        write_fakenect_file(staging, color, encode_fakenect_rgb(view.color));
        index.push_back(color);
      }
      if (listed) {
        RawDepthImage raw(view.depth.width, view.depth.height);
        for (size_t i = 0; i < raw.data.size(); ++i) raw.data[i] = kinect_mm_to_raw(view.depth.data[i]);
        write_fakenect_file(staging, depth, encode_fakenect_depth(raw));
        index.push_back(depth);
        ++result.frames_listed;
      }

      write_depth_png(truth_dir / "cam0" / "depth" / frame_file_name(frame, ".png"), view.depth);
      write_color_image(truth_dir / "cam0" / "color" / frame_file_name(frame, ".png"), view.color);
      if (frame == 0) first_depth_time_s = as_written(depth.time_s);
      char line[128];
      std::snprintf(line, sizeof line, "%d,cam0,%.6f,%" PRIu32 "\n", frame, as_written(depth.time_s) - first_depth_time_s, depth.timestamp);
      timestamps += line;
      if (progress) progress(frame + 1, options.frames);
    }
    write_fakenect_index(staging, index);
    write_file_atomic(truth_dir / "timestamps.csv", timestamps);
    write_rig(truth_dir / "rig.json", truth);
  });
  return result;
}

}  // namespace zipfusion
