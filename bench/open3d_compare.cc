// zf_open3d_compare: Open3D's TSDF fusion and Poisson reconstruction on a rig capture, side by
// side with zipfusion (issue 6). Open3D is used here only, never in the library or the zipfusion
// binary. Writes one mesh per frame that `zipfusion eval CAPTURE DIR` scores like zipfusion's own.
//
//   zf_open3d_compare CAPTURE --out DIR [--frames A:B] [--voxel 0.01] [--rig RIG.json]
//                     [--tsdf scalable|voxel-block-grid] [--poisson-frame N | --no-poisson]
//                     [--threads T] [--json]
//
// Per frame set: a fresh ScalableTSDFVolume (voxel, sdf_trunc = 4 voxels, colour RGB8) integrates
// every camera's depth and colour with the camera's depth intrinsics and camera_from_world pose,
// then ExtractTriangleMesh. With --tsdf voxel-block-grid, Open3D's tensor TSDF instead
// (BlockGridTsdf below: one grid, cleared for every frame set), the faster of the two here.
// Input is exactly the depth zipfusion starts from: zipfusion's own extract_foreground (0.4–4.5 m
// and the rig's capture volume, per pixel), as float metres. Colour is resampled into the depth
// camera (colour registered to depth through color_from_depth, the colour intrinsics and bilinear
// sampling, as zipfusion's lookup_colors does), since Open3D wants colour pixel-aligned with depth.
//
// Times (steady clock, milliseconds): decode (PNG/JPEG, reported apart), prepare (foreground crop,
// colour alignment and filling Open3D's images: our work, reported apart), integrate (volume
// creation, or the grid's clearing, + Integrate of every camera), extract (ExtractTriangleMesh);
// total = integrate + extract, i.e. Open3D's own work only. Writing (with the crop of triangles
// whose centroid lies outside the volume, the rule `zipfusion eval` uses, and the tensor mesh's
// conversion to a legacy one) is reported apart.
//
// Poisson, on one frame: every camera's foreground pixels back-projected to the world and merged,
// normals by PCA over 30 nearest neighbours (EstimateNormals), each flipped towards the camera
// that saw its point (normals_ms), then CreateFromPointCloudPoisson depth 8 (poisson_ms), written
// to DIR/poisson/NNNNNN.ply so that `zipfusion eval CAPTURE DIR/poisson --frames N` scores it.
//
// Errors as the zipfusion CLI: one line naming the file or option, exit 2 (invalid input),
// 3 (I/O) or 1 (anything else, e.g. Open3D's own errors). Files are written atomically.

#include <omp.h>
#include <sys/resource.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include <open3d/Open3DConfig.h>
#include <open3d/camera/PinholeCameraIntrinsic.h>
#include <open3d/core/EigenConverter.h>
#include <open3d/core/hashmap/HashMap.h>
#include <open3d/geometry/KDTreeSearchParam.h>
#include <open3d/geometry/PointCloud.h>
#include <open3d/geometry/RGBDImage.h>
#include <open3d/geometry/TriangleMesh.h>
#include <open3d/pipelines/integration/ScalableTSDFVolume.h>
#include <open3d/t/geometry/Image.h>
#include <open3d/t/geometry/TriangleMesh.h>
#include <open3d/t/geometry/VoxelBlockGrid.h>
#include <open3d/utility/Logging.h>

#include "cli/frame_range.h"
#include "cli/rig_poses.h"
#include "zipfusion/core/error.h"
#include "zipfusion/core/stopwatch.h"
#include "zipfusion/depth/color_lookup.h"
#include "zipfusion/depth/foreground.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/mesh_io.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;
namespace o3d = open3d;
using Clock = std::chrono::steady_clock;

constexpr double kSdfTruncVoxels = 4;  // sdf_trunc = 4 voxels (Open3D's examples use 4–5)
constexpr int kPoissonDepth = 8;       // issue 6
constexpr int kNormalNeighbours = 30;  // Open3D's default KNN for EstimateNormals

struct Args {
  std::string capture;
  std::string out;
  std::string frames;
  std::string rig;
  double voxel_m = 0.01;
  int poisson_frame = -1;  // -1: the first frame of the range
  bool no_poisson = false;
  int threads = 0;  // 0: all cores
  bool json = false;
  std::string tsdf = "scalable";
};


double peak_rss_mib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // Linux: kilobytes
}

