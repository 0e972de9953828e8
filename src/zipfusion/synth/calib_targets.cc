#include "zipfusion/synth/calib_targets.h"


#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <numbers>
#include <random>
#include <sstream>
#include <system_error>

#include "zipfusion/core/calibration_targets.h"
#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/image_io.h"
#include "zipfusion/synth/kinect_model.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = std::numbers::pi;

// Random streams of hash_uniform/hash_normal, one per effect.
enum Stream : std::uint64_t {
  kJitter = 110, kOcclusion = 120, kReflection = 130, kLamp = 140,
};

std::uint64_t view_index(int frame, int camera) { return static_cast<std::uint64_t>(frame) * 4096 + camera; }

// Adds a round spot of colour `rgb` (peak gain, may exceed 255: a saturated core) with Gaussian
// falloff σ pixels at (u, v).
void add_spot(Image<Eigen::Vector3f>& image, double u, double v, double sigma, const Eigen::Vector3f& rgb) {
  const int reach = static_cast<int>(std::ceil(3.5 * sigma));
  const int u0 = std::max(0, static_cast<int>(std::floor(u)) - reach), u1 = std::min(image.width - 1, static_cast<int>(std::ceil(u)) + reach);
  const int v0 = std::max(0, static_cast<int>(std::floor(v)) - reach), v1 = std::min(image.height - 1, static_cast<int>(std::ceil(v)) + reach);
  for (int y = v0; y <= v1; ++y) {
    for (int x = u0; x <= u1; ++x) {
      const double d2 = (x - u) * (x - u) + (y - v) * (y - v);
      image(x, y) += rgb * static_cast<float>(std::exp(-d2 / (2 * sigma * sigma)));
    }
  }
}

// Sensor noise: one 64-bit hash per pixel picks three entries of a table of standard normals
// (drawn once), ten times cheaper than Box-Muller per channel; the table's 2^16 values are plenty
// for noise that only has to look like noise.
const std::vector<float>& normal_table() {
  static const std::vector<float> table = [] {
    std::vector<float> t(1 << 16);
    for (size_t i = 0; i < t.size(); ++i) t[i] = static_cast<float>(hash_normal(0x6e6f697365ULL, i, 0));
    return t;
  }();
  return table;
}

inline std::uint64_t mix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

ColorImage to_color(const Image<Eigen::Vector3f>& linear, double noise_sigma, std::uint64_t seed) {
  const std::vector<float>& normal = normal_table();
  const float sigma = static_cast<float>(noise_sigma);
  ColorImage out(linear.width, linear.height);
  for (size_t i = 0; i < linear.data.size(); ++i) {
    const std::uint64_t h = mix64(seed ^ (i * 0xd1b54a32d192ed03ULL));
    auto level = [&](float value, int channel) {
      const float noisy = value + sigma * normal[(h >> (16 * channel)) & 0xffff];
      return static_cast<unsigned char>(std::clamp(std::lround(noisy), 0L, 255L));
    };
    out.data[i] = {level(linear.data[i].x(), 0), level(linear.data[i].y(), 1), level(linear.data[i].z(), 2)};
  }
  return out;
}

}  // namespace

void WandOptions::validate() const {
  auto fail = [](const std::string& field, const std::string& problem) { throw InvalidInput(field + ": " + problem); };
  if (frames < 2 || frames > kMostFrames) fail("--frames", "must be in [2, " + std::to_string(kMostFrames) + "] (six-digit frame files)");
  if (!(led_distance_m > kShortestWandM && led_distance_m < kLongestWandM)) {
    fail("--led-distance", wand_distance_rule());
  }
  if (!(led_jitter_px >= 0 && led_jitter_px < 10)) fail("--led-jitter", "must be in [0, 10) pixels");
  if (!(led_glow_radius_m > 0 && led_glow_radius_m < 0.1)) fail("led_glow_radius_m", "must be in (0, 0.1) metres");
  if (!(occlusion_probability >= 0 && occlusion_probability < 1)) fail("occlusion_probability", "must be in [0, 1)");
  if (!(reflection_probability >= 0 && reflection_probability < 1)) fail("reflection_probability", "must be in [0, 1)");
  if (lamps < 0 || lamps > 100) fail("lamps", "must be in [0, 100]");
  if (!(background_level >= 0 && background_level < 100)) fail("background_level", "must be in [0, 100) levels");
  if (!(color_noise_sigma >= 0 && color_noise_sigma < 50)) fail("--color-noise", "must be in [0, 50) levels");
}

