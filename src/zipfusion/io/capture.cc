#include "zipfusion/io/capture.h"

#include <sys/stat.h>

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <system_error>
#include <tuple>

#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/io/file_util.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

// Is a frame file there? A missing one (or a link to nothing) is a missing frame, which degrades
// the frame set; one that cannot even be looked at (a loop of links, no permission) is an error
// naming it.
// (stat(2) on the name as it stands, not std::filesystem: a path object allocates each time.)
bool frame_file_present(const std::string& file) {
  struct stat status {};
  if (::stat(file.c_str(), &status) == 0) return true;
  const int error = errno;  // before the message is built, which may change it
  if (error == ENOENT || error == ENOTDIR) return false;
  throw IoError(file + ": " + std::strerror(error));
}

// Empties the image of a file left out. Its buffer stays for the next frame, unless a corrupt
// file's header made it larger than the camera's images (a bogus size would otherwise hold its
// memory for the rest of the run).
template <typename T>
void leave_out(Image<T>& image, const Intrinsics& camera) {
  if (image.data.capacity() > static_cast<size_t>(camera.width) * camera.height) {
    image = Image<T>();
  } else {
    image.resize_for_overwrite(0, 0);
  }
}

// `folder` (which ends in a separator) + frame_file_name(frame, extension), into `out`, whose
// buffer is reused (the name is short enough for std::string's own buffer: no allocation).
void frame_file_path(const std::string& folder, int frame, const char* extension, std::string& out) {
  out.assign(folder);
  out.append(frame_file_name(frame, extension));
}

void check_size(const std::string& file, int width, int height, const Intrinsics& k, const char* field) {
  if (width != k.width || height != k.height) {
    throw InvalidInput(file + ": size " + std::to_string(width) + "x" + std::to_string(height) + " does not match rig.json " +
                       field + " " + std::to_string(k.width) + "x" + std::to_string(k.height));
  }
}

void check_same_cameras(const Rig& rig, const Rig& truth, const std::string& truth_file) {
  if (truth.cameras.size() != rig.cameras.size()) {
    throw InvalidInput(truth_file + ": cameras: has " + std::to_string(truth.cameras.size()) + " cameras, rig.json has " +
                       std::to_string(rig.cameras.size()));
  }
  for (size_t i = 0; i < rig.cameras.size(); ++i) {
    if (truth.cameras[i].name != rig.cameras[i].name) {
      throw InvalidInput(truth_file + ": cameras[" + std::to_string(i) + "].name: \"" + truth.cameras[i].name +
                         "\" differs from rig.json's \"" + rig.cameras[i].name + "\"");
    }
  }
}

// The frame files of a camera's depth or colour folder, as (frame, extension), in no order: what
// is there, not what rig.json promises, so that a frame_count far beyond the files costs nothing
// before it is found out. A file numbered beyond frame_count is a rig.json error.
std::vector<std::pair<int, std::string>> scan_frame_folder(const fs::path& folder, std::initializer_list<const char*> extensions, int frames,
                                                           const fs::path& rig_path) {
  std::vector<std::pair<int, std::string>> files;
  for (const fs::directory_entry& entry : fs::directory_iterator(folder)) {
    const int index = frame_index_of(entry.path(), extensions);
    if (index < 0) continue;
    // A link to nothing is a missing file, as load_camera_frame finds it; a loop of links stays
    // listed, for load_camera_frame to name.
    std::error_code ec;
    if (!entry.exists(ec) && (!ec || ec == std::errc::no_such_file_or_directory)) continue;
    if (index >= frames) {
      throw InvalidInput(rig_path.string() + ": frame_count: is " + std::to_string(frames) + " but " +
                         (folder.parent_path().filename() / folder.filename() / entry.path().filename()).string() + " exists");
    }
    files.emplace_back(index, entry.path().extension().string());
  }
  return files;
}

}  // namespace

int frame_index_of(const fs::path& file, std::initializer_list<const char*> extensions) {
  const std::string stem = file.stem().string();
  const std::string ext = file.extension().string();
  bool ext_ok = false;
  for (const char* e : extensions) ext_ok = ext_ok || ext == e;
  if (!ext_ok || stem.size() != 6) return -1;
  int index = 0;
  for (char c : stem) {
    if (c < '0' || c > '9') return -1;
    index = index * 10 + (c - '0');
  }
  return index;
}

std::string frame_file_name(int frame, const std::string& extension) {
  char name[32];
  std::snprintf(name, sizeof name, "%06d", frame);
  return name + extension;
}

