#pragma once
// Live cameras for the CLI (record, reconstruct --live): --devices / --replay / --depth-format,
// and Ctrl-C as a clean stop.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <csignal>
#include <memory>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "zipfusion/core/error.h"
#include "zipfusion/live/kinect_camera.h"
#include "zipfusion/live/live_camera.h"
#include "zipfusion/live/live_rig.h"
#include "zipfusion/live/replay_camera.h"

namespace zipfusion::cli {

struct LiveDeviceArgs {
  std::string devices;               // --devices all|INDEX,...|SERIAL,...
  std::string replay;                // --replay DUMP[,DUMP...]
  std::string depth_format = "auto";
  KinectOptions kinect;
  double max_wait_s = -1;            // --max-wait; below 0: 0.25 s for devices, the stall timeout for replays
  bool replay_paced = false;         // replays at their recorded pace (serve: a live stream), not as fast as read
  bool replay_loop = false;          // replays again and again (serve --loop)
  // The options as given on the command line (add_live_device_options): asked whether they were
  // given at all, as a value equal to the default is given too.
  std::vector<const CLI::Option*> given_options;
};

//! The LiveRig's options for the selected cameras. A device (or a paced replay) delivers in real
//! time, so a camera 0.25 s late is dropped from its frame set and the set goes on; an unpaced
//! replay delivers as fast as it is read, so a late frame only means a busy machine (CI runs
//! tests side by side), and the rig waits up to the stall timeout before it decides a set without it.
inline LiveRigOptions live_rig_options(const LiveDeviceArgs& args, const std::atomic<bool>* cancel) {
  // A paced replay delivers as a device does (a looped dump shorter than the others' pass must
  // not hold every set for seconds).
  const bool real_time = args.replay.empty() || args.replay_paced;
  const double wait = args.max_wait_s >= 0 ? args.max_wait_s : real_time ? 0.25 : args.kinect.stall_timeout_s;
  return LiveRigOptions{.max_wait_s = std::min(wait, 60.0), .cancel = cancel};
}

inline void add_live_device_options(CLI::App* cmd, LiveDeviceArgs& args) {
  args.given_options.push_back(cmd->add_option("--devices", args.devices,
                  "Kinect v1 devices: all, or comma-separated indices (0,2) or serials, in the rig's camera order (cam0, cam1, ...)"));
  args.given_options.push_back(cmd->add_option("--replay", args.replay,
                  "Instead of devices: fakenect dumps (fakenect-record folders), one per camera, comma-separated, replayed as fast as "
                  "they can be read (their recording times group the frames; serve plays them at their recorded pace)"));
  args.given_options.push_back(cmd->add_option("--depth-format", args.depth_format,
                  "Kinect depth: auto (mm where libfreenect registers depth, raw under fakenect), mm, registered (on the colour "
                  "camera's grid) or raw (11-bit disparity, converted by the Kinect v1 model)")
      ->check(CLI::IsMember({"auto", "mm", "registered", "raw"}))
      ->capture_default_str());
  args.given_options.push_back(cmd->add_option("--stall-timeout", args.kinect.stall_timeout_s, "A Kinect without a depth frame this long has been unplugged, seconds")
      ->check(kFiniteNumber & CLI::Range(0.05, 3600.0))
      ->capture_default_str());
  args.given_options.push_back(cmd->add_option("--max-wait", args.max_wait_s,
                  "A camera's frame this late is left out of its frame set, seconds (default: 0.25 for --devices, the stall timeout "
                  "for --replay, whose frames come as fast as they are read)")
      ->check(CLI::Range(0.0, 60.0)));
}

inline std::vector<std::string> split_commas(const std::string& text) {
  std::vector<std::string> parts;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(',', start), text.size());
    parts.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return parts;
}

//! Throws InvalidInput naming the live-camera options given to a run that reads a capture (they
//! would be ignored).
inline void check_no_live_device_options(const LiveDeviceArgs& args) {
  std::string given;
  for (const CLI::Option* option : args.given_options) {
    if (option->count() > 0) given += (given.empty() ? "" : ", ") + option->get_name();
  }
  if (!given.empty()) throw InvalidInput(given + ": only with --live");
}

//! The selected cameras; throws InvalidInput naming the option.
inline std::vector<std::unique_ptr<LiveCamera>> open_live_cameras(LiveDeviceArgs& args) {
  if (args.devices.empty() == args.replay.empty()) throw InvalidInput("--devices, --replay: give exactly one (the cameras to read)");
  std::vector<std::unique_ptr<LiveCamera>> cameras;
  if (!args.replay.empty()) {
    std::vector<std::filesystem::path> dumps;
    for (const std::string& dir : split_commas(args.replay)) {
      if (dir.empty()) throw InvalidInput("--replay: \"" + args.replay + "\": an empty entry");
      dumps.emplace_back(dir);
    }
    ReplayOptions options{.loop = args.replay_loop, .paced = args.replay_paced};
    // One time line for all dumps (recorded on one PC): paced, the cameras deliver together;
    // looped, every camera's pass has the same length, so their frames stay grouped.
    if (options.loop || options.paced) options.timeline = replay_timeline(dumps, options.fps);
    for (size_t c = 0; c < dumps.size(); ++c) cameras.push_back(std::make_unique<ReplayCamera>(dumps[c], "cam" + std::to_string(c), options));
    return cameras;
  }
  const std::string& f = args.depth_format;
  args.kinect.depth_format = f == "mm"           ? KinectDepthFormat::kMillimetres
                             : f == "registered" ? KinectDepthFormat::kRegistered
                             : f == "raw"        ? KinectDepthFormat::kRaw
                                                 : KinectDepthFormat::kAuto;
  return open_kinect_cameras(args.devices, args.kinect);
}

//! Set by SIGINT, SIGTERM or SIGHUP (a closed terminal) while installed; a second one ends the
//! process as usual. A SIGHUP the process started with ignored stays ignored: nohup's (the run
//! outlives its terminal). SIGINT is caught all the same: a script that starts a run in the
//! background (bash then ignores SIGINT for it) and waits is stopped by Ctrl-C as a whole.
inline std::atomic<bool>& stop_requested() {
  static std::atomic<bool> flag{false};
  return flag;
}

//! The signal that set stop_requested(), 0 before one came.
inline std::atomic<int>& stop_signal() {
  static std::atomic<int> number{0};
  return number;
}

//! Idempotent: a second call (serve installs it, then opens live cameras, which install it too)
//! keeps a signal that came in between.
inline void install_stop_on_signal() {
  static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<int>::is_always_lock_free, "the signal handler stores to them");
  static bool installed = false;
  if (installed) return;
  installed = true;
  stop_requested().store(false);  // also constructs the flags before any signal can arrive
  stop_signal().store(0);
  struct sigaction action {};
  action.sa_handler = [](int number) {
    stop_signal().store(number);
    stop_requested().store(true);
  };
  action.sa_flags = SA_RESETHAND;
  sigemptyset(&action.sa_mask);
  for (const int number : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction inherited {};
    if (number == SIGHUP && sigaction(number, nullptr, &inherited) == 0 && inherited.sa_handler == SIG_IGN) continue;
    sigaction(number, &action, nullptr);
  }
}

}  // namespace zipfusion::cli