WandSequence make_wand_sequence(const Box3d& volume, const WandOptions& options) {
  std::mt19937_64 rng(options.seed ^ 0x3a7d11edULL);
  std::uniform_real_distribution<double> phase(0, 2 * kPi);
  const double px = phase(rng), py = phase(rng), pz = phase(rng), pa = phase(rng), pe = phase(rng);
  Eigen::Vector3d lo = volume.min + Eigen::Vector3d(0.3, 0.3, 0.0), hi = volume.max - Eigen::Vector3d::Constant(0.3);
  lo.z() = std::max(lo.z(), 0.4);  // a wand is not waved on the floor
  const Eigen::Vector3d centre = (lo + hi) / 2, half = ((hi - lo) / 2).cwiseMax(0.05);
  WandSequence seq;
  for (int f = 0; f < options.frames; ++f) {
    // Incommensurate frequencies: the centre sweeps the volume rather than repeating a loop.
    const double t = 2 * kPi * f / options.frames;
    const Eigen::Vector3d mid = centre + half.cwiseProduct(Eigen::Vector3d(std::sin(3 * t + px), std::sin(4.3 * t + py), std::sin(2.2 * t + pz)));
    const double azimuth = 5.1 * t + pa, elevation = 0.9 * std::sin(3.7 * t + pe);
    const Eigen::Vector3d dir(std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
    seq.red.push_back(mid + 0.5 * options.led_distance_m * dir);
    seq.green.push_back(mid - 0.5 * options.led_distance_m * dir);
  }
  return seq;
}

ColorImage render_wand_view(const Intrinsics& k, const Rigid3d& color_from_world, const WandSequence& sequence, int frame,
                            int camera, const WandOptions& options) {
  assert(frame >= 0 && frame < static_cast<int>(sequence.red.size()));
  const std::uint64_t seed = options.seed * 0x9e3779b97f4a7c15ULL;
  const std::uint64_t index = view_index(frame, camera);
  const float bg = static_cast<float>(options.background_level);
  Image<Eigen::Vector3f> image(k.width, k.height, Eigen::Vector3f(bg, bg * 1.05f, bg * 1.15f));

  // Static distractors, the same in every frame of a camera: white lamps and yellow spots (bright
  // in several channels) and a red poster (red, but far larger than an LED).
  for (int i = 0; i < options.lamps; ++i) {
    const std::uint64_t lamp = static_cast<std::uint64_t>(camera) * 1000 + i;
    // Kept 50 px inside the image: a poster cut by the image border would be LED-sized.
    const double u = 5 + hash_uniform(seed, lamp, kLamp) * (k.width - 55), v = 5 + hash_uniform(seed, lamp, kLamp + 1) * (k.height - 40);
    const int kind = i % 3;
    if (kind == 0) add_spot(image, u, v, 2.5, {420, 410, 390});  // white lamp, saturated
    if (kind == 1) add_spot(image, u, v, 2.0, {300, 240, 60});   // yellow indicator
    if (kind == 2) {
      for (int y = std::max(0, static_cast<int>(v)); y < std::min(k.height, static_cast<int>(v) + 30); ++y) {
        for (int x = std::max(0, static_cast<int>(u)); x < std::min(k.width, static_cast<int>(u) + 45); ++x) {
          image(x, y) = {170, 35, 30};
        }
      }
    }
  }

  const double glow = options.led_glow_radius_m * k.fx;
  auto draw_led = [&](const Eigen::Vector3d& world, int led, const Eigen::Vector3f& rgb) {
    if (hash_uniform(seed, index, kOcclusion + led) < options.occlusion_probability) return;
    const Eigen::Vector3d p = color_from_world * world;
    if (p.z() < 0.1) return;
    const Eigen::Vector2d pixel = project(k, p) + options.led_jitter_px * Eigen::Vector2d(hash_normal(seed, index, kJitter + 2 * led),
                                                                                          hash_normal(seed, index, kJitter + 2 * led + 1));
    add_spot(image, pixel.x(), pixel.y(), std::max(1.2, glow / p.z()), rgb);
  };
  draw_led(sequence.red[frame], 0, {420, 70, 50});
  draw_led(sequence.green[frame], 1, {60, 420, 110});

  // A reflection of one LED on a shiny surface: as LED-like as the LED itself, so that frame is
  // ambiguous for this camera and must be skipped.
  if (hash_uniform(seed, index, kReflection) < options.reflection_probability) {
    const double u = hash_uniform(seed, index, kReflection + 1) * k.width, v = hash_uniform(seed, index, kReflection + 2) * k.height;
    const bool red = hash_uniform(seed, index, kReflection + 3) < 0.5;
    add_spot(image, u, v, 1.8, red ? Eigen::Vector3f(380, 60, 45) : Eigen::Vector3f(55, 380, 100));
  }
  return to_color(image, options.color_noise_sigma, seed ^ index);
}

SynthResult write_wand_capture(const fs::path& out_dir, const SynthOptions& rig_options, const WandOptions& options,
                               const std::function<void(int, int)>& progress) {
  rig_options.validate();
  options.validate();
  check_new_folder(out_dir, "--out");

  SynthResult result;
  result.true_rig = make_ring_rig(rig_options);
  result.true_rig.frame_count = options.frames;
  result.true_rig.volume = samba_capture_volume();
  result.rig = miscalibrate(result.true_rig, rig_options);
  const WandSequence sequence = make_wand_sequence(*result.true_rig.volume, options);

  write_folder_atomic(out_dir, [&](const fs::path& staging) {
    for (const CameraModel& cam : result.rig.cameras) {
      fs::create_directories(staging / cam.name / "depth");
      fs::create_directories(staging / cam.name / "color");
    }
    fs::create_directories(staging / "ground_truth");
    for (int frame = 0; frame < options.frames; ++frame) {
      const TriangleMesh person = subject_mesh(rig_options, frame);
      parallel_for(0, rig_options.cameras, [&](int c) {
        const CameraModel& cam = result.true_rig.cameras[c];
        const Rigid3d color_from_world = cam.color_from_depth * cam.world_from_depth.inverse();
        write_color_image(staging / cam.name / "color" / frame_file_name(frame, ".png"),
                          render_wand_view(*cam.color_intrinsics, color_from_world, sequence, frame, c, options));
        // The depth cameras see the person waving the wand (the wand itself is too thin to be
        // measured) and the floor: what a depth camera records during a real wand capture, and
        // what calibrate checks the wand's scale against (depth_scale.h).
        write_depth_png(staging / cam.name / "depth" / frame_file_name(frame, ".png"),
                        render_depth_view(person, result.true_rig, c, frame, rig_options));
      }, rig_options.num_threads);
      if (progress) progress(frame + 1, options.frames);
    }
    nlohmann::json truth = {{"led_distance_m", options.led_distance_m}, {"red", nlohmann::json::array()}, {"green", nlohmann::json::array()}};
    for (int f = 0; f < options.frames; ++f) {
      truth["red"].push_back({sequence.red[f].x(), sequence.red[f].y(), sequence.red[f].z()});
      truth["green"].push_back({sequence.green[f].x(), sequence.green[f].y(), sequence.green[f].z()});
    }
    write_file_atomic(staging / "ground_truth" / "wand.json", truth.dump() + "\n");
    write_rig(staging / "ground_truth" / "rig.json", result.true_rig);
    write_rig(staging / "rig.json", result.rig);
  });
  return result;
}

void CheckerboardOptions::validate() const {
  auto fail = [](const std::string& field, const std::string& problem) { throw InvalidInput(field + ": " + problem); };
  if (views < 1 || views > 10000) fail("--views", "must be in [1, 10000]");
  if (inner_columns < kFewestBoardCorners || inner_rows < kFewestBoardCorners || inner_columns > kMostBoardCorners || inner_rows > kMostBoardCorners) {
    fail("--board", "needs " + std::to_string(kFewestBoardCorners) + " to " + std::to_string(kMostBoardCorners) + " inner corners each way, got " +
                      std::to_string(inner_columns) + "x" + std::to_string(inner_rows));
  }
  if (!(square_m > 0.001 && square_m < 1)) fail("--square", "must be in (0.001, 1) metres");
  if (intrinsics.width < 64 || intrinsics.height < 48 || !(intrinsics.fx > 0 && intrinsics.fy > 0)) fail("intrinsics", "need a positive size and focal lengths");
  const bool automatic = min_distance_m == 0 && max_distance_m == 0;
  if (!automatic && !(min_distance_m > 0.05 && max_distance_m >= min_distance_m)) fail("min_distance_m, max_distance_m", "need 0.05 < min <= max metres, or both 0");
  if (!(max_tilt_deg >= 0 && max_tilt_deg < 80)) fail("max_tilt_deg", "must be in [0, 80) degrees");
  if (supersampling < 1 || supersampling > 8) fail("supersampling", "must be in [1, 8]");
}

std::vector<CheckerboardView> render_checkerboard_views(const CheckerboardOptions& o) {
  o.validate();
  const Intrinsics& k = o.intrinsics;
  std::mt19937_64 rng(o.seed ^ 0xc4ecb0a2dULL);
  std::uniform_real_distribution<double> unit(0, 1);
  // Board: (columns+1) x (rows+1) squares plus one square of white margin around them.
  const double s = o.square_m;
  const Eigen::Vector3d board_centre(s * (o.inner_columns - 1) / 2, s * (o.inner_rows - 1) / 2, 0);
  auto board_color = [&](double x, double y) -> float {
    const int ix = static_cast<int>(std::floor(x / s)) + 1, iy = static_cast<int>(std::floor(y / s)) + 1;
    if (ix < -1 || iy < -1 || ix > o.inner_columns + 1 || iy > o.inner_rows + 1) return 90.0f;  // grey wall behind
    if (ix < 0 || iy < 0 || ix > o.inner_columns || iy > o.inner_rows) return o.white_margin ? 225.0f : 90.0f;  // margin
    return (ix + iy) % 2 == 0 ? 25.0f : 225.0f;
  };

  // Automatic distances: the board with its margin fills 55 % (nearest) to 29 % (farthest) of
  // the image along its fuller axis, whatever the board's size.
  double min_distance = o.min_distance_m, max_distance = o.max_distance_m;
  if (min_distance == 0 && max_distance == 0) {
    const double filled_at_1m = std::max(s * (o.inner_columns + 3) * k.fx / k.width, s * (o.inner_rows + 3) * k.fy / k.height);
    min_distance = std::max(0.06, filled_at_1m / 0.55);
    max_distance = min_distance * (0.85 / 0.45);
  }
  // A view is drawn until its board lies inside the image; with distances given, it may never.
  const long most_draws = 1000L * o.views;
  long draws = 0;
  std::vector<CheckerboardView> views;
  while (static_cast<int>(views.size()) < o.views) {
    if (++draws > most_draws) {
      std::ostringstream what;
      what << "distance: the board (" << o.inner_columns + 1 << "x" << o.inner_rows + 1 << " squares of " << s << " m) is not inside the image in any of "
           << most_draws << " random views between " << min_distance << " and " << max_distance << " m";
      throw InvalidInput(what.str());
    }
    const double tilt = o.max_tilt_deg * kPi / 180;
    const Eigen::Matrix3d rotation = (Eigen::AngleAxisd((unit(rng) - 0.5) * 0.6, Eigen::Vector3d::UnitZ()) *
                                      Eigen::AngleAxisd((2 * unit(rng) - 1) * tilt, Eigen::Vector3d::UnitY()) *
                                      Eigen::AngleAxisd((2 * unit(rng) - 1) * tilt, Eigen::Vector3d::UnitX())).toRotationMatrix();
    const double z = min_distance + unit(rng) * (max_distance - min_distance);
    const Eigen::Vector3d centre_in_cam((unit(rng) - 0.5) * 0.5 * z * k.width / k.fx, (unit(rng) - 0.5) * 0.5 * z * k.height / k.fy, z);
    Rigid3d cam_from_board = Rigid3d::Identity();
    cam_from_board.linear() = rotation;
    cam_from_board.translation() = centre_in_cam - rotation * board_centre;
    // Keep views whose whole board (margin included) lies inside the image with room to spare.
    bool inside = true;
    for (double bx : {-2 * s, s * o.inner_columns + s}) {
      for (double by : {-2 * s, s * o.inner_rows + s}) {
        const Eigen::Vector3d p = cam_from_board * Eigen::Vector3d(bx, by, 0);
        const Eigen::Vector2d px = project(k, p);
        if (p.z() < 0.05 || px.x() < 10 || px.y() < 10 || px.x() > k.width - 11 || px.y() > k.height - 11) inside = false;
      }
    }
    if (!inside) continue;

    // Per pixel: rays through sub-pixel samples hit the board plane; the average is the pixel.
    const Rigid3d board_from_cam = cam_from_board.inverse();
    const Eigen::Vector3d normal = rotation.col(2);
    const double plane_offset = normal.dot(cam_from_board.translation());
    Image<Eigen::Vector3f> linear(k.width, k.height, Eigen::Vector3f::Zero());
    const int n = o.supersampling;
    parallel_for(0, k.height, [&](int v) {
      for (int u = 0; u < k.width; ++u) {
        float sum = 0;
        for (int sy = 0; sy < n; ++sy) {
          for (int sx = 0; sx < n; ++sx) {
            const double su = u - 0.5 + (sx + 0.5) / n, sv = v - 0.5 + (sy + 0.5) / n;
            const Eigen::Vector3d ray((su - k.cx) / k.fx, (sv - k.cy) / k.fy, 1);
            const double along = plane_offset / normal.dot(ray);
            const Eigen::Vector3d on_board = board_from_cam * (along * ray);
            sum += along > 0 ? board_color(on_board.x(), on_board.y()) : 90.0f;
          }
        }
        linear(u, v) = Eigen::Vector3f::Constant(sum / (n * n));
      }
    }, o.num_threads);
    views.push_back({to_color(linear, o.color_noise_sigma, o.seed * 7919 + views.size()), cam_from_board});
  }
  return views;
}

void write_checkerboard_views(const fs::path& out_dir, const CheckerboardOptions& options) {
  // Options and folder checked before the rendering, nothing made on disk before it; then written as a whole.
  options.validate();
  check_new_folder(out_dir, "--out");
  const std::vector<CheckerboardView> views = render_checkerboard_views(options);
  write_folder_atomic(out_dir, [&](const fs::path& staging) {
    for (size_t i = 0; i < views.size(); ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "view_%03zu.png", i);
      write_color_image(staging / name, views[i].image);
    }
    const Intrinsics& k = options.intrinsics;
    const nlohmann::json truth = {
        {"intrinsics", {{"width", k.width}, {"height", k.height}, {"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}}},
        {"board", {{"inner_columns", options.inner_columns}, {"inner_rows", options.inner_rows}, {"square_m", options.square_m}}},
        {"views", views.size()}};
    write_file_atomic(staging / "truth.json", truth.dump(2) + "\n");
  });
}

}  // namespace zipfusion