// Median and nearest-rank 95th percentile.
double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  if (p == 50) {
    const size_t n = values.size();
    return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  }
  const size_t rank = static_cast<size_t>(std::ceil(p / 100.0 * values.size()));
  return values[std::max<size_t>(rank, 1) - 1];
}

// Colour of each depth pixel with depth, sampled from the colour image (as lookup_colors), written
// into an 8-bit RGB Open3D image aligned with the depth image. Grey where the colour camera does
// not see the point or the camera has no colour; black where there is no depth (never used).
void align_color(const Image<float>& depth_m, const CameraModel& camera, const CameraFrame& frame, o3d::geometry::Image& out) {
  out.Prepare(depth_m.width, depth_m.height, 3, 1);
  unsigned char* rgb = out.data_.data();
  const bool has_color = frame.has_color && camera.has_color() && !frame.color.empty();
  const Intrinsics& depth_k = camera.depth_intrinsics;
  const Rigid3f color_from_depth = camera.color_from_depth.cast<float>();
  const int count = depth_m.width * depth_m.height;
  for (int i = 0; i < count; ++i) {
    const float z = depth_m.data[i];
    Rgb8 c{0, 0, 0};
    if (z > 0) {
      c = kNoColor;
      if (has_color) {
        const Eigen::Vector3f p_color = color_from_depth * unproject(depth_k, static_cast<float>(i % depth_m.width), static_cast<float>(i / depth_m.width), z);
        if (p_color.z() > 0) {
          const Intrinsics& color_k = *camera.color_intrinsics;
          const Eigen::Vector2f pixel = color_k.has_distortion ? project(color_k, p_color.cast<double>()).cast<float>() : project_pinhole(color_k, p_color);
          c = sample_bilinear(frame.color, pixel.x(), pixel.y());
        }
      }
    }
    rgb[3 * i] = c.r;
    rgb[3 * i + 1] = c.g;
    rgb[3 * i + 2] = c.b;
  }
}

void fill_depth(const Image<float>& depth_m, o3d::geometry::Image& out) {
  out.Prepare(depth_m.width, depth_m.height, 1, 4);
  std::memcpy(out.data_.data(), depth_m.data.data(), depth_m.data.size() * sizeof(float));
}

// Open3D mesh → zipfusion mesh, keeping the triangles whose centroid lies in the volume (the rule
// of `zipfusion eval`) and only the vertices they use.
TriangleMesh to_zipfusion_mesh(const o3d::geometry::TriangleMesh& mesh, const std::optional<Box3d>& volume) {
  TriangleMesh result;
  std::vector<int> remap(mesh.vertices_.size(), -1);
  const bool colors = mesh.HasVertexColors();
  for (const Eigen::Vector3i& t : mesh.triangles_) {
    const Eigen::Vector3d centroid = (mesh.vertices_[t[0]] + mesh.vertices_[t[1]] + mesh.vertices_[t[2]]) / 3.0;
    if (volume && !volume->contains(centroid)) continue;
    Eigen::Vector3i mapped;
    for (int k = 0; k < 3; ++k) {
      int& index = remap[t[k]];
      if (index < 0) {
        index = static_cast<int>(result.positions.size());
        result.positions.push_back(mesh.vertices_[t[k]].cast<float>());
        if (colors) {
          const Eigen::Vector3d c = (mesh.vertex_colors_[t[k]] * 255.0).cwiseMax(0.0).cwiseMin(255.0);
          result.colors.push_back({static_cast<unsigned char>(std::lround(c.x())), static_cast<unsigned char>(std::lround(c.y())),
                                   static_cast<unsigned char>(std::lround(c.z()))});
        }
      }
      mapped[k] = index;
    }
    result.triangles.push_back(mapped);
  }
  return result;
}

// Open3D's tensor TSDF (t::geometry::VoxelBlockGrid on the CPU device), set up once and cleared
// for every frame set: creating a grid zeroes its whole block buffer (190 ms for 1 000 blocks of
// 16³ voxels here), which a live user would pay once, not per frame. So that a cleared grid starts
// from empty voxels, the weights of the blocks a frame set activates are zeroed before it is
// integrated (Open3D does not initialise a reactivated block's voxels). Depth goes in as uint16
// millimetres and colour as uint8, one of the kernel's two input types.
class BlockGridTsdf {
 public:
  // Room for 1 000 blocks at 10 mm (samba-4cam activates about 130), four times as many at 5 mm;
  // the map grows if a frame set needs more.
  BlockGridTsdf(double voxel_m, double sdf_trunc_voxels)
      : grid_({"tsdf", "weight", "color"}, {o3d::core::Float32, o3d::core::Float32, o3d::core::Float32}, {{1}, {1}, {3}}, static_cast<float>(voxel_m),
              kBlockResolution, static_cast<int64_t>(std::ceil(1000 * (0.01 / voxel_m) * (0.01 / voxel_m))), o3d::core::Device("CPU:0")),
        trunc_voxels_(static_cast<float>(sdf_trunc_voxels)) {}

