#include "zipfusion/synth/synth.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>

#include "zipfusion/core/error.h"
#include "zipfusion/core/folder_test_util.h"
#include "zipfusion/core/mesh_distance.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/mesh_io.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

const fs::path kSamba = fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data" / "samba-4cam";

double median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

struct DepthError {
  std::vector<double> distance_m;   // point to true surface
  std::vector<double> normalized;   // distance / expected sensor sigma at that depth
  int subject_pixels = 0;
};

// Back-projects the depth map with the true pose and measures the distance of every point inside
// the capture volume (the subject, not the floor) to the true mesh.
DepthError depth_error(const DepthImage& depth, const Rig& true_rig, int camera, const TriangleMesh& truth) {
  const CameraModel& cam = true_rig.cameras[camera];
  const MeshDistance distance(truth);
  DepthError out;
  for (int v = 0; v < depth.height; ++v) {
    for (int u = 0; u < depth.width; ++u) {
      if (depth(u, v) == 0) continue;
      const float z = static_cast<float>(depth(u, v) * true_rig.depth_unit_m);
      const Eigen::Vector3d p = cam.world_from_depth * unproject(cam.depth_intrinsics, u, v, z).cast<double>();
      if (!true_rig.volume->contains(p)) continue;
      ++out.subject_pixels;
      const double d = distance.closest(p.cast<float>(), 0.5f).distance;
      const double quantization = kinect_quantization_step_m(z, cam.depth_intrinsics.fx, 0.075, 0.125);
      const double sigma = std::sqrt(std::pow(kinect_axial_sigma_m(z), 2) + quantization * quantization / 12);
      out.distance_m.push_back(d);
      out.normalized.push_back(d / sigma);
    }
  }
  return out;
}

SynthOptions small_options() {
  SynthOptions options;
  options.frames = 2;
  options.cameras = 3;
  options.seed = 7;
  return options;
}

TEST(Synth, RingRigLooksAtTheTarget) {
  SynthOptions options = small_options();
  options.cameras = 6;
  const Rig rig = make_ring_rig(options);
  ASSERT_EQ(rig.cameras.size(), 6u);
  for (const CameraModel& cam : rig.cameras) {
    const Eigen::Vector3d target(0, 0, options.target_height_m);
    const Eigen::Vector2d pixel = project(cam.depth_intrinsics, cam.world_from_depth.inverse() * target);
    EXPECT_NEAR(pixel.x(), cam.depth_intrinsics.cx, 1e-9);
    EXPECT_NEAR(pixel.y(), cam.depth_intrinsics.cy, 1e-9);
    EXPECT_NEAR(cam.world_from_depth.translation().head<2>().norm(), options.radius_m, 1e-12);
    EXPECT_NEAR(cam.world_from_depth.translation().z(), options.camera_height_m, 1e-12);
    // The colour camera is 2.5 cm along the depth camera's +x.
    EXPECT_NEAR((cam.color_from_depth.inverse().translation() - Eigen::Vector3d(0.025, 0, 0)).norm(), 0, 1e-12);
  }
}

TEST(Synth, MiscalibrationMovesEveryPoseButTheFirstByExactlyTheAmount) {
  SynthOptions options = small_options();
  options.cameras = 5;
  options.miscalibrate_deg = 0.5;
  options.miscalibrate_m = 0.01;
  const Rig truth = make_ring_rig(options);
  const Rig perturbed = miscalibrate(truth, options);
  EXPECT_TRUE(perturbed.cameras[0].world_from_depth.isApprox(truth.cameras[0].world_from_depth, 1e-15));
  for (int c = 1; c < 5; ++c) {
    const Rigid3d delta = truth.cameras[c].world_from_depth.inverse() * perturbed.cameras[c].world_from_depth;
    EXPECT_NEAR(rotation_angle_deg(delta), 0.5, 1e-9);
    EXPECT_NEAR((perturbed.cameras[c].world_from_depth.translation() - truth.cameras[c].world_from_depth.translation()).norm(), 0.01, 1e-12);
  }
}

TEST(Synth, IdealDepthLiesOnTheTrueSurface) {
  SynthOptions options = small_options();
  options.noise = KinectNoiseOptions::none();
  const Rig rig = [&] { Rig r = make_ring_rig(options); r.volume = Box3d{{-1, -1, 0.02}, {1, 1, 2.2}}; return r; }();
  const TriangleMesh subject = subject_mesh(options, 0);
  for (int c = 0; c < options.cameras; ++c) {
    const SyntheticView view = render_view(subject, rig, c, 0, options);
    const DepthError error = depth_error(view.depth, rig, c, subject);
    ASSERT_GT(error.subject_pixels, 5000) << "camera " << c << " hardly sees the subject";
    // Only the rounding to whole millimetres remains.
    EXPECT_LT(median(error.distance_m), 0.0005);
    std::vector<double> sorted = error.distance_m;
    std::sort(sorted.begin(), sorted.end());
    EXPECT_LT(sorted[sorted.size() * 99 / 100], 0.0015);
  }
}

