#include "zipfusion/io/rig.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <numbers>
#include <nlohmann/json.hpp>

#include "zipfusion/core/error.h"
#include "zipfusion/core/geometry.h"
#include "zipfusion/core/error_test_util.h"
#include "zipfusion/io/file_util.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

Rig example_rig() {
  Rig rig;
  rig.fps = 30;
  rig.frame_count = 12;
  rig.depth_unit_m = 0.0005;
  rig.volume = Box3d{{-1, -1.5, 0.02}, {1, 1.5, 2.2}};
  CameraModel cam;
  cam.name = "left";
  cam.depth_intrinsics = {.width = 640, .height = 480, .fx = 580.5, .fy = 579.25, .cx = 319.5, .cy = 239.5};
  Intrinsics color{.width = 1280, .height = 960, .fx = 1050.125, .fy = 1050.5, .cx = 639.5, .cy = 479.5};
  color.distortion = {0.12, -0.21, 0.001, -0.0005, 0.07};
  color.has_distortion = true;
  cam.color_intrinsics = color;
  cam.color_from_depth.translation() = Eigen::Vector3d(-0.025, 0.001, 0.0003);
  cam.world_from_depth.linear() = Eigen::AngleAxisd(0.8, Eigen::Vector3d(0.2, -1, 0.3).normalized()).toRotationMatrix();
  cam.world_from_depth.translation() = Eigen::Vector3d(1.2345678901234, -2, 1.3);
  rig.cameras.push_back(cam);
  CameraModel depth_only;
  depth_only.name = "right";
  depth_only.depth_intrinsics = {.width = 320, .height = 240, .fx = 290, .fy = 290, .cx = 160, .cy = 120};
  depth_only.world_from_depth.translation() = Eigen::Vector3d(0, 2, 1);
  rig.cameras.push_back(depth_only);
  return rig;
}

class RigFile : public ::testing::Test {
 protected:
  fs::path dir_ = fs::temp_directory_path() / ("zf_rig_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
                                               ::testing::UnitTest::GetInstance()->current_test_info()->name());
  void SetUp() override { fs::create_directories(dir_); }
  void TearDown() override { fs::remove_all(dir_); }

  // Writes the example rig with `edit` applied to its JSON and returns the error text of reading it.
  std::string error_after(const std::function<void(json&)>& edit) {
    json j = json::parse(format_rig(example_rig()));
    edit(j);
    const fs::path path = dir_ / "rig.json";
    write_file_atomic(path, j.dump(1));
    return invalid_input_message([&] { read_rig(path); });
  }
};

TEST_F(RigFile, RoundTripIsExact) {
  const Rig rig = example_rig();
  write_rig(dir_ / "rig.json", rig);
  const Rig back = read_rig(dir_ / "rig.json");
  EXPECT_EQ(back.fps, rig.fps);
  EXPECT_EQ(back.frame_count, rig.frame_count);
  EXPECT_EQ(back.depth_unit_m, rig.depth_unit_m);
  ASSERT_TRUE(back.volume.has_value());
  EXPECT_EQ(back.volume->min, rig.volume->min);
  EXPECT_EQ(back.volume->max, rig.volume->max);
  ASSERT_EQ(back.cameras.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(back.cameras[i].name, rig.cameras[i].name);
    EXPECT_EQ(back.cameras[i].depth_intrinsics, rig.cameras[i].depth_intrinsics);
    EXPECT_EQ(back.cameras[i].color_intrinsics, rig.cameras[i].color_intrinsics);
    EXPECT_NEAR((back.cameras[i].world_from_depth.matrix() - rig.cameras[i].world_from_depth.matrix()).cwiseAbs().maxCoeff(), 0, 1e-15);
    EXPECT_NEAR((back.cameras[i].color_from_depth.matrix() - rig.cameras[i].color_from_depth.matrix()).cwiseAbs().maxCoeff(), 0, 1e-15);
  }
  EXPECT_FALSE(back.cameras[1].has_color());
  // Writing what was read gives the same bytes.
  EXPECT_EQ(format_rig(back), format_rig(rig));
}

