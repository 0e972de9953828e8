#include "zipfusion/synth/synth.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <system_error>

#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/image_io.h"
#include "zipfusion/io/mesh_io.h"
#include "zipfusion/core/rasterizer.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

// Kinect v1 geometry (FORMATS.md, samba-4cam): colour camera 2.5 cm along the depth camera's +x.
constexpr double kColorOffsetM = 0.025;
const Rgb8 kBackground{38, 40, 46};

// A frame-number pattern split around its one %d conversion ("dir/%06d.ply").
struct FramePattern {
  std::string prefix, suffix;
  int width = 0;
  bool zero_pad = false;
};

FramePattern parse_frame_pattern(const std::string& pattern) {
  FramePattern parsed;
  bool found = false;
  std::string* out = &parsed.prefix;
  for (size_t i = 0; i < pattern.size(); ++i) {
    if (pattern[i] != '%') {
      *out += pattern[i];
      continue;
    }
    if (i + 1 < pattern.size() && pattern[i + 1] == '%') {
      *out += '%';
      ++i;
      continue;
    }
    if (found) throw InvalidInput("--subject: \"" + pattern + "\" must hold exactly one %d conversion");
    size_t j = i + 1;
    if (j < pattern.size() && pattern[j] == '0') {
      parsed.zero_pad = true;
      ++j;
    }
    while (j < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[j])) && parsed.width < 100) {
      parsed.width = parsed.width * 10 + (pattern[j++] - '0');
    }
    if (j >= pattern.size() || pattern[j] != 'd') {
      throw InvalidInput("--subject: \"" + pattern + "\" must hold a %d conversion such as %06d");
    }
    found = true;
    out = &parsed.suffix;
    i = j;
  }
  if (!found) throw InvalidInput("--subject: \"" + pattern + "\" must hold a %d conversion such as %06d");
  return parsed;
}

std::string format_frame_pattern(const FramePattern& p, int frame) {
  std::string number = std::to_string(frame);
  if (static_cast<int>(number.size()) < p.width) number.insert(0, p.width - number.size(), p.zero_pad ? '0' : ' ');
  return p.prefix + number + p.suffix;
}

// A Kinect v1 camera's intrinsics (focal length at 640×480) for an image of width × height.
Intrinsics kinect_intrinsics(double focal_at_640, int width, int height) {
  const double f = focal_at_640 * width / 640.0;
  return {.width = width, .height = height, .fx = f, .fy = f, .cx = (width - 1) / 2.0, .cy = (height - 1) / 2.0};
}

Eigen::Vector3d random_unit_vector(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  Eigen::Vector3d v;
  do {
    v = {normal(rng), normal(rng), normal(rng)};
  } while (v.norm() < 1e-6);
  return v.normalized();
}

// Seeds for the independent random streams of one (frame, camera).
std::uint64_t view_seed(std::uint64_t seed, int frame, int camera) {
  return seed * 0x9e3779b97f4a7c15ULL + static_cast<std::uint64_t>(frame) * 1024 + static_cast<std::uint64_t>(camera);
}

void add_color_noise(ColorImage& color, double sigma, std::uint64_t seed) {
  if (sigma <= 0) return;
  auto channel = [&](unsigned char c, std::uint64_t index, std::uint64_t stream) {
    const double noisy = c + sigma * hash_normal(seed, index, stream);
    return static_cast<unsigned char>(std::clamp(std::lround(noisy), 0L, 255L));
  };
  for (size_t i = 0; i < color.data.size(); ++i) {
    Rgb8& p = color.data[i];
    p = {channel(p.r, i, 11), channel(p.g, i, 12), channel(p.b, i, 13)};
  }
}

}  // namespace