TEST(Synth, ResolutionKeepsTheFieldOfViewAndScalesThePixelCount) {
  // The subject covers the same share of the image at every resolution; its pixels scale with
  // the image area, and the depth stays on the true surface.
  SynthOptions options = small_options();
  options.noise = KinectNoiseOptions::none();
  const TriangleMesh subject = subject_mesh(options, 0);
  std::vector<double> subject_pixels;
  for (auto [width, height] : {std::pair{320, 240}, {640, 480}, {1280, 960}}) {
    options.depth_width = width;
    options.depth_height = height;
    Rig rig = make_ring_rig(options);
    rig.volume = Box3d{{-1, -1, 0.02}, {1, 1, 2.2}};
    EXPECT_NEAR(rig.cameras[0].depth_intrinsics.fx / width, 580.0 / 640, 1e-12);
    const SyntheticView view = render_view(subject, rig, 0, 0, options);
    ASSERT_EQ(view.depth.width, width);
    ASSERT_EQ(view.color.height, height);
    const DepthError error = depth_error(view.depth, rig, 0, subject);
    EXPECT_LT(median(error.distance_m), 0.0005) << width;
    subject_pixels.push_back(error.subject_pixels);
  }
  EXPECT_NEAR(subject_pixels[1] / subject_pixels[0], 4.0, 0.2);
  EXPECT_NEAR(subject_pixels[2] / subject_pixels[1], 4.0, 0.2);
}

TEST(Synth, KinectDepthAgreesWithTheTruthWithinTheNoiseModel) {
  SynthOptions options = small_options();
  const Rig rig = [&] { Rig r = make_ring_rig(options); r.volume = Box3d{{-1, -1, 0.02}, {1, 1, 2.2}}; return r; }();
  const TriangleMesh subject = subject_mesh(options, 1);
  SynthOptions ideal = options;
  ideal.noise = KinectNoiseOptions::none();
  for (int c = 0; c < options.cameras; ++c) {
    const DepthError noisy = depth_error(render_view(subject, rig, c, 1, options).depth, rig, c, subject);
    const DepthError clean = depth_error(render_view(subject, rig, c, 1, ideal).depth, rig, c, subject);
    // The distance to the surface is at most the axial error, so a median of |e|/σ below 2 is the
    // model's promise; above 0.3 shows the noise is really there (a Gaussian gives 0.67 axially).
    const double m = median(noisy.normalized);
    std::cout << "camera " << c << ": median |error| " << median(noisy.distance_m) * 1000 << " mm, median |error|/sigma " << m
              << ", subject pixels " << noisy.subject_pixels << " of " << clean.subject_pixels << " without sensor effects\n";
    EXPECT_LT(m, 2.0) << "camera " << c;
    EXPECT_GT(m, 0.3) << "camera " << c;
    // Shadows, edge dropout and holes remove some, but not most, of the subject's pixels.
    EXPECT_LT(noisy.subject_pixels, clean.subject_pixels * 0.98);
    EXPECT_GT(noisy.subject_pixels, clean.subject_pixels * 0.75);
  }
}

TEST(Synth, ProjectorShadowsRemoveDepthBesideOccluders) {
  SynthOptions options = small_options();
  options.noise = KinectNoiseOptions::none();
  SynthOptions shadows = options;
  shadows.noise.projector_shadows = true;
  const Rig rig = make_ring_rig(options);
  const TriangleMesh subject = subject_mesh(options, 0);
  const DepthImage without = render_view(subject, rig, 0, 0, options).depth;
  const DepthImage with = render_view(subject, rig, 0, 0, shadows).depth;
  int lost = 0, gained = 0;
  for (size_t i = 0; i < with.size(); ++i) {
    lost += without.data[i] != 0 && with.data[i] == 0;
    gained += without.data[i] == 0 && with.data[i] != 0;
  }
  EXPECT_EQ(gained, 0);
  EXPECT_GT(lost, 200);  // the floor behind the body, at least
}