  // Clears the grid and integrates the frame set's cameras (depth from depth_mm, colour uint8 RGB).
  void integrate(const std::vector<o3d::t::geometry::Image>& depth_mm, const std::vector<o3d::t::geometry::Image>& color,
                 const std::vector<o3d::core::Tensor>& intrinsics, const std::vector<o3d::core::Tensor>& camera_from_world,
                 const std::vector<bool>& used) {
    o3d::core::HashMap hash = grid_.GetHashMap();  // shares the grid's map
    hash.Clear();
    // Debian's Open3D 0.16 asserts that a voxel's buffer index is > 0 in ExtractTriangleMesh, which
    // aborts whenever the surface crosses voxel 0 of the block in buffer slot 0 (the condition
    // upstream issue #7535 reports as off by one). A block far from any surface takes that slot.
    hash.Activate(o3d::core::Tensor(std::vector<int>{kFarBlock, kFarBlock, kFarBlock}, {1, 3}, o3d::core::Int32, hash.GetDevice()));
    for (size_t c = 0; c < depth_mm.size(); ++c) {
      if (!used[c]) continue;
      const o3d::core::Tensor blocks = grid_.GetUniqueBlockCoordinates(depth_mm[c], intrinsics[c], camera_from_world[c], kDepthScale, kDepthMax, trunc_voxels_);
      auto [slots, added] = hash.Activate(blocks);
      zero_weights(slots.IndexGet({added}).To(o3d::core::Int64).Contiguous());
      grid_.Integrate(blocks, depth_mm[c], color[c], intrinsics[c], camera_from_world[c], kDepthScale, kDepthMax, trunc_voxels_);
    }
  }

  // Marching cubes over every voxel seen at least once (the legacy volume's rule: weight > 0).
  o3d::t::geometry::TriangleMesh extract() { return grid_.ExtractTriangleMesh(0.5f); }

  int64_t active_blocks() { return grid_.GetHashMap().Size() - 1; }  // without the far block

  static o3d::t::geometry::Image depth_mm(const o3d::geometry::Image& depth_m) {
    return o3d::t::geometry::Image::FromLegacy(depth_m).To(o3d::core::UInt16, false, 1000.0);
  }

 private:
  static constexpr int64_t kBlockResolution = 16;  // Open3D's default
  static constexpr int kFarBlock = 1 << 20;
  static constexpr float kDepthScale = 1000.0f;    // millimetres
  static constexpr float kDepthMax = 5.0f;         // beyond the foreground's 4.5 m

  // Only the weights: a voxel of weight 0 takes the new TSDF and colour as they come (the old ones
  // have weight 0 in the running mean) and extraction skips it until then. Zeroing every
  // attribute gave the same meshes on samba-4cam frames 0–39, and integration 0.2–0.9 ms a frame
  // set slower.
  void zero_weights(const o3d::core::Tensor& slots) {
    const int64_t* slot = slots.GetDataPtr<int64_t>();
    o3d::core::Tensor weights = grid_.GetAttribute("weight");  // {capacity, 16, 16, 16, 1}, a view
    const int64_t block_voxels = weights.NumElements() / weights.GetShape(0);
    float* data = weights.GetDataPtr<float>();
    for (int64_t i = 0; i < slots.GetLength(); ++i) std::fill_n(data + slot[i] * block_voxels, block_voxels, 0.0f);
  }

  o3d::t::geometry::VoxelBlockGrid grid_;
  float trunc_voxels_;
};

struct FrameTimes {
  int frame = 0;
  double decode_ms = 0, prepare_ms = 0, integrate_ms = 0, extract_ms = 0, total_ms = 0, write_ms = 0;
  size_t triangles = 0, vertices = 0;  // as written (inside the volume)
};

