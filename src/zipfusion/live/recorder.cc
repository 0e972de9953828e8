#include "zipfusion/live/recorder.h"

#include <cinttypes>
#include <cstdio>
#include <fstream>
#include <system_error>

#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/image_io.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

// A file of one frame set on its way to disk: written to `part`, then renamed to `path`.
struct PendingFile {
  fs::path path, part;
  std::vector<std::uint8_t> bytes;
};

PendingFile pending_file(const fs::path& folder, const std::string& name, std::vector<std::uint8_t> bytes) {
  return {folder / name, folder / ("." + name + ".part"), std::move(bytes)};
}

void write_part(const PendingFile& file) {
  std::ofstream out(file.part, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(file.bytes.data()), static_cast<std::streamsize>(file.bytes.size()));
  out.flush();
  if (!out) throw IoError(file.path.string() + ": write failed");
}

void rename_into_place(const PendingFile& file) {
  std::error_code ec;
  fs::rename(file.part, file.path, ec);
  if (ec) throw IoError(file.path.string() + ": cannot rename temporary file: " + ec.message());
}

void check_rig_matches(const Rig& rig, const LiveRig& live) {
  if (static_cast<int>(rig.cameras.size()) != live.camera_count()) {
    throw InvalidInput("rig.json: cameras: has " + std::to_string(rig.cameras.size()) + " cameras, the live rig " +
                       std::to_string(live.camera_count()));
  }
}

}  // namespace

void RecordOptions::validate() const {
  if (max_frames < 0 || max_frames > kMostFrames) {
    throw InvalidInput("--frames: must be in [0, " + std::to_string(kMostFrames) + "] (0 = no limit), got " + std::to_string(max_frames));
  }
  if (!(max_seconds >= 0)) throw InvalidInput("--seconds: must be >= 0 (0 = no limit)");
  if (color_extension != ".jpg" && color_extension != ".png") throw InvalidInput("--color-format: must be jpg or png");
  if (jpeg_quality < 1 || jpeg_quality > 100) throw InvalidInput("--jpeg-quality: must be in [1, 100]");
  if (num_threads < 0) throw InvalidInput("--threads: must be >= 0");
}