// A whole number written as a float (640.0, as a writer that keeps sizes as floats writes it) is
// that integer; 2.5 is not (EveryMalformedFieldIsNamed).
TEST_F(RigFile, IntegralFloatsAreIntegers) {
  const Rig rig = example_rig();
  json j = json::parse(format_rig(rig));
  j["frame_count"] = static_cast<double>(rig.frame_count);
  j["cameras"][0]["depth_intrinsics"]["width"] = static_cast<double>(rig.cameras[0].depth_intrinsics.width);
  ASSERT_NE(j.dump().find(".0,"), std::string::npos);  // written as floats
  write_file_atomic(dir_ / "rig.json", j.dump());
  const Rig back = read_rig(dir_ / "rig.json");
  EXPECT_EQ(back.frame_count, rig.frame_count);
  EXPECT_EQ(back.cameras[0].depth_intrinsics.width, rig.cameras[0].depth_intrinsics.width);
}

TEST_F(RigFile, UnknownKeysAreIgnoredAndDefaultsApply) {
  const std::string error = error_after([](json& j) {
    j["comment"] = "made by hand";
    j["cameras"][0]["serial"] = "A00362";
    j.erase("depth_unit_m");
    j.erase("volume");
  });
  EXPECT_EQ(error, kNoInvalidInput);
  const Rig rig = read_rig(dir_ / "rig.json");
  EXPECT_EQ(rig.depth_unit_m, 0.001);
  EXPECT_FALSE(rig.volume.has_value());
  EXPECT_FALSE(rig.poses_trusted);  // absent: the poses may be refined
}

TEST_F(RigFile, TrustedPosesRoundTrip) {
  Rig rig = example_rig();
  rig.poses_trusted = true;
  write_rig(dir_ / "rig.json", rig);
  EXPECT_TRUE(read_rig(dir_ / "rig.json").poses_trusted);
  rig.poses_trusted = false;
  write_rig(dir_ / "rig.json", rig);
  EXPECT_FALSE(read_rig(dir_ / "rig.json").poses_trusted);
  EXPECT_EQ(format_rig(rig).find("poses_trusted"), std::string::npos);  // written only when true: other tools' files stay as they were
}

struct BadCase {
  const char* what;
  std::function<void(json&)> edit;
  const char* expected_field;
};