struct PoissonResult {
  int frame = 0;
  size_t points = 0;
  double decode_ms = 0, prepare_ms = 0, normals_ms = 0, poisson_ms = 0, write_ms = 0;
  size_t triangles = 0, vertices = 0;
  fs::path file;
};

PoissonResult run_poisson(const Capture& capture, const Rig& rig, int frame, const ForegroundOptions& foreground, int threads,
                          const fs::path& dir) {
  PoissonResult result;
  result.frame = frame;
  Clock::time_point start = Clock::now();
  const FrameSet set = capture.load_frame(frame);
  result.decode_ms = ms_since(start);

  start = Clock::now();
  o3d::geometry::PointCloud cloud;
  std::vector<Eigen::Vector3d> centres;  // camera centre of each point, for orientation
  Image<float> depth_m;
  o3d::geometry::Image color;
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    if (!set.cameras[c].has_depth) continue;
    const CameraModel& camera = rig.cameras[c];
    extract_foreground(set.cameras[c].depth, rig.depth_unit_m, camera, rig.volume, foreground, depth_m);
    align_color(depth_m, camera, set.cameras[c], color);
    const Eigen::Vector3d centre = camera.world_from_depth.translation();
    for (int i = 0; i < depth_m.width * depth_m.height; ++i) {
      const float z = depth_m.data[i];
      if (z <= 0) continue;
      const Eigen::Vector3f p = unproject(camera.depth_intrinsics, static_cast<float>(i % depth_m.width), static_cast<float>(i / depth_m.width), z);
      cloud.points_.push_back(camera.world_from_depth * p.cast<double>());
      cloud.colors_.emplace_back(color.data_[3 * i] / 255.0, color.data_[3 * i + 1] / 255.0, color.data_[3 * i + 2] / 255.0);
      centres.push_back(centre);
    }
  }
  result.prepare_ms = ms_since(start);
  result.points = cloud.points_.size();
  if (cloud.points_.size() < 4) throw InvalidInput(capture.dir().string() + ": frame " + std::to_string(frame) + ": too few foreground points for Poisson");

  start = Clock::now();
  cloud.EstimateNormals(o3d::geometry::KDTreeSearchParamKNN(kNormalNeighbours));
  for (size_t i = 0; i < cloud.points_.size(); ++i) {
    if (cloud.normals_[i].dot(centres[i] - cloud.points_[i]) < 0) cloud.normals_[i] = -cloud.normals_[i];
  }
  result.normals_ms = ms_since(start);

  start = Clock::now();
  auto [mesh, densities] = o3d::geometry::TriangleMesh::CreateFromPointCloudPoisson(cloud, kPoissonDepth, 0.0f, 1.1f, false, threads > 0 ? threads : -1);
  result.poisson_ms = ms_since(start);

  start = Clock::now();
  const TriangleMesh out = to_zipfusion_mesh(*mesh, rig.volume);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (!fs::is_directory(dir, ec)) throw IoError(dir.string() + ": cannot create output folder");
  result.file = dir / frame_file_name(frame, ".ply");
  write_mesh(result.file, out);
  result.write_ms = ms_since(start);
  result.triangles = out.triangle_count();
  result.vertices = out.vertex_count();
  return result;
}