TEST(Synth, ColourImageShowsTheSubjectsColours) {
  SynthOptions options = small_options();
  options.noise = KinectNoiseOptions::none();
  options.color_noise_sigma = 0;
  const Rig rig = make_ring_rig(options);
  const TriangleMesh subject = subject_mesh(options, 0);
  for (int c = 0; c < options.cameras; ++c) {
    const SyntheticView view = render_view(subject, rig, c, 0, options);
    const CameraModel& cam = rig.cameras[c];
    std::vector<double> channel_error;
    for (size_t i = 0; i < subject.positions.size(); ++i) {
      const Eigen::Vector3d p_depth = cam.world_from_depth.inverse() * subject.positions[i].cast<double>();
      const Eigen::Vector2d pd = project(cam.depth_intrinsics, p_depth);
      const int u = static_cast<int>(std::lround(pd.x())), v = static_cast<int>(std::lround(pd.y()));
      if (!view.depth.contains(u, v) || view.depth(u, v) == 0) continue;
      if (std::abs(view.depth(u, v) * 0.001 - p_depth.z()) > 0.003) continue;  // hidden from the depth camera
      const Eigen::Vector2d pc = project(*cam.color_intrinsics, cam.color_from_depth * p_depth);
      const int cu = static_cast<int>(std::lround(pc.x())), cv = static_cast<int>(std::lround(pc.y()));
      if (!view.color.contains(cu, cv)) continue;
      const Rgb8 seen = view.color(cu, cv), truth = subject.colors[i];
      channel_error.push_back((std::abs(seen.r - truth.r) + std::abs(seen.g - truth.g) + std::abs(seen.b - truth.b)) / 3.0);
    }
    ASSERT_GT(channel_error.size(), 500u);
    EXPECT_LT(median(channel_error), 8.0) << "camera " << c;
  }
}

class SynthCapture : public FolderTest {
 protected:
  SynthCapture() : FolderTest("zf_synth_test_") {}
};

TEST_F(SynthCapture, WritesALoadableCaptureDeterministically) {
  SynthOptions options = small_options();
  options.miscalibrate_deg = 0.5;
  options.miscalibrate_m = 0.01;
  const SynthResult result = write_synthetic_capture(dir_ / "a", options);
  write_synthetic_capture(dir_ / "b", options);
  SynthOptions other_seed = options;
  other_seed.seed = 8;
  write_synthetic_capture(dir_ / "c", other_seed);

  const Capture capture = Capture::open(dir_ / "a", {.strict = true});
  EXPECT_EQ(capture.frame_count(), 2);
  EXPECT_EQ(capture.camera_count(), 3);
  ASSERT_TRUE(capture.ground_truth_rig().has_value());
  EXPECT_TRUE(capture.rig().volume.has_value());
  const Rigid3d delta = capture.ground_truth_rig()->cameras[2].world_from_depth.inverse() * capture.rig().cameras[2].world_from_depth;
  EXPECT_NEAR(rotation_angle_deg(delta), 0.5, 1e-6);

  const TriangleMesh truth = read_mesh(capture.ground_truth_mesh_path(1));
  const TriangleMesh expected = subject_mesh(options, 1);
  EXPECT_EQ(truth.positions, expected.positions);
  EXPECT_EQ(truth.triangles, expected.triangles);
  EXPECT_EQ(truth.colors, expected.colors);

  for (const std::string file : {"rig.json", "cam1/depth/000001.png", "cam2/color/000000.jpg", "ground_truth/mesh/000001.ply"}) {
    EXPECT_EQ(read_file_bytes(dir_ / "a" / file), read_file_bytes(dir_ / "b" / file)) << file;
  }
  EXPECT_NE(read_file_bytes(dir_ / "a" / "cam1/depth/000001.png"), read_file_bytes(dir_ / "c" / "cam1/depth/000001.png"));
  // Nothing is left behind but the captures themselves.
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++entries;
  EXPECT_EQ(entries, 3);
}

TEST_F(SynthCapture, RefusesToOverwriteAndLeavesNothingOnFailure) {
  SynthOptions options = small_options();
  fs::create_directories(dir_ / "full");
  write_file_atomic(dir_ / "full" / "keep.txt", std::string_view("x"));
  EXPECT_THROW(write_synthetic_capture(dir_ / "full", options), InvalidInput);

  options.subject_pattern = (dir_ / "missing" / "%06d.ply").string();
  EXPECT_THROW(write_synthetic_capture(dir_ / "new", options), IoError);
  EXPECT_FALSE(fs::exists(dir_ / "new"));
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++entries;
  EXPECT_EQ(entries, 1);  // just "full"

  options.subject_pattern = (dir_ / "%s.ply").string();
  EXPECT_THROW(write_synthetic_capture(dir_ / "new", options), InvalidInput);
}

TEST_F(SynthCapture, RendersAMeshSequenceSubject) {
  SynthOptions options = small_options();
  options.frames = 1;
  options.subject_pattern = (kSamba / "ground_truth" / "mesh" / "%06d.ply").string();
  write_synthetic_capture(dir_ / "samba", options);
  const Capture capture = Capture::open(dir_ / "samba");
  const TriangleMesh truth = read_mesh(capture.ground_truth_mesh_path(0));
  const TriangleMesh source = read_mesh(kSamba / "ground_truth" / "mesh" / "000000.ply");
  EXPECT_EQ(truth.positions, source.positions);
  const DepthError error = depth_error(capture.load_camera_frame(0, 0).depth, *capture.ground_truth_rig(), 0, truth);
  EXPECT_GT(error.subject_pixels, 3000);
  EXPECT_LT(median(error.normalized), 2.0);
}

}  // namespace
}  // namespace zipfusion