TEST_F(RigFile, EveryMalformedFieldIsNamed) {
  const std::vector<BadCase> cases = {
      {"missing format", [](json& j) { j.erase("format"); }, "format: missing required key"},
      {"wrong format", [](json& j) { j["format"] = "zipfusion.rig/2"; }, "format: must be"},
      {"array at the top", [](json& j) { j = json::array({1, 2}); }, "rig.json: top level: must be an object"},
      {"missing fps", [](json& j) { j.erase("fps"); }, "fps: missing required key"},
      {"zero fps", [](json& j) { j["fps"] = 0; }, "fps: must be positive"},
      {"fractional frame_count", [](json& j) { j["frame_count"] = 2.5; }, "frame_count: must be an integer"},
      {"negative frame_count", [](json& j) { j["frame_count"] = -1; }, "frame_count: must be an integer >= 0"},
      // Past int's range, the field's own limit is named.
      {"frame_count past int", [](json& j) { j["frame_count"] = 2147483648LL; }, "frame_count: must be at most 1000000 (frame files are numbered with six digits), got 2147483648"},
      {"width past int", [](json& j) { j["cameras"][1]["depth_intrinsics"]["width"] = 4000000000LL; }, "cameras[1].depth_intrinsics.width: 4000000000x240 is larger than any camera's image"},
      {"width past long long", [](json& j) { j["cameras"][1]["depth_intrinsics"]["width"] = 18446744073709551615ULL; }, "cameras[1].depth_intrinsics.width: 18446744073709551615x240 is larger than any camera's image"},
      {"more frames than six digits number", [](json& j) { j["frame_count"] = 1000001; },
       "frame_count: must be at most 1000000 (frame files are numbered with six digits), got 1000001"},
      {"string depth unit", [](json& j) { j["depth_unit_m"] = "mm"; }, "depth_unit_m: must be a number"},
      {"numeric trust", [](json& j) { j["poses_trusted"] = 1; }, "poses_trusted: must be true or false"},
      {"inverted volume", [](json& j) { j["volume"]["max"][2] = -5; }, "volume: min must be below max"},
      {"short volume", [](json& j) { j["volume"]["min"] = {1, 2}; }, "volume.min: must be an array of 3 numbers"},
      {"volume beyond the world", [](json& j) { j["volume"]["max"][0] = 3.3e38; }, "volume: must lie within 1000 m of the origin on each axis"},
      {"no cameras", [](json& j) { j["cameras"] = json::array(); }, "cameras: must be a non-empty array"},
      {"missing name", [](json& j) { j["cameras"][1].erase("name"); }, "cameras[1].name: missing required key"},
      {"duplicate name", [](json& j) { j["cameras"][1]["name"] = "left"; }, "cameras[1].name: \"left\" is used by two cameras"},
      {"unsafe name", [](json& j) { j["cameras"][0]["name"] = "../etc"; }, "cameras[0].name: \"../etc\" is not a usable folder name"},
      {"missing intrinsics", [](json& j) { j["cameras"][0].erase("depth_intrinsics"); }, "cameras[0].depth_intrinsics: missing required key"},
      {"negative focal", [](json& j) { j["cameras"][0]["depth_intrinsics"]["fx"] = -580; }, "cameras[0].depth_intrinsics.fx: must be positive"},
      {"zero width", [](json& j) { j["cameras"][1]["depth_intrinsics"]["width"] = 0; }, "cameras[1].depth_intrinsics.width: must be an integer >= 1"},
      {"short distortion", [](json& j) { j["cameras"][0]["color_intrinsics"]["distortion"] = {0.1, 0.2}; },
       "cameras[0].color_intrinsics.distortion: must be an array of 5 numbers"},
      {"folding distortion", [](json& j) { j["cameras"][1]["depth_intrinsics"]["distortion"] = {-1.5, 0, 0, 0, 0}; },
       "cameras[1].depth_intrinsics.distortion: folds back inside the image"},
      // Growing all the way, yet scaling the image's distances by far more than a lens does: the
      // camera's whole image would shrink to a few undistorted pixels.
      {"stretching distortion", [](json& j) { j["cameras"][1]["depth_intrinsics"]["distortion"] = {1e9, 1e9, 0, 0, 1e9}; },
       "cameras[1].depth_intrinsics.distortion: moves points of the image to 1–"},
      {"overflowing distortion", [](json& j) { j["cameras"][0]["color_intrinsics"]["distortion"] = {0, 0, 1e308, -1e308, 0}; },
       "cameras[0].color_intrinsics.distortion: moves points of the image to "},
      {"squeezing tangential distortion", [](json& j) { j["cameras"][0]["depth_intrinsics"]["distortion"] = {0, 0, 3, 0, 0}; },
       "cameras[0].depth_intrinsics.distortion: moves points of the image to "},
      {"colour pose without intrinsics", [](json& j) { j["cameras"][0].erase("color_intrinsics"); },
       "cameras[0].color_intrinsics: missing: color_intrinsics and color_from_depth come together"},
      {"scaled pose", [](json& j) { j["cameras"][0]["world_from_depth"][0][0] = 2.0; }, "cameras[0].world_from_depth: is not a rigid transform"},
      {"mirrored pose", [](json& j) { j["cameras"][1]["world_from_depth"] = {{-1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}}; },
       "cameras[1].world_from_depth: is not a rigid transform"},
      {"projective last row", [](json& j) { j["cameras"][1]["world_from_depth"][3] = {0, 0, 0.1, 1}; },
       "cameras[1].world_from_depth: is not a rigid transform"},
      {"3x3 pose", [](json& j) { j["cameras"][1]["world_from_depth"] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}; },
       "cameras[1].world_from_depth: must be a 4x4 array of rows"},
      {"text in matrix", [](json& j) { j["cameras"][0]["color_from_depth"][1][2] = "0"; },
       "cameras[0].color_from_depth[1]: must hold finite numbers only"},
      // Values no camera has, which would otherwise make empty or garbage meshes without an error.
      {"tiny fps", [](json& j) { j["fps"] = 1e-300; }, "fps: must be in [0.001, 1000] frames per second"},
      {"huge depth unit", [](json& j) { j["depth_unit_m"] = 1e30; }, "depth_unit_m: must be in [1e-06, 1] metres"},
      {"tiny focal", [](json& j) { j["cameras"][1]["depth_intrinsics"]["fx"] = 1e-300; },
       "cameras[1].depth_intrinsics.fx: must be in [6.4, 32000] pixels for an image of 320x240"},
      {"huge focal", [](json& j) { j["cameras"][0]["color_intrinsics"]["fy"] = 1e300; }, "cameras[0].color_intrinsics.fy: must be in"},
      {"far principal point", [](json& j) { j["cameras"][0]["depth_intrinsics"]["cx"] = 5000; }, "cameras[0].depth_intrinsics.cx: must be in"},
      {"far camera", [](json& j) { j["cameras"][1]["world_from_depth"][0][3] = 1e300; },
       "cameras[1].world_from_depth: translation must be within 1000 m"},
      // Found before any frame: a distortion map of 20000×20000 pixels took 3 GB and 12 s.
      {"huge image", [](json& j) { j["cameras"][0]["depth_intrinsics"].update({{"width", 20000}, {"height", 20000}, {"fx", 2000}, {"fy", 2000}}); },
       "cameras[0].depth_intrinsics.width: 20000x20000 is larger than any camera's image (at most 32768 pixels a side and 2^26 pixels)"},
  };
  for (const BadCase& c : cases) {
    const std::string error = error_after(c.edit);
    EXPECT_NE(error.find((dir_ / "rig.json").string()), std::string::npos) << c.what << ": " << error;
    EXPECT_NE(error.find(c.expected_field), std::string::npos) << c.what << ": " << error;
  }
}