void run(const Args& args) {
  if (!(std::isfinite(args.voxel_m) && args.voxel_m > 0 && args.voxel_m <= 0.5)) {
    char text[64];
    std::snprintf(text, sizeof text, "%g", args.voxel_m);
    throw InvalidInput(std::string("--voxel: must be in (0, 0.5] metres, got ") + text);
  }
  if (args.tsdf != "scalable" && args.tsdf != "voxel-block-grid") throw InvalidInput("--tsdf: must be scalable or voxel-block-grid, got " + args.tsdf);
  if (args.threads < 0) throw InvalidInput("--threads: must be >= 0, got " + std::to_string(args.threads));
  if (args.threads > 0) omp_set_num_threads(args.threads);
  const int threads = args.threads > 0 ? args.threads : omp_get_max_threads();
  // Open3D logs to standard output: with --json only its errors (which also throw) may appear.
  o3d::utility::SetVerbosityLevel(args.json ? o3d::utility::VerbosityLevel::Error : o3d::utility::VerbosityLevel::Warning);

  Capture capture = Capture::open(args.capture);
  const Rig rig = args.rig.empty() ? capture.rig() : cli::use_calibration_from(capture, args.rig);
  const cli::FrameRange range = cli::parse_frame_range(args.frames, capture.frame_count());
  const int poisson_frame = args.poisson_frame < 0 ? range.begin : args.poisson_frame;
  if (!args.no_poisson && poisson_frame >= capture.frame_count()) {
    throw InvalidInput("--poisson-frame: " + std::to_string(poisson_frame) + " is not a frame of a capture with " + std::to_string(capture.frame_count()) +
                       " frames");
  }
  const ForegroundOptions foreground;  // zipfusion's defaults: 0.4–4.5 m, crop to the volume
  const double sdf_trunc_m = kSdfTruncVoxels * args.voxel_m;

  const fs::path out_dir = args.out;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (!fs::is_directory(out_dir, ec)) throw IoError(out_dir.string() + ": cannot create output folder");

  std::vector<FrameTimes> frames;
  Image<float> depth_m;
  std::vector<o3d::geometry::RGBDImage> rgbd(rig.cameras.size());
  std::vector<o3d::camera::PinholeCameraIntrinsic> intrinsics;
  std::vector<Eigen::Matrix4d> camera_from_world;
  for (const CameraModel& camera : rig.cameras) {
    const Intrinsics& k = camera.depth_intrinsics;
    intrinsics.emplace_back(k.width, k.height, k.fx, k.fy, k.cx, k.cy);
    camera_from_world.push_back(camera.world_from_depth.inverse().matrix());
  }
  std::optional<BlockGridTsdf> block_grid;
  std::vector<o3d::core::Tensor> intrinsic_tensors, camera_from_world_tensors;
  std::vector<double> active_blocks;
  if (args.tsdf == "voxel-block-grid") {
    block_grid.emplace(args.voxel_m, kSdfTruncVoxels);
    for (size_t c = 0; c < rig.cameras.size(); ++c) {
      intrinsic_tensors.push_back(o3d::core::eigen_converter::EigenMatrixToTensor(intrinsics[c].intrinsic_matrix_));
      camera_from_world_tensors.push_back(o3d::core::eigen_converter::EigenMatrixToTensor(camera_from_world[c]));
    }
  }
  for (int frame = range.begin; frame < range.end; ++frame) {
    FrameTimes t;
    t.frame = frame;
    Clock::time_point start = Clock::now();
    const FrameSet set = capture.load_frame(frame);
    t.decode_ms = ms_since(start);

    start = Clock::now();
    std::vector<bool> used(rig.cameras.size(), false);
    for (size_t c = 0; c < rig.cameras.size(); ++c) {
      if (!set.cameras[c].has_depth) continue;
      used[c] = true;
      extract_foreground(set.cameras[c].depth, rig.depth_unit_m, rig.cameras[c], rig.volume, foreground, depth_m);
      fill_depth(depth_m, rgbd[c].depth_);
      align_color(depth_m, rig.cameras[c], set.cameras[c], rgbd[c].color_);
    }
    t.prepare_ms = ms_since(start);

    std::shared_ptr<o3d::geometry::TriangleMesh> mesh;
    double convert_ms = 0;
    if (block_grid) {
      start = Clock::now();
      std::vector<o3d::t::geometry::Image> depth_mm, color;
      for (size_t c = 0; c < rig.cameras.size(); ++c) {
        depth_mm.push_back(BlockGridTsdf::depth_mm(rgbd[c].depth_));
        color.push_back(o3d::t::geometry::Image::FromLegacy(rgbd[c].color_));
      }
      t.prepare_ms += ms_since(start);
      start = Clock::now();
      block_grid->integrate(depth_mm, color, intrinsic_tensors, camera_from_world_tensors, used);
      t.integrate_ms = ms_since(start);
      start = Clock::now();
      const o3d::t::geometry::TriangleMesh tensor_mesh = block_grid->extract();
      t.extract_ms = ms_since(start);
      active_blocks.push_back(static_cast<double>(block_grid->active_blocks()));
      // Into the legacy mesh that the writing below takes: a conversion for our writer, timed with it.
      start = Clock::now();
      mesh = std::make_shared<o3d::geometry::TriangleMesh>(tensor_mesh.ToLegacy());
      convert_ms = ms_since(start);
    } else {
      start = Clock::now();
      o3d::pipelines::integration::ScalableTSDFVolume volume(args.voxel_m, sdf_trunc_m, o3d::pipelines::integration::TSDFVolumeColorType::RGB8);
      for (size_t c = 0; c < rig.cameras.size(); ++c) {
        if (used[c]) volume.Integrate(rgbd[c], intrinsics[c], camera_from_world[c]);
      }
      t.integrate_ms = ms_since(start);
      start = Clock::now();
      mesh = volume.ExtractTriangleMesh();
      t.extract_ms = ms_since(start);
    }
    t.total_ms = t.integrate_ms + t.extract_ms;

    start = Clock::now();
    const TriangleMesh out = to_zipfusion_mesh(*mesh, rig.volume);
    write_mesh(out_dir / frame_file_name(frame, ".ply"), out);
    t.write_ms = convert_ms + ms_since(start);
    t.triangles = out.triangle_count();
    t.vertices = out.vertex_count();
    frames.push_back(t);
    if (::isatty(STDERR_FILENO)) std::fprintf(stderr, "\rtsdf: %d/%d%s", frame - range.begin + 1, range.end - range.begin, frame + 1 == range.end ? "\n" : "");
  }
  const double tsdf_rss_mib = peak_rss_mib();

  std::optional<PoissonResult> poisson;
  if (!args.no_poisson) poisson = run_poisson(capture, rig, poisson_frame, foreground, args.threads, out_dir / "poisson");

  // Report.
  auto column = [&](double FrameTimes::*field) {
    std::vector<double> v;
    for (const FrameTimes& t : frames) v.push_back(t.*field);
    return v;
  };
  const std::vector<std::pair<const char*, double FrameTimes::*>> fields = {
      {"decode", &FrameTimes::decode_ms},       {"prepare", &FrameTimes::prepare_ms}, {"integrate", &FrameTimes::integrate_ms},
      {"extract", &FrameTimes::extract_ms},     {"total", &FrameTimes::total_ms},     {"write", &FrameTimes::write_ms}};
  nlohmann::ordered_json stages;  // "integrate_ms": {"median": .., "p95": ..}, as `zipfusion bench` reports stages
  for (const auto& [name, field] : fields) {
    stages[std::string(name) + "_ms"] = {{"median", percentile(column(field), 50)}, {"p95", percentile(column(field), 95)}};
  }
  std::vector<double> triangles;
  for (const FrameTimes& t : frames) triangles.push_back(static_cast<double>(t.triangles));

  nlohmann::ordered_json j;
  j["capture"] = args.capture;
  j["rig"] = args.rig.empty() ? (fs::path(args.capture) / "rig.json").string() : args.rig;
  j["out"] = args.out;
  j["frames"] = {range.begin, range.end};
  j["threads"] = threads;
  const char* wait_policy = std::getenv("OMP_WAIT_POLICY");
  j["omp_wait_policy"] = wait_policy ? wait_policy : "default";
  j["open3d_version"] = OPEN3D_VERSION;
  const char* volume_name = block_grid ? "VoxelBlockGrid" : "ScalableTSDFVolume";
  j["tsdf"] = {{"volume", volume_name},
               {"voxel_m", args.voxel_m},
               {"sdf_trunc_m", sdf_trunc_m},
               {"color", "RGB8"},
               {"input", "zipfusion extract_foreground (0.4-4.5 m, capture volume per pixel), colour resampled into the depth camera"},
               {"total_is", "integrate + extract (decode, prepare and write apart)"},
               {"median_triangles", percentile(triangles, 50)},
               {"peak_rss_mib", tsdf_rss_mib}};
  if (block_grid) j["tsdf"]["median_active_blocks"] = percentile(active_blocks, 50);
  j["tsdf"].update(stages);
  nlohmann::ordered_json per_frame = nlohmann::json::array();
  for (const FrameTimes& t : frames) {
    per_frame.push_back({{"frame", t.frame},
                         {"triangles", t.triangles},
                         {"vertices", t.vertices},
                         {"ms", {{"decode", t.decode_ms}, {"prepare", t.prepare_ms}, {"integrate", t.integrate_ms}, {"extract", t.extract_ms},
                                 {"total", t.total_ms}, {"write", t.write_ms}}}});
  }
  j["tsdf"]["per_frame"] = per_frame;
  if (poisson) {
    j["poisson"] = {{"frame", poisson->frame},
                    {"depth", kPoissonDepth},
                    {"points", poisson->points},
                    {"normals", "EstimateNormals KNN 30, flipped towards the camera that saw the point"},
                    {"ms", {{"decode", poisson->decode_ms}, {"prepare", poisson->prepare_ms}, {"normals", poisson->normals_ms},
                            {"poisson", poisson->poisson_ms}, {"total", poisson->normals_ms + poisson->poisson_ms}, {"write", poisson->write_ms}}},
                    {"triangles", poisson->triangles},
                    {"vertices", poisson->vertices},
                    {"file", poisson->file.string()}};
  }
  j["peak_rss_mib"] = peak_rss_mib();
  write_file_atomic(out_dir / "stats.json", j.dump(2) + "\n");

  if (args.json) {
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::printf("Open3D %s %s, voxel %.1f mm, sdf_trunc %.1f mm, %d threads (OMP_WAIT_POLICY %s), frames %d:%d of %s\n",
              OPEN3D_VERSION, volume_name, args.voxel_m * 1000, sdf_trunc_m * 1000, threads, wait_policy ? wait_policy : "default", range.begin,
              range.end, args.capture.c_str());
  std::printf("%-10s %10s %10s\n", "ms", "median", "p95");
  for (const auto& [name, field] : fields) {
    const nlohmann::ordered_json& stage = stages[std::string(name) + "_ms"];
    std::printf("%-10s %10.1f %10.1f\n", name, stage["median"].get<double>(), stage["p95"].get<double>());
  }
  std::printf("total = integrate + extract; median %.0f triangles per frame; peak RSS %.0f MiB\n", percentile(triangles, 50), tsdf_rss_mib);
  if (poisson) {
    std::printf("Poisson depth %d, frame %d: %zu points, normals %.1f ms, Poisson %.1f ms, %zu triangles -> %s\n", kPoissonDepth, poisson->frame,
                poisson->points, poisson->normals_ms, poisson->poisson_ms, poisson->triangles, poisson->file.string().c_str());
  }
  std::printf("meshes in %s, numbers in %s; peak RSS %.0f MiB\n", out_dir.string().c_str(), (out_dir / "stats.json").string().c_str(), peak_rss_mib());
}

}  // namespace
}  // namespace zipfusion

