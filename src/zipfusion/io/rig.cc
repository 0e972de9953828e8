#include "zipfusion/io/rig.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>
#include <sstream>

#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/image_io.h"

namespace zipfusion {
namespace {

using nlohmann::json;

// Reads fields of one JSON object, naming "source: path.to.field" in every error.
class Fields {
 public:
  Fields(const json& object, std::string source, std::string path)
      : object_(object), source_(std::move(source)), path_(std::move(path)) {
    if (!object_.is_object()) fail(path_.empty() ? "top level" : path_, "must be an object");
  }

  [[noreturn]] void fail(const std::string& field, const std::string& problem) const {
    throw InvalidInput(source_ + ": " + field + ": " + problem);
  }
  std::string field(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  bool has(const std::string& key) const { return object_.contains(key); }

  const json& required(const std::string& key) const {
    if (!object_.contains(key)) fail(field(key), "missing required key");
    return object_.at(key);
  }

  double number(const std::string& key) const {
    const json& v = required(key);
    if (!v.is_number()) fail(field(key), "must be a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(field(key), "must be finite");
    return d;
  }
  double positive(const std::string& key) const {
    const double d = number(key);
    if (d <= 0) fail(field(key), "must be positive, got " + quoted(required(key)));
    return d;
  }
  // A positive number inside [lowest, highest]: values outside are no camera's, and would pass
  // through the reconstruction as empty or garbage meshes rather than fail (a focal length of
  // 1e-300 pixels, a depth unit of 1e30 metres).
  double plausible(const std::string& key, double lowest, double highest, const std::string& unit) const {
    const double d = positive(key);
    if (!(d >= lowest && d <= highest)) {
      fail(field(key), "must be in [" + short_number(lowest) + ", " + short_number(highest) + "] " + unit + ", got " + quoted(required(key)));
    }
    return d;
  }
  // A value from the file as a message quotes it: JSON text, cut and escaped (printable_excerpt).
  static std::string quoted(const json& v) { return printable_excerpt(v.dump(), 80); }
  static std::string short_number(double d) {
    char text[32];
    std::snprintf(text, sizeof text, "%g", d);
    return text;
  }
  // An integer of at least min_value; the field's own upper limit (frames, image sizes) is its
  // caller's to test and to explain. One past long long's range reads as its largest.
  long long integer(const std::string& key, int min_value) const {
    const json& v = required(key);
    // 640.0 is 640: a writer that keeps sizes as floats (Python's w / 2) writes it so.
    const double as_float = v.is_number_float() ? v.get<double>() : 0;
    const bool integral_float = v.is_number_float() && std::isfinite(as_float) && as_float == std::floor(as_float) && std::abs(as_float) <= 1e15;
    if (!v.is_number_integer() && !integral_float) fail(field(key), "must be an integer, got " + quoted(v));
    const long long i = integral_float                                                                                  ? static_cast<long long>(as_float)
                        : v.is_number_unsigned() && v.get<std::uint64_t>() > static_cast<std::uint64_t>(LLONG_MAX) ? LLONG_MAX
                                                                                                                     : v.get<long long>();
    if (i < min_value) fail(field(key), "must be an integer >= " + std::to_string(min_value) + ", got " + quoted(v));
    return i;
  }
  std::string string(const std::string& key) const {
    const json& v = required(key);
    if (!v.is_string()) fail(field(key), "must be a string");
    return v.get<std::string>();
  }
  Fields object(const std::string& key) const { return Fields(required(key), source_, field(key)); }
  const std::string& source() const { return source_; }

  std::vector<double> numbers(const json& v, const std::string& field_name, size_t count) const {
    if (!v.is_array() || v.size() != count) fail(field_name, "must be an array of " + std::to_string(count) + " numbers");
    std::vector<double> out;
    for (const json& e : v) {
      if (!e.is_number() || !std::isfinite(e.get<double>())) fail(field_name, "must hold finite numbers only");
      out.push_back(e.get<double>());
    }
    return out;
  }

 private:
  const json& object_;
  std::string source_;
  std::string path_;
};

void check_distortion_unfolded(const Fields& f, const Intrinsics& k) {
  const double fold = distortion_fold_share(k);
  if (fold > 0) {
    char where[200];
    std::snprintf(where, sizeof where,
                  "folds back inside the image: its radial part (k1 %g, k2 %g, k3 %g) stops growing %.1f %% of the way to the farthest corner",
                  k.distortion[0], k.distortion[1], k.distortion[4], 100.0 * fold);
    f.fail(f.field("distortion"), where);
  }
  if (const auto stretch = distortion_stretch_range(k); !stretch_of_a_lens(stretch)) f.fail(f.field("distortion"), distortion_stretch_problem(stretch));
}

Intrinsics parse_intrinsics(const Fields& f) {
  Intrinsics k;
  const long long width = f.integer("width", 1), height = f.integer("height", 1);
  // A size no camera has would only be found when the first frame is decoded, after what is
  // sized by it (a distortion map of every pixel) has been built.
  if (!plausible_image_size(static_cast<std::uint64_t>(width), static_cast<std::uint64_t>(height))) {
    const bool only_height_too_long = width <= static_cast<long long>(kMostImageSide) && height > static_cast<long long>(kMostImageSide);
    // The sizes as the file writes them: one past long long's range reads here as its largest.
    f.fail(f.field(only_height_too_long ? "height" : "width"), Fields::quoted(f.required("width")) + "x" + Fields::quoted(f.required("height")) +
                                                                " is larger than any camera's image (at most " + std::to_string(kMostImageSide) +
                                                                " pixels a side and 2^26 pixels)");
  }
  k.width = static_cast<int>(width);
  k.height = static_cast<int>(height);
  // Focal lengths from 0.02 to 100 times the image's size: fields of view from about 0.6 to 175
  // degrees, past any pinhole lens. The principal point within an image's size of the image.
  // Bounded by the larger side: a strip sensor (synth allows 4096×24) has one focal length for both.
  const double side = std::max(k.width, k.height);
  const std::string for_image = "pixels for an image of " + std::to_string(k.width) + "x" + std::to_string(k.height);
  k.fx = f.plausible("fx", 0.02 * side, 100.0 * side, for_image);
  k.fy = f.plausible("fy", 0.02 * side, 100.0 * side, for_image);
  k.cx = f.number("cx");
  k.cy = f.number("cy");
  if (!(k.cx >= -k.width && k.cx <= 2.0 * k.width)) f.fail(f.field("cx"), "must be in [-width, 2 width] pixels, got " + Fields::quoted(f.required("cx")));
  if (!(k.cy >= -k.height && k.cy <= 2.0 * k.height)) f.fail(f.field("cy"), "must be in [-height, 2 height] pixels, got " + Fields::quoted(f.required("cy")));
  if (f.has("distortion")) {
    const std::vector<double> d = f.numbers(f.required("distortion"), f.field("distortion"), 5);
    std::copy(d.begin(), d.end(), k.distortion.begin());
    k.has_distortion = true;
    check_distortion_unfolded(f, k);
  }
  return k;
}

Rigid3d parse_rigid(const Fields& parent, const std::string& key) {
  const json& v = parent.required(key);
  const std::string field = parent.field(key);
  if (!v.is_array() || v.size() != 4) parent.fail(field, "must be a 4x4 array of rows");
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    const std::vector<double> row = parent.numbers(v[r], field + "[" + std::to_string(r) + "]", 4);
    for (int c = 0; c < 4; ++c) m(r, c) = row[c];
  }
  if (!is_rigid(m)) {
    parent.fail(field, "is not a rigid transform (rotation must be orthonormal with det +1, last row 0 0 0 1)");
  }
  // Metres: a rig is room-sized; a kilometre is far past any, and 1e300 would overflow the maths.
  if (m.topRightCorner<3, 1>().cwiseAbs().maxCoeff() > kMostWorldM) {
    parent.fail(field, "translation must be within " + std::to_string(static_cast<int>(kMostWorldM)) + " m of the origin on each axis");
  }
  // Exactly orthonormal input is kept bit for bit (exact round trips); rounded input is repaired.
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-12) return Rigid3d(m);
  return nearest_rigid(m);
}

bool is_safe_folder_name(const std::string& name) {
  if (name.empty() || name == "." || name == ".." || name == "ground_truth") return false;
  return name.find_first_of("/\\") == std::string::npos && name.find('\0') == std::string::npos;
}

nlohmann::ordered_json intrinsics_json(const Intrinsics& k) {
  nlohmann::ordered_json j = {{"width", k.width}, {"height", k.height}, {"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}};
  if (k.has_distortion) j["distortion"] = k.distortion;
  return j;
}

std::string matrix_json(const Rigid3d& t) {
  const Eigen::Matrix4d m = t.matrix();
  std::string s = "[";
  for (int r = 0; r < 4; ++r) {
    json row = json::array();
    for (int c = 0; c < 4; ++c) row.push_back(m(r, c));
    s += (r ? ", " : "") + row.dump();
  }
  return s + "]";
}

json parse_json(const std::string& json_text, const std::string& source) {
  try {
    return json::parse(json_text);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number past double's range
    throw InvalidInput(source + ": not valid JSON: " + printable_excerpt(e.what(), 300));  // nlohmann quotes the bytes it last read
  }
}

void check_format(const Fields& top, const char* expected) {
  const std::string format = top.string("format");
  if (format != expected) top.fail("format", "must be \"" + std::string(expected) + "\", got " + Fields::quoted(format));
}

}  // namespace

int Rig::camera_index(const std::string& name) const {
  for (size_t i = 0; i < cameras.size(); ++i) {
    if (cameras[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

Rig parse_rig(const std::string& json_text, const std::string& source) {
  const json root = parse_json(json_text, source);
  const Fields top(root, source, "");
  check_format(top, kRigFormat);

  Rig rig;
  rig.fps = top.plausible("fps", 0.001, 1000, "frames per second");
  const long long frame_count = top.integer("frame_count", 0);
  if (frame_count > kMostFrames) {
    top.fail("frame_count", "must be at most " + std::to_string(kMostFrames) + " (frame files are numbered with six digits), got " +
                                std::to_string(frame_count));
  }
  rig.frame_count = static_cast<int>(frame_count);
  if (top.has("depth_unit_m")) rig.depth_unit_m = top.plausible("depth_unit_m", 1e-6, 1, "metres");
  if (top.has("poses_trusted")) {
    const json& trusted = top.required("poses_trusted");
    if (!trusted.is_boolean()) top.fail("poses_trusted", "must be true or false, got " + Fields::quoted(trusted));
    rig.poses_trusted = trusted.get<bool>();
  }
  if (top.has("volume")) {
    const Fields volume = top.object("volume");
    const std::vector<double> lo = top.numbers(volume.required("min"), "volume.min", 3);
    const std::vector<double> hi = top.numbers(volume.required("max"), "volume.max", 3);
    Box3d box{{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}};
    if (!(box.min.array() < box.max.array()).all()) top.fail("volume", "min must be below max on every axis");
    if (std::max(box.min.cwiseAbs().maxCoeff(), box.max.cwiseAbs().maxCoeff()) > kMostWorldM) {
      top.fail("volume", "must lie within " + std::to_string(static_cast<int>(kMostWorldM)) + " m of the origin on each axis");
    }
    rig.volume = box;
  }

  const json& cameras = top.required("cameras");
  if (!cameras.is_array() || cameras.empty()) top.fail("cameras", "must be a non-empty array");
  std::set<std::string> names;
  for (size_t i = 0; i < cameras.size(); ++i) {
    const Fields cam(cameras[i], source, "cameras[" + std::to_string(i) + "]");
    CameraModel model;
    model.name = cam.string("name");
    if (!is_safe_folder_name(model.name)) cam.fail(cam.field("name"), Fields::quoted(model.name) + " is not a usable folder name");
    if (!names.insert(model.name).second) cam.fail(cam.field("name"), Fields::quoted(model.name) + " is used by two cameras");
    model.depth_intrinsics = parse_intrinsics(cam.object("depth_intrinsics"));
    const bool has_color_intrinsics = cam.has("color_intrinsics");
    if (has_color_intrinsics != cam.has("color_from_depth")) {
      cam.fail(cam.field(has_color_intrinsics ? "color_from_depth" : "color_intrinsics"),
               "missing: color_intrinsics and color_from_depth come together");
    }
    if (has_color_intrinsics) {
      model.color_intrinsics = parse_intrinsics(cam.object("color_intrinsics"));
      model.color_from_depth = parse_rigid(cam, "color_from_depth");
    }
    model.world_from_depth = parse_rigid(cam, "world_from_depth");
    rig.cameras.push_back(std::move(model));
  }
  return rig;
}

Rig read_rig(const std::filesystem::path& path) {
  const std::vector<std::uint8_t> bytes = read_file_bytes(path);
  return parse_rig(std::string(bytes.begin(), bytes.end()), path.string());
}

void check_replaces_only_format(const std::filesystem::path& path, const char* format, std::string_view option) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) return;
  auto refuse = [&](const std::string& what) {
    throw InvalidInput(std::string(option) + ": " + path.string() + " " + what + ", not a \"" + format +
                       "\" file to replace; name a new file, or remove that one first");
  };
  if (!fs::is_regular_file(path, ec)) refuse("is not a plain file");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) refuse("cannot be measured (" + ec.message() + ")");
  if (size == 0) return;  // an empty file (mktemp's) is free
  // A rig of the most cameras is tens of kB: what is far larger (a video) is not read to say so.
  if (size > (std::uintmax_t{64} << 20)) refuse("is over 64 MB");
  std::vector<std::uint8_t> bytes;
  try {
    bytes = read_file_bytes(path);
  } catch (const std::exception&) {
    refuse("cannot be read");
  }
  const json found = json::parse(bytes.begin(), bytes.end(), nullptr, /*allow_exceptions=*/false);
  if (found.is_discarded()) refuse("is there and is not JSON");
  if (!found.is_object()) refuse("is JSON but not an object");
  const auto key = found.find("format");
  if (key == found.end()) refuse("is a JSON file without a \"format\"");
  if (!key->is_string()) refuse("has a \"format\" that is not a string");
  if (key->get<std::string>() != format) refuse("is a \"" + printable_excerpt(key->get<std::string>(), 40) + "\" file");
  // What makes it one: cameras with poses, or an intrinsics object. `info --json` names the rig's
  // format in a report about a capture, whose cameras have no world_from_depth.
  const bool rig = std::string_view(format) == kRigFormat;
  const auto body = found.find(rig ? "cameras" : "intrinsics");
  const bool has_body = body != found.end() && (rig ? body->is_array() && (body->empty() || (body->front().is_object() && body->front().contains("world_from_depth")))
                                                    : body->is_object());
  if (!has_body) refuse(rig ? "has no cameras with world_from_depth (a report about a rig?)" : "has no \"intrinsics\" object");
}

std::string format_rig(const Rig& rig) {
  std::ostringstream out;
  out << "{\n";
  out << "  \"format\": " << json(kRigFormat).dump() << ",\n";
  out << "  \"fps\": " << json(rig.fps).dump() << ",\n";
  out << "  \"frame_count\": " << rig.frame_count << ",\n";
  out << "  \"depth_unit_m\": " << json(rig.depth_unit_m).dump() << ",\n";
  if (rig.poses_trusted) out << "  \"poses_trusted\": true,\n";
  if (rig.volume) {
    const nlohmann::ordered_json volume = {{"min", {rig.volume->min.x(), rig.volume->min.y(), rig.volume->min.z()}},
                         {"max", {rig.volume->max.x(), rig.volume->max.y(), rig.volume->max.z()}}};
    out << "  \"volume\": " << volume.dump() << ",\n";
  }
  out << "  \"cameras\": [\n";
  for (size_t i = 0; i < rig.cameras.size(); ++i) {
    const CameraModel& cam = rig.cameras[i];
    out << "    {\"name\": " << json(cam.name).dump() << ",\n";
    out << "     \"depth_intrinsics\": " << intrinsics_json(cam.depth_intrinsics).dump() << ",\n";
    if (cam.color_intrinsics) {
      out << "     \"color_intrinsics\": " << intrinsics_json(*cam.color_intrinsics).dump() << ",\n";
      out << "     \"color_from_depth\": " << matrix_json(cam.color_from_depth) << ",\n";
    }
    out << "     \"world_from_depth\": " << matrix_json(cam.world_from_depth) << "}";
    out << (i + 1 < rig.cameras.size() ? ",\n" : "\n");
  }
  out << "  ]\n}\n";
  return out.str();
}

void write_rig(const std::filesystem::path& path, const Rig& rig) { write_file_atomic(path, format_rig(rig)); }

Intrinsics parse_intrinsics_file(const std::string& json_text, const std::string& source) {
  const json root = parse_json(json_text, source);
  const Fields top(root, source, "");
  check_format(top, kIntrinsicsFormat);
  return parse_intrinsics(top.object("intrinsics"));
}

Intrinsics read_intrinsics_file(const std::filesystem::path& path) {
  const std::vector<std::uint8_t> bytes = read_file_bytes(path);
  return parse_intrinsics_file(std::string(bytes.begin(), bytes.end()), path.string());
}

std::string format_intrinsics(const Intrinsics& k) { return intrinsics_json(k).dump(); }

std::vector<Rigid3d> world_from_depth_poses(const Rig& rig) {
  std::vector<Rigid3d> poses;
  poses.reserve(rig.cameras.size());
  for (const CameraModel& cam : rig.cameras) poses.push_back(cam.world_from_depth);
  return poses;
}

std::optional<std::pair<int, int>> cameras_sharing_a_pose(const Rig& rig) {
  for (size_t j = 1; j < rig.cameras.size(); ++j) {
    for (size_t i = 0; i < j; ++i) {
      const Rigid3d& a = rig.cameras[i].world_from_depth;
      const Rigid3d& b = rig.cameras[j].world_from_depth;
      if ((a.translation() - b.translation()).norm() <= kSamePoseM && rotation_angle_deg(a.inverse() * b) <= kSamePoseDeg) {
        return std::pair{static_cast<int>(i), static_cast<int>(j)};
      }
    }
  }
  return std::nullopt;
}

std::string shared_pose_problem(const Rig& rig) {
  const auto same = cameras_sharing_a_pose(rig);
  if (!same) return {};
  const auto& [i, j] = *same;
  return "cameras[" + std::to_string(j) + "].world_from_depth: the pose of cameras[" + std::to_string(i) + "] (\"" + rig.cameras[i].name +
         "\" and \"" + rig.cameras[j].name + "\" within 1 cm and 1 degree): the rig is not calibrated; run zipfusion calibrate and pass its "
         "rig.json with --rig";
}

void check_poses_distinct(const Rig& rig, const std::string& source) {
  if (const std::string problem = shared_pose_problem(rig); !problem.empty()) throw InvalidInput(source + ": " + problem);
}

bool world_looks_z_up(const Rig& rig) {
  const size_t n = rig.cameras.size();
  if (n == 0) return false;
  size_t upright_or_overhead = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const CameraModel& cam : rig.cameras) {
    // Columns of the rotation: the image's x (right), y (down) and z (viewing) axes in the world.
    const Eigen::Matrix3d axes = cam.world_from_depth.linear();
    if (axes(2, 1) < -0.5 || axes(2, 2) < -0.7) ++upright_or_overhead;
    mean += cam.world_from_depth.translation() / static_cast<double>(n);
  }
  // A majority, not one: in the first camera's frame the camera facing it looks along −z too.
  if (2 * upright_or_overhead > n) return true;
  if (n < 2) return false;
  // The cameras' positions: a ring's plane, or the line through a pair, is level in a z-up world
  // whatever way each camera is turned about its axis.
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (const CameraModel& cam : rig.cameras) {
    const Eigen::Vector3d d = cam.world_from_depth.translation() - mean;
    spread += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> axes_of(spread);  // eigenvalues ascending
  const Eigen::Vector3d extent = axes_of.eigenvalues();
  if (!(extent(2) > 0)) return false;  // every camera at one place
  if (extent(1) < 0.1 * extent(2)) return std::abs(axes_of.eigenvectors().col(2).z()) < 0.5;  // about a line
  return std::abs(axes_of.eigenvectors().col(0).z()) > std::cos(std::numbers::pi / 6);
}

void take_camera_calibration(CameraModel& camera, const Rig& calibration, int c, const std::string& source, const std::string& owner) {
  const CameraModel& calibrated = calibration.cameras.at(c);
  const std::string field = source + ": cameras[" + std::to_string(c) + "].";
  auto same_size = [&](const Intrinsics& theirs, const Intrinsics& ours, const std::string& key) {
    if (theirs.width != ours.width || theirs.height != ours.height) {
      throw InvalidInput(field + key + ": " + std::to_string(theirs.width) + "x" + std::to_string(theirs.height) + ", but " + owner + " images are " +
                         std::to_string(ours.width) + "x" + std::to_string(ours.height));
    }
  };
  same_size(calibrated.depth_intrinsics, camera.depth_intrinsics, "depth_intrinsics");
  if (calibrated.has_color() != camera.has_color()) {
    throw InvalidInput(field + "color_intrinsics: " + (camera.has_color() ? "missing, but " + owner + " camera has colour" : "given, but " + owner + " camera has no colour"));
  }
  if (camera.has_color()) same_size(*calibrated.color_intrinsics, *camera.color_intrinsics, "color_intrinsics");
  camera.depth_intrinsics = calibrated.depth_intrinsics;
  camera.color_intrinsics = calibrated.color_intrinsics;
  camera.color_from_depth = calibrated.color_from_depth;
  camera.world_from_depth = calibrated.world_from_depth;
}

}  // namespace zipfusion