Capture Capture::open(const fs::path& dir, const CaptureOpenOptions& options) {
  check_input_folder(dir, "a capture folder");
  std::error_code ec;
  const fs::path rig_path = dir / "rig.json";
  if (!fs::exists(rig_path, ec)) throw IoError(rig_path.string() + ": missing (every capture has a rig.json)");

  Capture capture;
  capture.dir_ = dir;
  capture.options_ = options;
  capture.rig_ = read_rig(rig_path);
  const Rig& rig = capture.rig_;
  const int frames = rig.frame_count;
  for (const CameraModel& camera : rig.cameras) {
    // Appending an empty name ends each in a separator, as a join with a file name puts one.
    capture.frame_folders_.push_back({(dir / camera.name / "depth" / "").string(), (dir / camera.name / "color" / "").string()});
  }

  int last_frame_seen = -1;
  std::vector<std::vector<std::pair<int, std::string>>> depth_files(rig.cameras.size()), color_files(rig.cameras.size());
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    const CameraModel& camera = rig.cameras[c];
    const fs::path depth_dir = dir / camera.name / "depth";
    if (!fs::is_directory(depth_dir, ec)) {
      throw InvalidInput(depth_dir.string() + ": missing folder for rig.json cameras[" + std::to_string(c) + "] (\"" +
                         camera.name + "\")");
    }
    depth_files[c] = scan_frame_folder(depth_dir, {".png"}, frames, rig_path);
    for (const auto& [f, extension] : depth_files[c]) last_frame_seen = std::max(last_frame_seen, f);
    const fs::path color_dir = dir / camera.name / "color";
    if (camera.has_color() && fs::is_directory(color_dir, ec)) color_files[c] = scan_frame_folder(color_dir, {".jpg", ".png"}, frames, rig_path);
  }
  if (frames > 0 && last_frame_seen != frames - 1) {
    throw InvalidInput(rig_path.string() + ": frame_count: is " + std::to_string(frames) + " but no camera has frame " +
                       frame_file_name(frames - 1, ".png") +
                       (last_frame_seen < 0 ? " (no depth frames at all)" : " (last depth frame is " + frame_file_name(last_frame_seen, ".png") + ")"));
  }
  capture.color_file_.resize(rig.cameras.size());
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    std::vector<std::uint8_t> has_depth(frames, 0);
    for (const auto& [f, extension] : depth_files[c]) has_depth[f] = 1;
    std::vector<ColorFile>& color_ext = capture.color_file_[c];
    color_ext.assign(frames, ColorFile::kNone);
    for (const auto& [f, extension] : color_files[c]) {
      // Both a .jpg and a .png of one frame: which one was meant is not known.
      if (color_ext[f] != ColorFile::kNone) {
        const fs::path jpg = dir / rig.cameras[c].name / "color" / frame_file_name(f, ".jpg");
        throw InvalidInput(jpg.string() + ", " + fs::path(jpg).replace_extension(".png").filename().string() + ": a .jpg and a .png of the same frame");
      }
      color_ext[f] = extension == ".jpg" ? ColorFile::kJpg : ColorFile::kPng;
    }
    for (int f = 0; f < frames; ++f) {
      if (!has_depth[f]) capture.missing_.push_back({static_cast<int>(c), f, false});
      if (rig.cameras[c].has_color() && color_ext[f] == ColorFile::kNone) capture.missing_.push_back({static_cast<int>(c), f, true});
    }
  }
  std::sort(capture.missing_.begin(), capture.missing_.end(), [](const MissingFrame& a, const MissingFrame& b) {
    return std::tie(a.frame, a.camera, a.color) < std::tie(b.frame, b.camera, b.color);
  });
  if (options.strict && !capture.missing_.empty()) {
    const MissingFrame& m = capture.missing_.front();
    const fs::path file = m.color ? dir / rig.cameras[m.camera].name / "color" / frame_file_name(m.frame, ".jpg")
                                  : capture.depth_path(m.frame, m.camera);
 throw InvalidInput(file.string() + (m.color ? " (or .png)" : "") + ": missing frame (" + std::to_string(capture.missing_.size()) + " frame files missing in all)");
  }

  const fs::path truth_rig_path = dir / "ground_truth" / "rig.json";
  if (fs::exists(truth_rig_path, ec)) {
    try {
      capture.ground_truth_rig_ = read_rig(truth_rig_path);
      check_same_cameras(rig, *capture.ground_truth_rig_, truth_rig_path.string());
    } catch (const std::runtime_error& e) {  // InvalidInput or IoError
      // Only eval needs it (and info reports it): the frames stay usable without it.
      if (options.strict) throw;
      capture.ground_truth_rig_.reset();
      capture.ground_truth_rig_problem_ = e.what();
    }
  }
  capture.has_ground_truth_meshes_ = fs::is_directory(dir / "ground_truth" / "mesh", ec);
  capture.depth_undistortion_ = depth_undistortion_maps(capture.rig_);
  return capture;
}

