#include "cli/frame_input.h"

#include <algorithm>
#include <iostream>
#include <sstream>
#include <type_traits>

#include "cli/commands.h"
#include "cli/rig_poses.h"

namespace zipfusion::cli {

static_assert(std::is_same_v<FrameSource, LiveFrameSource>, "live_frame_source feeds run_pipeline as it is");

void add_input_options(CLI::App* cmd, InputArgs& args) {
  cmd->add_option("capture", args.capture, "Capture folder (with rig.json); not with --live");
  cmd->add_option("--frames", args.frames, "Frames A:B (A included, B excluded; default all); with --live, the number of frame sets");
  cmd->add_flag("--live", args.live, "Live cameras (--devices or --replay) instead of a capture; Ctrl-C stops");
  add_live_device_options(cmd, args.devices);
  cmd->add_option("--seconds", args.seconds, "Seconds to run (0 = until Ctrl-C or the end of the frames)")->capture_default_str();
}

double Input::skew_of(int index) {
  std::lock_guard lock(skew_mutex);
  return index >= 0 && index < static_cast<int>(skew_ms.size()) ? skew_ms[index] : -1;
}

std::vector<std::string> Input::unreadable_of(int index) {
  std::lock_guard lock(unreadable_mutex);
  const auto found = unreadable.find(index);
  return found == unreadable.end() ? std::vector<std::string>{} : found->second;
}

int Input::unreadable_count() {
  std::lock_guard lock(unreadable_mutex);
  int count = 0;
  for (const auto& [index, files] : unreadable) count += static_cast<int>(files.size());
  return count;
}

std::vector<std::string> UnreadableFrames::report(const Rig& rig, const FrameSet& set) {
  std::vector<std::string> files = unreadable_files(set);
  const bool has_depth = std::any_of(set.cameras.begin(), set.cameras.end(), [](const CameraFrame& c) { return c.has_depth; });
  if (!depth_decoded_ && !has_depth && !files.empty()) {
    throw InvalidInput(files.front() + "; no depth of the capture has decoded up to this frame set (are its files unreadable: Git LFS "
                                        "pointers, no read permission?)");
  }
  depth_decoded_ = depth_decoded_ || has_depth;
  for (size_t c = 0; c < set.cameras.size(); ++c) {
    for (const std::string& file : set.cameras[c].unreadable) {
      ++count_;
      if (count_ > kListed + 1) continue;
      std::ostringstream line;
      if (count_ == kListed + 1) {
        line << command_ << ": warning: more frame files cannot be decoded; they are counted, not listed";
      } else {
        // A camera without depth is left out; one with depth but no colour makes grey vertices.
        line << command_ << ": warning: " << file << "; " << rig.cameras.at(c).name
             << (set.cameras[c].has_depth ? " has no colour in frame set " : " left out of frame set ") << set.index;
      }
      print_diagnostic(line.str());
    }
  }
  return files;
}

namespace {

// One line for the frame files of `range` that the capture lacks (known when it is opened, as the
// unreadable ones are not), so that a camera left out, or grey, is not a surprise.
void warn_missing_frames(const Capture& capture, const FrameRange& range, const std::string& command) {
  const Rig& rig = capture.rig();
  std::vector<int> depth(rig.cameras.size(), 0), color(rig.cameras.size(), 0);
  int total = 0;
  for (const MissingFrame& m : capture.missing_frames()) {
    if (m.frame < range.begin || m.frame >= range.end) continue;
    ++(m.color ? color : depth)[m.camera];
    ++total;
  }
  if (total == 0) return;
  std::string counts;
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    if (depth[c] + color[c] == 0) continue;
    counts += (counts.empty() ? "" : ", ") + rig.cameras[c].name + " depth " + std::to_string(depth[c]) + " colour " + std::to_string(color[c]);
  }
  print_diagnostic(command + ": warning: " + std::to_string(total) + " frame files missing (" + counts +
                   "): a camera without its depth file is left out of that frame set, one without its colour file is grey there");
}

}  // namespace