void SynthOptions::validate() const {
  auto fail = [](const std::string& field, const std::string& problem) { throw InvalidInput(field + ": " + problem); };
  if (frames < 1 || frames > kMostFrames) fail("--frames", "must be in [1, " + std::to_string(kMostFrames) + "] (six-digit frame files)");
  if (!(fps >= 0.001 && fps <= 1000)) fail("--fps", "must be in [0.001, 1000]");  // rig.json's range
  if (cameras < 1 || cameras > 64) fail("--cameras", "must be in [1, 64]");
  if (!(radius_m > 0.5 && radius_m < 20)) fail("--radius", "must be in (0.5, 20) metres");
  if (!(camera_height_m > 0 && camera_height_m < 10)) fail("--height", "must be in (0, 10) metres");
  if (!(target_height_m >= 0 && target_height_m < 10)) fail("--target-height", "must be in [0, 10) metres");
  if (depth_width < 32 || depth_width > 4096 || depth_height < 24 || depth_height > 4096) fail("--resolution", "must be within 32x24 .. 4096x4096");
  if (color_extension != ".jpg" && color_extension != ".png") fail("--color-format", "must be jpg or png");
  if (jpeg_quality < 1 || jpeg_quality > 100) fail("--jpeg-quality", "must be in [1, 100]");
  if (!(color_noise_sigma >= 0 && color_noise_sigma < 100)) fail("--color-noise", "must be in [0, 100) levels");
  if (!(miscalibrate_deg >= 0 && miscalibrate_deg <= 180)) fail("--miscalibrate", "angle must be in [0, 180] degrees");
  if (!(miscalibrate_m >= 0 && miscalibrate_m <= 10)) fail("--miscalibrate", "distance must be in [0, 10] metres");
  if (!subject_pattern.empty()) parse_frame_pattern(subject_pattern);
  human.validate();
  noise.validate();
}

Box3d synthetic_capture_volume(const TriangleMesh& first_subject) {
  Box3d box = samba_capture_volume();
  for (const Eigen::Vector3f& p : first_subject.positions) {
    const Eigen::Vector3d q = p.cast<double>();
    box.min = box.min.cwiseMin(q - Eigen::Vector3d(0.3, 0.3, 0));
    box.max = box.max.cwiseMax(q + Eigen::Vector3d::Constant(0.3));
  }
  box.min.z() = std::max(box.min.z(), kVolumeFloorClearanceM);  // the floor stays outside
  return box;
}

Rig make_ring_rig(const SynthOptions& options) {
  Rig rig;
  rig.fps = options.fps;
  rig.frame_count = options.frames;
  rig.depth_unit_m = 0.001;
  rig.poses_trusted = true;  // the exact poses the views are rendered from
  const Eigen::Vector3d target(0, 0, options.target_height_m);
  Rigid3d color_from_depth = Rigid3d::Identity();
  color_from_depth.translation() = Eigen::Vector3d(-kColorOffsetM, 0, 0);
  for (int k = 0; k < options.cameras; ++k) {
    const double angle = std::numbers::pi / 4 + 2 * std::numbers::pi * k / options.cameras;
    const Eigen::Vector3d eye(options.radius_m * std::cos(angle), options.radius_m * std::sin(angle), options.camera_height_m);
    rig.cameras.push_back({.name = "cam" + std::to_string(k),
                           .depth_intrinsics = kinect_intrinsics(580, options.depth_width, options.depth_height),
                           .color_intrinsics = kinect_intrinsics(525, options.depth_width, options.depth_height),
                           .color_from_depth = color_from_depth,
                           .world_from_depth = look_at(eye, target)});
  }
  return rig;
}

Rig miscalibrate(const Rig& true_rig, const SynthOptions& options) {
  Rig rig = true_rig;
  if (options.miscalibrate_deg == 0 && options.miscalibrate_m == 0) return rig;
  rig.poses_trusted = false;
  std::mt19937_64 rng(options.seed ^ 0x5eed0ca1ULL);
  for (size_t k = 1; k < rig.cameras.size(); ++k) {
    Rigid3d depth_from_perturbed = Rigid3d::Identity();
    depth_from_perturbed.linear() =
        Eigen::AngleAxisd(options.miscalibrate_deg * std::numbers::pi / 180, random_unit_vector(rng)).toRotationMatrix();
    const Eigen::Vector3d shift_in_world = options.miscalibrate_m * random_unit_vector(rng);
    Rigid3d& pose = rig.cameras[k].world_from_depth;
    const Eigen::Vector3d centre = pose.translation();
    pose = pose * depth_from_perturbed;  // rotate about the camera centre
    pose.translation() = centre + shift_in_world;
  }
  return rig;
}

TriangleMesh subject_mesh(const SynthOptions& options, int frame) {
  if (options.subject_pattern.empty()) return make_human(frame / options.fps, options.human);
  const fs::path file = format_frame_pattern(parse_frame_pattern(options.subject_pattern), frame);
  TriangleMesh mesh = read_mesh(file);
  if (mesh.triangles.empty()) throw InvalidInput(file.string() + ": subject mesh has no triangles");
  // The capture volume grows around the subject, and rig.json holds it within kMostWorldM.
  for (const Eigen::Vector3f& p : mesh.positions) {
    if (p.cwiseAbs().maxCoeff() > kMostWorldM - 1) {
      char reach[32];
      std::snprintf(reach, sizeof reach, "%.4g", p.cwiseAbs().maxCoeff());
      throw InvalidInput(file.string() + ": a vertex lies " + reach + " m from the origin; a subject must lie within " +
                         std::to_string(static_cast<int>(kMostWorldM - 1)) + " m of it on each axis (metres, not millimetres?)");
    }
  }
  if (!mesh.has_colors()) mesh.colors.assign(mesh.positions.size(), Rgb8{170, 170, 170});
  return mesh;
}