void Capture::check_output_outside(const fs::path& output, std::string_view option) const {
  std::error_code ec;
  auto resolved = [&](const fs::path& p) {
    const fs::path canonical = fs::weakly_canonical(fs::absolute(p, ec), ec);
    return ec ? fs::absolute(p).lexically_normal() : canonical;
  };
  auto within = [](const fs::path& path, const fs::path& folder) {
    auto p = path.begin();
    for (auto f = folder.begin(); f != folder.end(); ++f, ++p) {
      if (f->empty() && std::next(f) == folder.end()) break;  // a trailing separator
      if (p == path.end() || *p != *f) return false;
    }
    return true;
  };
  const fs::path out = resolved(output), root = resolved(dir_);
  auto refuse = [&](const std::string& where) {
    throw InvalidInput(std::string(option) + ": " + output.string() + " " + where + " of the capture " + dir_.string() +
                       "; write it outside the capture's folders");
  };
  if (out == root) refuse("is the folder");
  // In the folder itself only rig.json may be replaced (a refined rig written back); its other
  // files (timestamps.csv of a recording, files of other tools) are the capture's.
  if (out.parent_path() == root && out.filename() != "rig.json" && fs::exists(out, ec)) refuse("is a file");
  if (within(out, resolved(dir_ / "ground_truth"))) refuse("lies in the ground truth");
  for (const CameraModel& camera : rig_.cameras) {
    if (within(out, resolved(dir_ / camera.name))) refuse("lies among the frames of camera " + camera.name);
  }
}

void Capture::use_calibration(const Rig& calibrated) {
  // What the frames are checked against must not change: the same cameras and image sizes.
  bool same = calibrated.cameras.size() == rig_.cameras.size() && calibrated.depth_unit_m == rig_.depth_unit_m;
  for (size_t c = 0; same && c < rig_.cameras.size(); ++c) {
    const CameraModel &a = calibrated.cameras[c], &b = rig_.cameras[c];
    same = a.name == b.name && a.depth_intrinsics.width == b.depth_intrinsics.width && a.depth_intrinsics.height == b.depth_intrinsics.height &&
           a.has_color() == b.has_color() &&
           (!a.has_color() || (a.color_intrinsics->width == b.color_intrinsics->width && a.color_intrinsics->height == b.color_intrinsics->height));
  }
  if (!same) throw InvalidInput(dir_.string() + ": a calibration of other cameras or image sizes than rig.json's");
  rig_ = calibrated;
  depth_undistortion_ = depth_undistortion_maps(rig_);
}

std::vector<int> depth_undistortion_map(const Intrinsics& k) {
  std::vector<int> source_pixel(static_cast<size_t>(k.width) * k.height, -1);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const Eigen::Vector2d xy = distort(k, {(u - k.cx) / k.fx, (v - k.cy) / k.fy});
      const double su = std::round(k.fx * xy.x() + k.cx), sv = std::round(k.fy * xy.y() + k.cy);
      if (su >= 0 && sv >= 0 && su < k.width && sv < k.height) source_pixel[static_cast<size_t>(v) * k.width + u] = static_cast<int>(sv) * k.width + static_cast<int>(su);
    }
  }
  return source_pixel;
}

std::vector<std::vector<int>> depth_undistortion_maps(const Rig& rig) {
  std::vector<std::vector<int>> maps;
  for (const CameraModel& camera : rig.cameras) {
    const Intrinsics& k = camera.depth_intrinsics;
    maps.push_back(k.has_distortion && k.distortion != std::array<double, 5>{} ? depth_undistortion_map(k) : std::vector<int>{});
  }
  return maps;
}

DepthImage undistort_depth(DepthImage recorded, const std::vector<std::vector<int>>& maps, int camera) {
  if (camera >= static_cast<int>(maps.size()) || maps[camera].empty()) return recorded;
  DepthImage out;
  undistort_depth_into(recorded, maps[camera], camera, out);
  return out;
}

void undistort_depth_into(const DepthImage& recorded, const std::vector<int>& source_pixel, int camera, DepthImage& out) {
  if (source_pixel.size() != recorded.data.size()) {
    throw InvalidInput("camera " + std::to_string(camera) + ": a depth frame of " + std::to_string(recorded.width) + "x" + std::to_string(recorded.height) +
                       ", but its depth_intrinsics undistort " + std::to_string(source_pixel.size()) + " pixels");
  }
  out.resize_for_overwrite(recorded.width, recorded.height);
  for (int p = 0; p < static_cast<int>(out.data.size()); ++p) out.data[p] = undistorted_depth(recorded.data.data(), source_pixel.data(), p);
}

fs::path Capture::ground_truth_mesh_path(int frame) const {
  return dir_ / "ground_truth" / "mesh" / frame_file_name(frame, ".ply");
}