TEST_F(RigFile, BrokenJsonAndMissingFileAreReported) {
  // Truncated, and a number past double's range (nlohmann's out_of_range, not a parse_error): the
  // same message.
  for (const std::string_view text : {R"({"format": "zipfusion.rig/1", )", R"({"format": "zipfusion.rig/1", "fps": 1e400})"}) {
    write_file_atomic(dir_ / "rig.json", text);
    const std::string message = invalid_input_message([&] { read_rig(dir_ / "rig.json"); });
    EXPECT_NE(message.find("rig.json: not valid JSON"), std::string::npos) << text << ": " << message;
  }
  EXPECT_THROW(read_rig(dir_ / "absent.json"), IoError);
}

// Two cameras cannot stand in one place: within 1 cm and 1° their poses are a placeholder (a
// capture recorded without --rig has identity poses) or a copied entry; farther apart, they are
// a rig, however close.
TEST(RigPoses, CamerasWithinACentimetreAndADegreeShareAPose) {
  Rig rig;
  for (int c = 0; c < 3; ++c) rig.cameras.push_back({.name = "cam" + std::to_string(c)});
  rig.cameras[1].world_from_depth.translation() = Eigen::Vector3d(1, 0, 0);
  rig.cameras[2].world_from_depth.translation() = Eigen::Vector3d(0, 1, 0);
  EXPECT_FALSE(cameras_sharing_a_pose(rig));
  EXPECT_EQ(shared_pose_problem(rig), "");
  EXPECT_NO_THROW(check_poses_distinct(rig, "rig.json"));

  const auto turned = [](double degrees) { return Rigid3d(Eigen::AngleAxisd(degrees * std::numbers::pi / 180, Eigen::Vector3d(1, 2, 3).normalized())); };
  rig.cameras[2].world_from_depth = rig.cameras[1].world_from_depth * turned(0.9);
  rig.cameras[2].world_from_depth.translation() += Eigen::Vector3d(0.005, 0.005, -0.005);  // 8.7 mm
  EXPECT_EQ(cameras_sharing_a_pose(rig), (std::pair{1, 2}));
  EXPECT_EQ(shared_pose_problem(rig).rfind("cameras[2].world_from_depth: the pose of cameras[1] (\"cam1\" and \"cam2\"", 0), 0u);
  const std::string message = invalid_input_message([&] { check_poses_distinct(rig, "x/rig.json"); });
  EXPECT_EQ(message.rfind("x/rig.json: cameras[2].world_from_depth: ", 0), 0u) << message;
  // 1.1° or 1.1 cm apart: two cameras side by side.
  rig.cameras[2].world_from_depth = rig.cameras[1].world_from_depth * turned(1.1);
  EXPECT_FALSE(cameras_sharing_a_pose(rig));
  rig.cameras[2].world_from_depth = rig.cameras[1].world_from_depth;
  rig.cameras[2].world_from_depth.translation() += Eigen::Vector3d(0, 0.011, 0);
  EXPECT_FALSE(cameras_sharing_a_pose(rig));
  // Every camera at identity, as record writes without --rig: the first two.
  for (CameraModel& camera : rig.cameras) camera.world_from_depth = Rigid3d::Identity();
  EXPECT_EQ(cameras_sharing_a_pose(rig), (std::pair{0, 1}));
}