namespace {

// The subject (and the floor) into a camera's buffers.
void render_scene(const TriangleMesh& subject, const Intrinsics& k, const Rigid3d& cam_from_world, bool with_color, bool floor,
                  RenderBuffers& buffers) {
  buffers.reset(k, with_color, kBackground);
  rasterize_mesh(subject, k, cam_from_world, buffers);
  if (floor) rasterize_floor(k, cam_from_world, buffers);
}

DepthImage render_depth(const TriangleMesh& subject, const Rig& true_rig, int camera, int frame, const SynthOptions& options,
                        RenderBuffers& buffers) {
  const CameraModel& cam = true_rig.cameras.at(camera);
  const Rigid3d depth_from_world = cam.world_from_depth.inverse();
  Image<float> projector_depth;
  if (options.noise.projector_shadows) {
    Rigid3d projector_from_depth = Rigid3d::Identity();
    projector_from_depth.translation() = Eigen::Vector3d(-options.noise.baseline_m, 0, 0);
    render_scene(subject, cam.depth_intrinsics, projector_from_depth * depth_from_world, false, options.floor, buffers);
    projector_depth = std::move(buffers.depth);
  }
  render_scene(subject, cam.depth_intrinsics, depth_from_world, false, options.floor, buffers);
  return simulate_kinect_depth(buffers.depth, projector_depth, cam.depth_intrinsics, options.noise, true_rig.depth_unit_m,
                               view_seed(options.seed, frame, camera));
}

}  // namespace

DepthImage render_depth_view(const TriangleMesh& subject, const Rig& true_rig, int camera, int frame, const SynthOptions& options) {
  RenderBuffers buffers;
  return render_depth(subject, true_rig, camera, frame, options, buffers);
}

SyntheticView render_view(const TriangleMesh& subject, const Rig& true_rig, int camera, int frame,
                          const SynthOptions& options) {
  const CameraModel& cam = true_rig.cameras.at(camera);
  RenderBuffers buffers;
  SyntheticView view;
  view.depth = render_depth(subject, true_rig, camera, frame, options, buffers);
  if (cam.has_color()) {
    render_scene(subject, *cam.color_intrinsics, cam.color_from_depth * cam.world_from_depth.inverse(), true, options.floor, buffers);
    view.color = std::move(buffers.color);
    add_color_noise(view.color, options.color_noise_sigma, view_seed(options.seed, frame, camera));
  }
  return view;
}

SynthResult write_synthetic_capture(const fs::path& out_dir, const SynthOptions& options,
                                    const std::function<void(int, int)>& progress) {
  options.validate();
  check_new_folder(out_dir, "--out");

  SynthResult result;
  result.true_rig = make_ring_rig(options);
  result.rig = miscalibrate(result.true_rig, options);
  const TriangleMesh first_subject = subject_mesh(options, 0);
  result.rig.volume = result.true_rig.volume = synthetic_capture_volume(first_subject);

  write_folder_atomic(out_dir, [&](const fs::path& staging) {
    for (const CameraModel& cam : result.rig.cameras) {
      fs::create_directories(staging / cam.name / "depth");
      fs::create_directories(staging / cam.name / "color");
    }
    fs::create_directories(staging / "ground_truth" / "mesh");
    for (int frame = 0; frame < options.frames; ++frame) {
      const TriangleMesh subject = frame == 0 ? first_subject : subject_mesh(options, frame);
      write_mesh(staging / "ground_truth" / "mesh" / frame_file_name(frame, ".ply"), subject);
      parallel_for(0, options.cameras, [&](int c) {
        const SyntheticView view = render_view(subject, result.true_rig, c, frame, options);
        const std::string& name = result.rig.cameras[c].name;
        write_depth_png(staging / name / "depth" / frame_file_name(frame, ".png"), view.depth);
        write_color_image(staging / name / "color" / frame_file_name(frame, options.color_extension), view.color,
                          options.jpeg_quality);
      }, options.num_threads);
      if (progress) progress(frame + 1, options.frames);
    }
    write_rig(staging / "ground_truth" / "rig.json", result.true_rig);
    write_rig(staging / "rig.json", result.rig);
  });
  return result;
}

}  // namespace zipfusion