fs::path Capture::depth_path(int frame, int camera) const {
  std::string path;
  frame_file_path(frame_folders_.at(camera).depth, frame, ".png", path);
  return path;
}

fs::path Capture::color_path(int frame, int camera) const {
  const ColorFile file = color_file_.at(camera).at(frame);
  if (file == ColorFile::kNone) return {};
  std::string path;
  frame_file_path(frame_folders_[camera].color, frame, extension_of(file), path);
  return path;
}

CameraFrame Capture::load_camera_frame(int frame, int camera) const {
  CameraFrame out;
  CameraFrameScratch scratch;
  load_camera_frame(frame, camera, out, scratch);
  return out;
}

CameraFrame Capture::load_camera_depth(int frame, int camera) const {
  CameraFrame out;
  CameraFrameScratch scratch;
  load_camera_frame(frame, camera, out, scratch, false);
  return out;
}

void Capture::load_camera_frame(int frame, int camera, CameraFrame& out, CameraFrameScratch& scratch, bool with_color) const {
  assert(frame >= 0 && frame < frame_count() && camera >= 0 && camera < camera_count());
  const CameraModel& model = rig_.cameras[camera];
  // What an earlier frame left in `out` goes. An image is emptied only where it is left out (its
  // buffer kept): one decoded is written whole, and growing an emptied one would clear it first.
  out.has_depth = out.has_color = false;
  out.unreadable.clear();
  // A file that is there but whose bytes cannot be read or decoded is left out as a missing one
  // is, its reason (which names it) kept for the caller to report; strict, the error goes up. A
  // decoded image of another size or bit depth than rig.json's breaks the capture's contract and
  // is an error either way.
  auto decode_or_leave_out = [&](auto&& decode) {
    if (options_.strict) {
      decode();
      return true;
    }
    std::optional<std::string> reason = undecodable_reason(decode);
    if (reason) out.unreadable.push_back(std::move(*reason));
    return !reason;
  };
  std::string& file = scratch.path;
  frame_file_path(frame_folders_[camera].depth, frame, ".png", file);
  if (frame_file_present(file)) {
    const std::vector<int>* undistortion = camera < static_cast<int>(depth_undistortion_.size()) && !depth_undistortion_[camera].empty()
                                               ? &depth_undistortion_[camera]
                                               : nullptr;
    DepthImage& decoded = undistortion != nullptr ? scratch.recorded : out.depth;
    out.has_depth = decode_or_leave_out([&] {
      scratch.decoder.read_depth_png(file, decoded);
      check_size(file, decoded.width, decoded.height, model.depth_intrinsics, "depth_intrinsics");
      if (undistortion != nullptr) undistort_depth_into(scratch.recorded, *undistortion, camera, out.depth);
    });
  } else if (options_.strict) {
    throw InvalidInput(file + ": missing frame");
  }
  if (!out.has_depth) leave_out(out.depth, model.depth_intrinsics);  // missing, or half decoded
  if (with_color && model.has_color()) {
    const ColorFile kind = color_file_.at(camera).at(frame);
    if (kind != ColorFile::kNone) frame_file_path(frame_folders_[camera].color, frame, extension_of(kind), file);
    if (kind != ColorFile::kNone && frame_file_present(file)) {
      out.has_color = decode_or_leave_out([&] {
        scratch.decoder.read_color_image(file, out.color);
        check_size(file, out.color.width, out.color.height, *model.color_intrinsics, "color_intrinsics");
      });
    } else if (options_.strict) {
      frame_file_path(frame_folders_[camera].color, frame, ".jpg", file);  // no file of either kind: named as the usual one
      throw InvalidInput(file + ": missing frame");
    }
  }
  if (!out.has_color) leave_out(out.color, model.has_color() ? *model.color_intrinsics : Intrinsics{});
}

std::vector<std::string> unreadable_files(const FrameSet& set) {
  std::vector<std::string> files;
  for (const CameraFrame& camera : set.cameras) files.insert(files.end(), camera.unreadable.begin(), camera.unreadable.end());
  return files;
}

FrameSetReader::FrameSetReader(const Capture& capture) : capture_(capture), scratch_(capture.camera_count()) {}

void FrameSetReader::read(int frame, FrameSet& set) {
  set.index = frame;
  set.capture_time_ms = 0;
  set.cameras.resize(capture_.camera_count());
  parallel_for(0, capture_.camera_count(), [&](int c) { capture_.load_camera_frame(frame, c, set.cameras[c], scratch_[c]); });
}

FrameSet Capture::load_frame(int frame) const {
  FrameSet set;
  set.index = frame;
  set.cameras.reserve(rig_.cameras.size());
  for (int c = 0; c < camera_count(); ++c) set.cameras.push_back(load_camera_frame(frame, c));
  return set;
}

}  // namespace zipfusion