// The floor lift takes the world to be z-up. A ring of cameras at chest height, or high up and
// tilted down, is; so is a camera overhead, and a ring of cameras turned on their side (portrait)
// or hung upside down, by the ring's level plane; so is a level pair. The same rings in a y-up
// world, or in their first camera's own frame (y down) as other tools write rigs, are not,
// although there the camera facing the first one looks along −z; nor is a facing pair there.
TEST(RigPoses, WorldLooksZUpFromTheCamerasAxesAndPlaces) {
  const auto ring_of = [](int cameras, double height, const Rigid3d& turned = Rigid3d::Identity()) {
    Rig ring;
    for (int c = 0; c < cameras; ++c) {
      const double angle = std::numbers::pi / 4 + c * 2 * std::numbers::pi / cameras;
      const Eigen::Vector3d eye(2.5 * std::cos(angle), 2.5 * std::sin(angle), height);
      ring.cameras.push_back({.name = "cam" + std::to_string(c), .world_from_depth = look_at(eye, Eigen::Vector3d(0, 0, 0.9)) * turned});
    }
    return ring;
  };
  const auto moved = [](Rig rig, const Rigid3d& new_from_old) {
    for (CameraModel& camera : rig.cameras) camera.world_from_depth = new_from_old * camera.world_from_depth;
    return rig;
  };
  const Rigid3d to_y_up(Eigen::AngleAxisd(-std::numbers::pi / 2, Eigen::Vector3d::UnitX()));  // (x, y, z) → (x, z, −y)
  ASSERT_TRUE((to_y_up * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitY()));
  const Rigid3d portrait(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()));  // about the viewing axis
  const Rigid3d upside_down(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ()));
  for (int cameras : {2, 3, 4, 6}) {
    SCOPED_TRACE(std::to_string(cameras) + " cameras");
    const Rig ring = ring_of(cameras, 1.3);
    EXPECT_TRUE(world_looks_z_up(ring));
    EXPECT_TRUE(world_looks_z_up(ring_of(cameras, 2.6)));  // tilted down 34°
    EXPECT_TRUE(world_looks_z_up(ring_of(cameras, 1.3, portrait)));
    EXPECT_TRUE(world_looks_z_up(ring_of(cameras, 2.6, upside_down)));
    EXPECT_FALSE(world_looks_z_up(moved(ring, to_y_up)));
    EXPECT_FALSE(world_looks_z_up(moved(ring, ring.cameras[0].world_from_depth.inverse())));
  }
  // One camera overhead, looking straight down (its image "down" level): z-up, alone or above a ring.
  Rig overhead;
  overhead.cameras.push_back({.name = "top", .world_from_depth = Rigid3d(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()))});
  overhead.cameras[0].world_from_depth.translation() = Eigen::Vector3d(0, 0, 3);
  ASSERT_NEAR((overhead.cameras[0].world_from_depth.linear() * Eigen::Vector3d::UnitZ()).z(), -1, 1e-12);
  EXPECT_TRUE(world_looks_z_up(overhead));
  Rig ring_and_overhead = ring_of(4, 1.3);
  ring_and_overhead.cameras.push_back(overhead.cameras[0]);
  EXPECT_TRUE(world_looks_z_up(ring_and_overhead));
  // One level camera turned on its side: nothing tells.
  EXPECT_FALSE(world_looks_z_up(Rig{.cameras = {ring_of(1, 1.3, portrait).cameras[0]}}));
  EXPECT_FALSE(world_looks_z_up(Rig{}));
}

}  // namespace
}  // namespace zipfusion