Capture open_capture(const std::string& dir, const std::string& command) {
  Capture capture = Capture::open(dir);
  if (!capture.ground_truth_rig_problem().empty()) {
    print_diagnostic(command + ": warning: " + capture.ground_truth_rig_problem() + "; the ground truth is not used");
  }
  return capture;
}

void open_input(InputArgs& args, const std::string& rig_path, const std::string& command, Input& in) {
  if (!(args.seconds >= 0)) throw InvalidInput("--seconds: must be >= 0 (0 = until Ctrl-C or the end of the frames)");
  if (!args.live) {
    if (args.capture.empty()) throw InvalidInput("capture: required (or --live)");
    check_no_live_device_options(args.devices);
    in.capture.emplace(open_capture(args.capture, command));
    in.rig = calibrated_rig(*in.capture, rig_path);
    in.range = parse_frame_range(args.frames, in.capture->frame_count());
    warn_missing_frames(*in.capture, in.range, command);
    in.source = [source = capture_source(*in.capture, in.range.begin, in.range.end), &in,
                 report = std::make_shared<UnreadableFrames>(command)](FrameSet& set, double& decode_ms) {
      if (!source(set, decode_ms)) return false;
      if (std::vector<std::string> files = report->report(in.capture->rig(), set); !files.empty()) {
        std::lock_guard lock(in.unreadable_mutex);
        in.unreadable[set.index] = std::move(files);
      }
      return true;
    };
    return;
  }
  if (!args.capture.empty()) throw InvalidInput("--live: takes no CAPTURE (frames come from --devices or --replay)");
  int max_frames = 0;
  if (!args.frames.empty()) {
    size_t used = 0;
    try {
      max_frames = std::stoi(args.frames, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != args.frames.size() || max_frames < 1) {
      throw InvalidInput("--frames: with --live, the number of frame sets (a whole number >= 1), got \"" + args.frames + "\"");
    }
  }
  install_stop_on_signal();
  in.live = std::make_unique<LiveRig>(open_live_cameras(args.devices), live_rig_options(args.devices, &stop_requested()));
  if (rig_path.empty()) {
    in.rig = make_live_rig(*in.live);
    // One camera needs no pose; several at one identity pose would lay their meshes over each other.
    if (in.rig.cameras.size() > 1) {
      throw InvalidInput("--rig: required with " + std::to_string(in.rig.cameras.size()) +
                         " live cameras (without it every pose is identity); run zipfusion calibrate and pass its rig.json");
    }
    std::cout << "no --rig: world pose is identity\n" << std::flush;
  } else {
    const Rig calibration = read_rig(rig_path);
    in.rig = make_live_rig(*in.live, &calibration, rig_path);
    check_poses_distinct(in.rig, rig_path);
  }
  in.range = {0, max_frames};
  LiveSourceOptions source_options{.max_frames = max_frames, .max_seconds = args.seconds, .observe = [&in](const LiveFrameSet& set) {
    std::lock_guard lock(in.skew_mutex);
    in.skew_ms.resize(set.index + 1, 0);
    in.skew_ms[set.index] = set.skew_s * 1000;
  }};
  source_options.depth_undistortion = depth_undistortion_maps(in.rig);  // a calibration's depth distortion, as a capture's reader applies it
  in.take_before_start = [&rig = *in.live, undistortion = source_options.depth_undistortion, live = std::make_shared<LiveFrameSet>(), command,
                          said = false](FrameSet& set) mutable {
    if (!said) std::cout << command << ": refining the poses on the first live frame sets before the first mesh (--register once)" << std::endl;
    said = true;
    return !stop_requested() && read_live_frame_set(rig, *live, set, undistortion);
  };
  in.source = live_frame_source(*in.live, std::move(source_options));
}

}  // namespace zipfusion::cli