RecordResult record_capture(LiveRig& live, const Rig& rig_in, const fs::path& out_dir, const RecordOptions& options) {
  options.validate();
  check_rig_matches(rig_in, live);
  check_new_folder(out_dir, "--out");
  Rig rig = rig_in;
  rig.frame_count = 0;
  const int n = live.camera_count();
  std::error_code ec;
  for (const CameraModel& camera : rig.cameras) {
    fs::create_directories(out_dir / camera.name / "depth", ec);
    if (!ec && camera.has_color()) fs::create_directories(out_dir / camera.name / "color", ec);
    if (ec) throw IoError((out_dir / camera.name).string() + ": cannot create folder: " + ec.message());
  }
  const fs::path timestamps_path = out_dir / "timestamps.csv";
  std::ofstream timestamps(timestamps_path, std::ios::trunc);
  timestamps << "frame,camera,time_s,device_timestamp\n";
  timestamps.flush();
  if (!timestamps) throw IoError(timestamps_path.string() + ": cannot write");
  write_rig(out_dir / "rig.json", rig);  // an empty, valid capture from the start

  RecordResult result;
  result.frames_written.assign(n, 0);
  double first_time_s = 0, skew_sum_s = 0;
  int skew_sets = 0;
  std::vector<std::vector<PendingFile>> files(n);
  LiveFrameSet set;
  while (true) {
    // A capture holds at most kMostFrames (six-digit frame files): about 9 hours at 30 fps.
    if ((options.max_frames > 0 && result.frame_sets >= options.max_frames) || result.frame_sets >= kMostFrames) {
      result.limit_reached = true;
      break;
    }
    if (!live.next(set)) break;
    if (result.frame_sets == 0) first_time_s = set.time_s;
    if (options.max_seconds > 0 && set.time_s - first_time_s >= options.max_seconds) {
      result.limit_reached = true;
      break;
    }
    const int frame = rig.frame_count;
    // Encode and write every camera's files under temporary names (in parallel), then rename.
    parallel_for(0, n, [&](int c) {
      files[c].clear();
      const std::optional<LiveFrame>& f = set.cameras[c];
      if (!f) return;
      const CameraModel& camera = rig.cameras[c];
      files[c].push_back(pending_file(out_dir / camera.name / "depth", frame_file_name(frame, ".png"), encode_depth_png(f->depth)));
      if (camera.has_color() && f->has_color) {
        files[c].push_back(pending_file(out_dir / camera.name / "color", frame_file_name(frame, options.color_extension),
                                        encode_color_image(f->color, options.color_extension, options.jpeg_quality)));
      }
      for (const PendingFile& file : files[c]) write_part(file);
    }, options.num_threads);
    int members = 0;
    for (int c = 0; c < n; ++c) {
      for (const PendingFile& file : files[c]) rename_into_place(file);
      const std::optional<LiveFrame>& f = set.cameras[c];
      if (!f) continue;
      ++members;
      ++result.frames_written[c];
      char line[256];
      std::snprintf(line, sizeof line, "%d,%s,%.6f,%" PRIu32 "\n", frame, rig.cameras[c].name.c_str(), f->time_s - first_time_s,
                    f->device_timestamp);
      timestamps << line;
    }
    timestamps.flush();
    if (!timestamps) throw IoError(timestamps_path.string() + ": write failed");
    rig.frame_count = frame + 1;
    write_rig(out_dir / "rig.json", rig);
    result.frame_sets = rig.frame_count;
    result.duration_s = set.time_s - first_time_s;
    if (members >= 2) {
      result.max_skew_s = std::max(result.max_skew_s, set.skew_s);
      skew_sum_s += set.skew_s;
      ++skew_sets;
    }
    if (options.progress) options.progress(set);
  }
  if (result.limit_reached) live.stop();
  result.mean_skew_s = skew_sets > 0 ? skew_sum_s / skew_sets : 0;
  result.cameras = live.stats();
  return result;
}

std::vector<RecordedTimestamp> read_recorded_timestamps(const fs::path& capture_dir, int frame_count) {
  const fs::path path = capture_dir / "timestamps.csv";
  const std::vector<std::uint8_t> bytes = read_file_bytes(path);
  const std::string text(bytes.begin(), bytes.end());
  std::vector<RecordedTimestamp> out;
  size_t start = text.find('\n');
  if (start == std::string::npos || text.compare(0, start, "frame,camera,time_s,device_timestamp") != 0) {
    throw InvalidInput(path.string() + ": line 1: expected the header frame,camera,time_s,device_timestamp");
  }
  ++start;
  int line_number = 1;
  while (start < text.size()) {
    const size_t end = text.find('\n', start);
    if (end == std::string::npos) break;  // an incomplete last line: a crash while appending
    const std::string line = text.substr(start, end - start);
    start = end + 1;
    ++line_number;
    RecordedTimestamp t;
    char camera[128] = {0};
    unsigned long long device = 0;
    char tail = 0;
    if (std::sscanf(line.c_str(), "%d,%127[^,],%lf,%llu%c", &t.frame, camera, &t.time_s, &device, &tail) != 4 || t.frame < 0 ||
        device > 0xffffffffULL) {
      throw InvalidInput(path.string() + ": line " + std::to_string(line_number) + ": expected FRAME,CAMERA,TIME_S,DEVICE_TIMESTAMP, got \"" +
                         line + "\"");
    }
    if (t.frame >= frame_count) continue;
    t.camera = camera;
    t.device_timestamp = static_cast<std::uint32_t>(device);
    out.push_back(std::move(t));
  }
  return out;
}

}  // namespace zipfusion