int main(int argc, char** argv) {
  // libgomp reads OMP_WAIT_POLICY when it loads, before main. Its default spins between parallel
  // regions, and Open3D opens one per volume unit: on a loaded 2-core machine integration then
  // took 0.7–3 s per frame set instead of 60 ms. Unless the caller chose a policy, run again with
  // the passive one, Open3D's best case on a shared machine.
  if (std::getenv("OMP_WAIT_POLICY") == nullptr && ::setenv("OMP_WAIT_POLICY", "PASSIVE", 1) == 0) {
    ::execv("/proc/self/exe", argv);  // returns only on failure: go on with the default policy
    ::unsetenv("OMP_WAIT_POLICY");
  }
  zipfusion::Args args;
  CLI::App app{"Open3D TSDF fusion and Poisson on a rig capture, for side-by-side comparison with zipfusion"};
  app.add_option("capture", args.capture, "Capture folder (with rig.json)")->required();
  app.add_option("--out", args.out, "Output folder: NNNNNN.ply per frame, poisson/NNNNNN.ply, stats.json")->required();
  app.add_option("--frames", args.frames, "Frames A:B (A included, B excluded; default all)");
  app.add_option("--voxel", args.voxel_m, "TSDF voxel size, metres (sdf_trunc = 4 voxels)")->capture_default_str();
  app.add_option("--rig", args.rig, "Take camera poses from this rig.json instead (e.g. CAPTURE/ground_truth/rig.json)");
  app.add_option("--poisson-frame", args.poisson_frame, "Frame for Poisson (default: the first of --frames)");
  app.add_flag("--no-poisson", args.no_poisson, "Skip Poisson");
  app.add_option("--threads", args.threads, "OpenMP threads for Open3D (0 = all cores)")->capture_default_str();
  app.add_option("--tsdf", args.tsdf, "Open3D's TSDF: scalable (the legacy ScalableTSDFVolume) or voxel-block-grid (the tensor VoxelBlockGrid)")
      ->capture_default_str();
  app.add_flag("--json", args.json, "Print the numbers as JSON on standard output");
  try {
    app.parse(argc, argv);
    zipfusion::run(args);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const zipfusion::InvalidInput& e) {
    std::cerr << "zf_open3d_compare: error: " << e.what() << "\n";
    return 2;
  } catch (const zipfusion::IoError& e) {
    std::cerr << "zf_open3d_compare: error: " << e.what() << "\n";
    return 3;
  } catch (const std::exception& e) {
    std::cerr << "zf_open3d_compare: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
