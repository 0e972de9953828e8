// zipfusion record: live cameras (Kinect v1 through libfreenect, or fakenect dumps) to a rig
// capture, written incrementally: Ctrl-C or a crash leaves a valid capture of what was recorded.

#include <cstdio>
#include <iostream>
#include <memory>

#include "cli/commands.h"
#include "cli/live_devices.h"
#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/live/live_rig.h"
#include "zipfusion/live/recorder.h"

namespace zipfusion::cli {
namespace {

struct RecordArgs {
  LiveDeviceArgs devices;
  std::string out;
  std::string rig;
  std::string color_format = "jpg";
  bool list_devices = false;
  RecordOptions options;
};

void print_devices() {
  const std::vector<KinectDevice> devices = list_kinect_devices();
  if (devices.empty()) std::cout << "no Kinect v1 found\n";
  for (const KinectDevice& d : devices) {
    std::cout << d.index << "  " << (d.serial.empty() ? "(serial unknown)" : d.serial) << "\n";
  }
}

// One line per camera whose stream ended on its own (not stopped by us), when it happens.
struct EndReporter {
  const Rig& rig;
  std::vector<char> reported;
  void report(const LiveRig& live, const std::vector<int>& written) {
    const std::vector<LiveCameraStats> stats = live.stats();
    reported.resize(stats.size(), 0);
    for (size_t c = 0; c < stats.size(); ++c) {
      if (!stats[c].ended || reported[c] || stats[c].end_reason == "stopped") continue;
      reported[c] = 1;
      std::cout << "record: " << rig.cameras[c].name << " (" << live.camera(static_cast<int>(c)).description()
                << "): stream ended after " << written[c] << " frames: " << stats[c].end_reason << "\n"
                << std::flush;
    }
  }
};

void run_record(RecordArgs& args) {
  if (args.list_devices) {
    print_devices();
    return;
  }
  if (args.out.empty()) throw InvalidInput("--out: required (the capture folder to write)");
  args.options.color_extension = "." + args.color_format;
  args.options.validate();
  check_new_folder(args.out, "--out");  // before the cameras start (record_capture checks it again)
  install_stop_on_signal();
  LiveRig live(open_live_cameras(args.devices), live_rig_options(args.devices, &stop_requested()));
  Rig rig;
  if (args.rig.empty()) {
    rig = make_live_rig(live);
  } else {
    const Rig calibration = read_rig(args.rig);
    rig = make_live_rig(live, &calibration, args.rig);
  }
  std::cout << "recording";
  for (int c = 0; c < live.camera_count(); ++c) std::cout << (c ? ", " : " ") << rig.cameras[c].name << " = " << live.camera(c).description();
  std::cout << " to " << args.out << " (Ctrl-C stops)\n";
  if (args.rig.empty()) {
    std::cout << "record: no --rig: world poses are identity; calibrate the rig (README.md) and reconstruct with --rig\n";
  }
  std::cout << std::flush;

  EndReporter ends{rig, {}};
  std::vector<int> written(live.camera_count(), 0);
  RecordOptions options = args.options;
  options.progress = [&](const LiveFrameSet& set) {
    for (size_t c = 0; c < set.cameras.size(); ++c) written[c] += set.cameras[c].has_value();
    ends.report(live, written);
    show_progress("record", set.index + 1, options.max_frames > 0 ? options.max_frames : set.index + 2);
  };
  const RecordResult result = record_capture(live, rig, args.out, options);
  if (result.frame_sets > 0) show_progress("record", result.frame_sets, result.frame_sets);  // ends the progress line
  ends.report(live, result.frames_written);

  std::printf("recorded %d frame sets in %.2f s to %s:", result.frame_sets, result.duration_s, args.out.c_str());
  for (size_t c = 0; c < result.frames_written.size(); ++c) std::printf(" %s %d", rig.cameras[c].name.c_str(), result.frames_written[c]);
  std::printf(" frames; skew max %.1f ms, mean %.1f ms%s\n", result.max_skew_s * 1000, result.mean_skew_s * 1000,
              stop_requested() ? " (stopped by Ctrl-C)" : "");
  for (size_t c = 0; c < result.cameras.size(); ++c) {
    const LiveCameraStats& s = result.cameras[c];
    if (s.dropped > 0) {
      std::printf("record: %s: %ld frames dropped by the camera's queue (writing fell behind; they were never recorded)\n",
                  rig.cameras[c].name.c_str(), s.dropped);
    }
    if (s.discarded_late > 0) {
      std::printf("record: %s: %ld frames came after their frame set was written and were left out\n", rig.cameras[c].name.c_str(),
                  s.discarded_late);
    }
  }
  std::fflush(stdout);
  if (result.frame_sets == 0) throw IoError(args.out + ": no frame was recorded (the capture is empty)");
}

}  // namespace

void add_record_command(CLI::App& app) {
  auto args = std::make_shared<RecordArgs>();
  CLI::App* cmd = app.add_subcommand("record", "Record live cameras (Kinect v1) to a rig capture, incrementally");
  add_live_device_options(cmd, args->devices);
  cmd->add_option("--out", args->out, "Capture folder to write (must not exist or be empty)");
  cmd->add_option("--seconds", args->options.max_seconds, "Length to record, seconds (0 = until Ctrl-C or the streams end)")
      ->capture_default_str();
  cmd->add_option("--frames", args->options.max_frames, "Frame sets to record (0 = no limit)")->capture_default_str();
  cmd->add_option("--rig", args->rig,
                  "Calibration rig.json: camera i takes its name and whole calibration from it (intrinsics with distortion, "
                  "color_from_depth, world pose; the rig its volume and poses_trusted), written into the capture; without it the "
                  "devices' intrinsics and identity poses");
  cmd->add_option("--color-format", args->color_format, "Colour files: jpg or png")->check(CLI::IsMember({"jpg", "png"}))->capture_default_str();
  cmd->add_option("--jpeg-quality", args->options.jpeg_quality, "JPEG quality 1..100")->capture_default_str();
  add_threads_option(cmd, args->options.num_threads, "Encoding threads (0 = all cores)");
  cmd->add_flag("--list-devices", args->list_devices, "List the Kinect v1 devices (index and serial) and exit");
  cmd->callback([args] { run_record(*args); });
}

}  // namespace zipfusion::cli
