#include "zipfusion/fusion/zipper.h"

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <random>
#include <set>
#include <functional>
#include <limits>

#include "zipfusion/core/error_test_util.h"
#include "zipfusion/core/mesh_distance.h"
#include "zipfusion/core/mesh_test_util.h"
#include "zipfusion/core/rasterizer.h"
#include "zipfusion/depth/color_lookup.h"
#include "zipfusion/eval/eval.h"

namespace zipfusion {
namespace {

const Intrinsics kKinect{.width = 640, .height = 480, .fx = 580, .fy = 580, .cx = 319.5, .cy = 239.5};

// A scene rendered by several cameras and triangulated: the zipper's input.
struct Scene {
  std::vector<CameraModel> models;
  std::vector<DepthMesh> meshes;
  std::vector<ColorImage> colors;

  void add_camera(const Rigid3d& world_from_depth, const TriangleMesh& surface) {
    CameraModel model;
    model.name = "cam" + std::to_string(models.size());
    model.depth_intrinsics = kKinect;
    model.color_intrinsics = kKinect;  // a colour camera where the depth camera is, all one colour
    model.world_from_depth = world_from_depth;
    RenderBuffers buffers;
    buffers.reset(kKinect, false);
    rasterize_mesh(surface, kKinect, world_from_depth.inverse(), buffers);
    Image<float> depth = buffers.depth;
    for (float& z : depth.data) z = std::isinf(z) ? 0.0f : z;
    DepthMesh mesh;
    triangulate_sdc(depth, kKinect, world_from_depth.cast<float>(), {}, mesh);
    models.push_back(model);
    meshes.push_back(std::move(mesh));
    colors.emplace_back(kKinect.width, kKinect.height, Rgb8{static_cast<unsigned char>(60 * models.size()), 100, 100});
  }

  ZipperResult zipper(const ZipperOptions& options = {}) {
    std::vector<ZipperCamera> cameras;
    for (size_t i = 0; i < meshes.size(); ++i) cameras.push_back({&meshes[i], &colors[i], &models[i]});
    scratch = ZipperScratch{};
    return zipper_meshes(cameras, options, scratch);
  }
  ZipperScratch scratch;  // the last call's, with its pairs
};

double area(const TriangleMesh& mesh) {
  double sum = 0;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    sum += 0.5 * (mesh.positions[t[1]] - mesh.positions[t[0]]).cross(mesh.positions[t[2]] - mesh.positions[t[0]]).norm();
  }
  return sum;
}

int components(const TriangleMesh& mesh, int min_triangles) {
  std::vector<int> parent(mesh.positions.size());
  std::iota(parent.begin(), parent.end(), 0);
  std::function<int(int)> find = [&](int x) { return parent[x] == x ? x : parent[x] = find(parent[x]); };
  for (const Eigen::Vector3i& t : mesh.triangles) {
    parent[find(t[1])] = find(t[0]);
    parent[find(t[2])] = find(t[0]);
  }
  std::map<int, int> sizes;
  for (const Eigen::Vector3i& t : mesh.triangles) sizes[find(t[0])]++;
  int count = 0;
  for (const auto& [root, size] : sizes) count += size >= min_triangles;
  return count;
}

int non_manifold_edges(const TriangleMesh& mesh) {
  std::map<std::pair<int, int>, int> uses;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) uses[{std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])}]++;
  }
  int count = 0;
  for (const auto& [edge, n] : uses) count += n > 2;
  return count;
}

// Share of sample points of `truth` farther than `distance` from `mesh` (holes).
double uncovered_share(const TriangleMesh& truth, const TriangleMesh& mesh, float distance) {
  const MeshDistance query(mesh);
  int uncovered = 0, total = 0;
  for (const Eigen::Vector3f& p : truth.positions) {
    ++total;
    uncovered += query.closest(p, distance).triangle < 0;
  }
  return static_cast<double>(uncovered) / total;
}

// A 1.2 m × 1.6 m wall at x = 0 seen by two cameras 2.2 m away, 40° apart.
TriangleMesh wall_mesh() {
  return grid_mesh(120, 160, [](float s, float t) { return Eigen::Vector3f(0, -0.6f + 1.2f * s, 0.2f + 1.6f * t); });
}
// The first camera sees `wall`, the second `second_view` (the wall itself, or a layer of it).
Scene two_views_of(const TriangleMesh& wall, const TriangleMesh& second_view) {
  Scene scene;
  for (const auto& [angle_deg, surface] : {std::pair{-20.0, &wall}, std::pair{20.0, &second_view}}) {
    const double a = angle_deg * std::numbers::pi / 180;
    scene.add_camera(look_at({2.2 * std::cos(a), 2.2 * std::sin(a), 1.0}, {0, 0, 1.0}), *surface);
  }
  return scene;
}
Scene two_views_of(const TriangleMesh& wall) { return two_views_of(wall, wall); }

// Sample points of the wall 5 cm or more from its border, where the zippered sheet may have no hole.
TriangleMesh wall_interior(const TriangleMesh& wall) {
  TriangleMesh interior;
  for (const Eigen::Vector3f& p : wall.positions) {
    if (std::abs(p.y()) < 0.55f && p.z() > 0.25f && p.z() < 1.75f) interior.positions.push_back(p);
  }
  return interior;
}

// The zipper's distances stop where they stop meaning one surface: 0.1 m for d_r and the longest
// seam edge, 0.05 m for d_c (beyond, seams webbed over the gaps of a body and folded).
TEST(Zipper, DistancesBeyondABodysGapsAreRefused) {
  auto refusal = [](auto set) {
    ZipperOptions options;
    set(options);
    return invalid_input_message([&] { options.validate(); });
  };
  EXPECT_EQ(refusal([](ZipperOptions& o) { o.redundancy_distance_m = 0.1; }), kNoInvalidInput);
  EXPECT_EQ(refusal([](ZipperOptions& o) { o.redundancy_distance_m = 0.11; }), "--redundancy-distance: must be in (0, 0.1] metres");
  EXPECT_EQ(refusal([](ZipperOptions& o) { o.max_seam_edge_m = 0.1; }), kNoInvalidInput);
  EXPECT_EQ(refusal([](ZipperOptions& o) { o.max_seam_edge_m = 0.2; }), "--max-seam-edge: must be in (0, 0.1] metres");
  EXPECT_EQ(refusal([](ZipperOptions& o) { o.clipping_distance_m = 0.05; }), kNoInvalidInput);
  EXPECT_EQ(refusal([](ZipperOptions& o) { o.clipping_distance_m = 0.06; }), "--clipping-distance: must be in (0, 0.05] metres");
  EXPECT_EQ(refusal([](ZipperOptions& o) { o.clipping_distance_m = std::nan(""); }), "--clipping-distance: must be in (0, 0.05] metres");
}

TEST(Zipper, TwoOverlappingViewsOfAPlaneBecomeOneSheet) {
  const TriangleMesh wall = wall_mesh();
  Scene scene = two_views_of(wall);
  TriangleMesh separate;
  std::vector<int> scratch;
  for (const DepthMesh& m : scene.meshes) append_depth_mesh(m, {}, separate, scratch);
  const ZipperResult result = scene.zipper();
  ASSERT_EQ(scene.scratch.pairs.size(), 1u);
  const TriangleMesh& mesh = result.mesh;
  EXPECT_LT(uncovered_share(wall_interior(wall), mesh, 0.005f), 0.001) << "holes in the zippered sheet";
  // No double layer: the area is the wall's (the separate meshes are much larger).
  const double true_area = 1.2 * 1.6;
  EXPECT_GT(area(separate), 1.5 * true_area);
  EXPECT_NEAR(area(mesh) / true_area, 1.0, 0.03);
  EXPECT_EQ(components(mesh, 50), 1);
  EXPECT_EQ(non_manifold_edges(mesh), 0);
  // Colours carry over: each camera's vertices have its colour, and both cameras keep some.
  ASSERT_EQ(mesh.colors.size(), mesh.positions.size());
  std::map<int, int> vertices_of_color;
  for (const Rgb8& c : mesh.colors) vertices_of_color[c.r]++;
  EXPECT_EQ(vertices_of_color.size(), 2u);
  EXPECT_GT(vertices_of_color[scene.colors[0].data[0].r], 1000);
  EXPECT_GT(vertices_of_color[scene.colors[1].data[0].r], 1000);
}

// Two cameras' layers of one wall a few millimetres apart in depth, as noise and calibration
// leave them: the seam joins them without creases (count_folded_edges: two triangles' normals
// more than 120° apart). Points of both layers laid out side by side made the seam's triangles
// zigzag between the layers: 96, 141 and 166 creases for 2, 4 and 6 mm before seam points were
// moved towards the other layer (consensus_projection, consensus_move) and creases flipped out
// (75, 113 and 141 with the flips alone; 0, 2 and 4 with both while the consensus moved points
// cos α of halfway, before the seam was faired). Neither may open a hole.
TEST(Zipper, SeamBetweenOffsetLayersDoesNotCrease) {
  for (const float offset : {0.002f, 0.004f, 0.006f}) {
    const TriangleMesh wall = wall_mesh();
    TriangleMesh shifted = wall;
    for (Eigen::Vector3f& p : shifted.positions) p.x() += offset;  // along the wall's normal
    Scene scene = two_views_of(wall, shifted);
    const ZipperResult result = scene.zipper();
    ASSERT_GT(result.stats.seam_added, 2000) << "offset " << offset;
    TriangleMesh kept = result.mesh;
    kept.triangles.resize(kept.triangles.size() - result.stats.seam_added);
    EXPECT_EQ(count_folded_edges(kept), 0) << "offset " << offset;
    const int folds = count_folded_edges(result.mesh);
    EXPECT_LE(folds, 0.0005 * result.stats.seam_added) << "offset " << offset;
    EXPECT_EQ(non_manifold_edges(result.mesh), 0) << "offset " << offset;
    // No holes: the wall's interior lies within the layers' offset and 3 mm of the mesh.
    const double uncovered = uncovered_share(wall_interior(wall), result.mesh, offset + 0.003f);
    EXPECT_LT(uncovered, 0.001) << "offset " << offset;
    std::printf("offset %.0f mm: %d seam triangles, %d folded edges, %.5f of the wall uncovered\n", 1000 * offset, result.stats.seam_added, folds,
                uncovered);
  }
}

// The output mesh is built in the previous frame's buffers: a frame set in which every camera is
// missing gives an empty mesh, and one with a single camera that camera's mesh alone.
TEST(Zipper, ReusedOutputHoldsOnlyThisFramesCameras) {
  Scene scene = two_views_of(wall_mesh());
  std::vector<ZipperCamera> both, none(2), first(2);
  for (size_t i = 0; i < 2; ++i) both.push_back({&scene.meshes[i], &scene.colors[i], &scene.models[i]});
  first[0] = both[0];
  ZipperScratch scratch;
  ZipperResult result = zipper_meshes(both, {}, scratch);
  ASSERT_GT(result.mesh.triangles.size(), 10000u);
  result = zipper_meshes(none, {}, scratch, std::move(result.mesh));
  EXPECT_TRUE(result.mesh.positions.empty());
  EXPECT_TRUE(result.mesh.colors.empty());
  EXPECT_TRUE(result.mesh.triangles.empty());
  result = zipper_meshes(first, {}, scratch, std::move(result.mesh));
  EXPECT_EQ(static_cast<int>(result.mesh.triangles.size()), scene.meshes[0].triangle_count());
  EXPECT_EQ(result.mesh.colors.size(), result.mesh.positions.size());
}

TEST(Zipper, VertexColoursAreSampledWhereTheirCameraSeesThem) {
  // The wall of the two-plane test; camera 0's colour camera sits 2.5 cm to the side of its depth
  // camera (as a Kinect's) and sees a gradient, 4 levels a pixel, camera 1 has no
  // colour image. Each vertex kept from camera 0 has the colour its point projects onto; camera
  // 1's are grey.
  Scene scene = two_views_of(wall_mesh());
  CameraModel& colored = scene.models[0];
  colored.color_from_depth = Rigid3d(Eigen::Translation3d(-0.025, 0, 0));
  ColorImage& gradient = scene.colors[0];
  for (int v = 0; v < gradient.height; ++v) {
    for (int u = 0; u < gradient.width; ++u) gradient(u, v) = {static_cast<unsigned char>(u * 4 % 256), static_cast<unsigned char>(v * 4 % 256), 40};
  }
  std::vector<ZipperCamera> cameras = {{&scene.meshes[0], &gradient, &scene.models[0]}, {&scene.meshes[1], nullptr, &scene.models[1]}};
  ZipperScratch scratch;
  const TriangleMesh mesh = zipper_meshes(cameras, {}, scratch).mesh;
  ASSERT_EQ(mesh.colors.size(), mesh.positions.size());
  const Rigid3f color_from_world = (colored.color_from_depth * colored.world_from_depth.inverse()).cast<float>();
  int grey = 0, sampled = 0;
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const Rgb8 c = mesh.colors[i];
    if (c == kNoColor) {
      ++grey;
      continue;
    }
    const Eigen::Vector2f pixel = project_pinhole(*colored.color_intrinsics, color_from_world * mesh.positions[i]);
    const Rgb8 expected = sample_bilinear(gradient, pixel.x(), pixel.y());
    // The point reaches the colour camera by another chain of float operations: a level apart.
    ASSERT_LE(std::abs(c.r - expected.r), 1) << "vertex " << i;
    ASSERT_LE(std::abs(c.g - expected.g), 1) << "vertex " << i;
    ASSERT_EQ(c.b, 40) << "vertex " << i;
    ++sampled;
  }
  EXPECT_GT(grey, 1000);
  EXPECT_GT(sampled, 1000);
}

// A cylinder of radius 0.15 m, 1.2 m high (a torso).
TriangleMesh torso_cylinder() {
  return grid_mesh(180, 60, [](float s, float t) {
    const float a = 2 * std::numbers::pi_v<float> * s;
    return Eigen::Vector3f(0.15f * std::cos(a), 0.15f * std::sin(a), 0.4f + 1.2f * t);
  });
}

// `surface` seen by four cameras on a square around it, 2.5 m away.
Scene four_cameras_around(const TriangleMesh& surface) {
  Scene scene;
  for (int k = 0; k < 4; ++k) {
    const double a = std::numbers::pi / 4 + k * std::numbers::pi / 2;
    scene.add_camera(look_at({2.5 * std::cos(a), 2.5 * std::sin(a), 1.3}, {0, 0, 1.0}), surface);
  }
  return scene;
}

TEST(Zipper, CylinderSeenByFourCamerasIsOneComponent) {
  const TriangleMesh cylinder = torso_cylinder();
  Scene scene = four_cameras_around(cylinder);
  const ZipperResult result = scene.zipper();
  const TriangleMesh& mesh = result.mesh;
  EXPECT_EQ(components(mesh, 50), 1);
  EXPECT_EQ(non_manifold_edges(mesh), 0);
  TriangleMesh interior;
  for (const Eigen::Vector3f& p : cylinder.positions) {
    if (p.z() > 0.45f && p.z() < 1.55f) interior.positions.push_back(p);
  }
  EXPECT_LT(uncovered_share(interior, mesh, 0.005f), 0.002) << "holes in the zippered cylinder";
  const double true_area = 2 * std::numbers::pi * 0.15 * 1.2;
  EXPECT_NEAR(area(mesh) / true_area, 1.0, 0.05);
}

// The scratch carries nothing from one frame set to the next: on one scratch, the four cameras,
// then three (camera 2 without depth, its pairs gone), then four and three again give bit for bit
// what a fresh scratch gives each time.
TEST(Zipper, ReusedScratchGivesWhatAFreshOneGives) {
  const Scene scene = four_cameras_around(torso_cylinder());
  auto zipper = [&](ZipperScratch& scratch, bool with_camera_2) {
    std::vector<DepthMesh> meshes = scene.meshes;  // the zipper clears removed triangles' bits
    std::vector<ZipperCamera> cameras;
    for (size_t i = 0; i < meshes.size(); ++i) cameras.push_back({i != 2 || with_camera_2 ? &meshes[i] : nullptr, &scene.colors[i], &scene.models[i]});
    return zipper_meshes(cameras, {}, scratch);
  };
  ZipperScratch reused;
  for (const bool with_camera_2 : {true, false, true, false}) {
    ZipperScratch fresh;
    const ZipperResult expected = zipper(fresh, with_camera_2);
    const ZipperResult got = zipper(reused, with_camera_2);
    ASSERT_GT(expected.stats.seam_added, 1000) << "with camera 2: " << with_camera_2;
    EXPECT_EQ(fresh.pairs.size(), with_camera_2 ? 4u : 2u);
    EXPECT_EQ(reused.pairs, fresh.pairs);
    EXPECT_EQ(got.mesh.triangles, expected.mesh.triangles) << "with camera 2: " << with_camera_2;
    EXPECT_EQ(got.mesh.positions, expected.mesh.positions) << "with camera 2: " << with_camera_2;
    EXPECT_EQ(got.mesh.colors, expected.mesh.colors) << "with camera 2: " << with_camera_2;
  }
}

// FRBR's frontier and the seams' candidate lists test their triangles for existence only
// (start_worklist, select_seeds): whatever they hold that still exists must be a boundary
// triangle, as it was when added, since a mesh only loses triangles. Checked after a whole
// zippering (the lists as its last level and its last seam left them) on the cylinder's four
// cameras, whose pairs remove triangles and take seams.
TEST(Zipper, BoundaryListsHoldOnlyBoundaryTriangles) {
  Scene scene = four_cameras_around(torso_cylinder());
  std::vector<ZipperCamera> cameras;
  for (size_t i = 0; i < scene.meshes.size(); ++i) cameras.push_back({&scene.meshes[i], &scene.colors[i], &scene.models[i]});
  ZipperScratch scratch;
  const ZipperResult result = zipper_meshes(cameras, {}, scratch);
  ASSERT_GT(result.stats.redundant_removed, 1000);
  ASSERT_GT(result.stats.seam_taken, 100);
  for (size_t c = 0; c < cameras.size(); ++c) {
    const DepthMesh& mesh = scene.meshes[c];
    int existing = 0;
    for (const std::vector<int>* list : {&scratch.cameras[c].frbr.frontier, &scratch.cameras[c].seam.boundary}) {
      for (int id : *list) {
        if (!(mesh.triangles[cell_of(id)] & bit_of(id))) continue;
        ++existing;
        ASSERT_TRUE(is_boundary_triangle(mesh.triangles.data(), cell_of(id), mesh.width, bit_of(id))) << "camera " << c << ", triangle " << id;
      }
    }
    EXPECT_GT(existing, 100) << "camera " << c;
  }
}

TEST(Redundancy, BoundaryTrianglesAreThoseTheElementTestFinds) {
  // A random bit matrix (none in the last row and column) with a depth box inside the image and
  // one touching its corner: the row kernel and the element function must agree on every cell.
  std::mt19937 random(7);
  for (const PixelBox box : {PixelBox{3, 2, 37, 25}, PixelBox{0, 0, 40, 30}}) {
    DepthMesh mesh;
    mesh.width = 40;
    mesh.height = 30;
    mesh.depth_box = box;
    mesh.triangles.assign(mesh.width * mesh.height, 0);
    for (int v = box.v0; v < std::min(box.v1, mesh.height - 1); ++v) {
      for (int u = box.u0; u < std::min(box.u1, mesh.width - 1); ++u) {
        mesh.triangles[v * mesh.width + u] = random() % 5 == 0 ? static_cast<std::uint8_t>(random() % 3) : 3;
      }
    }
    std::vector<int> expected;
    for_each_triangle_id(mesh, [&](int id) {
      if (is_boundary_triangle(mesh.triangles.data(), cell_of(id), mesh.width, bit_of(id))) expected.push_back(id);
    });
    std::vector<int> found;
    collect_boundary_triangles(mesh, found);
    EXPECT_GT(expected.size(), 100u);
    EXPECT_EQ(found, expected);
  }
}

TEST(Redundancy, TestBlockKernelsGiveTheElementFunctionsFloatsAndAnswers) {
  // Every triangle of one view of the wall tested against the other: the projections of their
  // centres (project_triangle_centres) and who owns them (select_owned_by_other) must be those of
  // project_camera_point and owner_is_other, bit for bit. The other view is turned a little
  // (every entry of the rotation between the two nonzero) and far (centres off its image or
  // behind it), and each camera is tested as a and as b. Ownership is the distance to each mesh's
  // border on its coarse level, or 1 on every cell of it (ties everywhere, which go to the lower
  // camera).
  const Scene scene = two_views_of(wall_mesh());
  std::vector<DepthMesh> meshes = scene.meshes, coarse(2);
  std::vector<OwnershipScore> border(2), flat(2);
  for (int c = 0; c < 2; ++c) {
    downsample_mesh(meshes[c], 1, DepthJump{}, coarse[c]);
    compute_border_distance(coarse[c], 1, 2, border[c]);
    flat[c] = border[c];
    for (int v = 0; v < flat[c].height; ++v) {
      for (int u = 0; u < flat[c].width; ++u) flat[c].cell(u, v) = 1.0f;
    }
    // Pixels without depth, each the last of a 2×2 whose other three have depth: there only that
    // pixel lets b see a point off its surface.
    for (int v = 1; v < kKinect.height; v += 4) {
      for (int u = 1; u < kKinect.width; u += 4) meshes[c].depth[v * kKinect.width + u] = 0;
    }
  }
  auto view = [&](int c, const Rigid3f& turn, const OwnershipScore* score) {
    return MeshView{&meshes[c], kKinect, turn * scene.models[c].world_from_depth.inverse().cast<float>(), score, c, 0};
  };
  auto same_bits = [](float x, float y) { return std::bit_cast<std::uint32_t>(x) == std::bit_cast<std::uint32_t>(y); };
  int outside = 0, owned_total = 0, tested = 0;
  for (const float turn_deg : {3.0f, 50.0f, 180.0f}) {
    const Rigid3f turn(Eigen::AngleAxisf(turn_deg * std::numbers::pi_v<float> / 180, Eigen::Vector3f(0.2f, 1.0f, 0.3f).normalized()));
    for (const auto& [a_camera, b_camera] : {std::pair{0, 1}, std::pair{1, 0}}) {
      for (const std::vector<OwnershipScore>* scores : {&border, &flat}) {
        for (const bool a_scored : {true, false}) {
          const MeshView a = view(a_camera, Rigid3f::Identity(), a_scored ? &(*scores)[a_camera] : nullptr);
          const MeshView b = view(b_camera, turn, &(*scores)[b_camera]);
          const Rigid3f b_from_a_camera = b_from_a(a, b);
          std::vector<int> ids;
          for_each_triangle_id(meshes[a_camera], [&](int id) { ids.push_back(id); });
          TriangleTestBlock block;
          int owned[TriangleTestBlock::kCapacity];
          for (size_t first = 0; first < ids.size(); first += TriangleTestBlock::kCapacity) {
            block.count = 0;
            for (size_t k = first; k < std::min(ids.size(), first + TriangleTestBlock::kCapacity); ++k) {
              const int cell = cell_of(ids[k]);
              block.add(ids[k], cell % kKinect.width, cell / kKinect.width);
            }
            project_triangle_centres(a, b, b_from_a_camera, block);
            const int m = select_owned_by_other(a, b, 0.06f, block, owned);
            std::vector<int> expected_owned;
            for (int i = 0; i < block.count; ++i) {
              const Eigen::Vector3f centre = camera_triangle_centre(a, block.u[i], block.v[i], bit_of(block.id[i]));
              const ViewPoint one = project_camera_point(b, transform_point(b_from_a_camera, centre));
              const ViewPoint many = block.centre(i);
              ASSERT_TRUE(same_bits(many.in_camera.x(), one.in_camera.x()) && same_bits(many.in_camera.y(), one.in_camera.y()) &&
                          same_bits(many.in_camera.z(), one.in_camera.z()) && same_bits(many.x, one.x) && same_bits(many.y, one.y) &&
                          many.cell == one.cell)
                  << "triangle " << block.id[i] << ", turned " << turn_deg << "°: (" << many.x << ", " << many.y << ") cell " << many.cell
                  << " against (" << one.x << ", " << one.y << ") cell " << one.cell;
              if (owner_is_other(a, block.a_x[i], block.a_y[i], b, one, 0.06f)) expected_owned.push_back(i);
              outside += one.cell < 0;
            }
            ASSERT_EQ(std::vector<int>(owned, owned + m), expected_owned) << "turned " << turn_deg << "°, a camera " << a_camera;
            owned_total += m;
            tested += block.count;
          }
        }
      }
    }
  }
  EXPECT_GT(outside, tested / 4);      // off the image or behind it
  EXPECT_GT(owned_total, tested / 20);  // and owned by b, for some
}

// has_triangle_near answers as a scan of every cell of its window does, with the same
// arithmetic: on a noisy surface with a step, holes and triangles cleared (their depths left, as
// redundancy removal leaves them), for windows of 1 to 4 cells, at points near and off both
// layers, wholly inside the image (where the window's columns are filtered by depth first, 8 or
// 16 at a time), near its edges and outside it, right in front of and behind triangles at about
// the distance, and for windows wider than the filter reads.
TEST(Redundancy, WindowSearchFindsWhatAScanOfTheWholeWindowFinds) {
  const Intrinsics k{.width = 96, .height = 40, .fx = 58, .fy = 58, .cx = 47.5, .cy = 19.5};
  std::mt19937 random(11);
  std::normal_distribution<float> noise(0.0f, 0.004f);
  Image<float> depth(k.width, k.height, 0.0f);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const bool step = u > 60 && v > 10 && v < 30;
      const bool hole = (u - 30) * (u - 30) + (v - 20) * (v - 20) < 16;
      depth(u, v) = hole ? 0.0f : (step ? 2.3f : 2.5f) + 0.002f * static_cast<float>(u % 7) + noise(random);
    }
  }
  DepthMesh mesh;
  triangulate_sdc(depth, k, Rigid3f::Identity(), {}, mesh);
  for (size_t cell = 0; cell < mesh.triangles.size(); ++cell) {
    if (random() % 5 == 0) mesh.triangles[cell] &= static_cast<std::uint8_t>(random() % 3);  // some cleared, depth kept
  }
  const MeshView view{&mesh, k, Rigid3f::Identity(), nullptr, 0, 0};
  // The scan: every cell within the window of p's cell, the centres as has_triangle_near forms them.
  auto scan = [&](const ViewPoint& p, float distance, int max_window) {
    const Eigen::Vector3f& q = p.in_camera;
    if (!(q.z() > 0) || !(std::abs(p.x) < 1e6f && std::abs(p.y) < 1e6f)) return false;
    const int window = std::clamp(ceil_to_int(distance * view.fx / q.z()), 1, max_window);
    const int cu = floor_to_int(p.x), cv = floor_to_int(p.y);
    const float third = 1.0f / 3.0f;
    for (int v = std::max(0, cv - window); v <= std::min(k.height - 2, cv + window); ++v) {
      for (int u = std::max(0, cu - window); u <= std::min(k.width - 2, cu + window); ++u) {
        const int cell = v * k.width + u;
        const float z00 = mesh.depth[cell], z10 = mesh.depth[cell + 1], z01 = mesh.depth[cell + k.width], z11 = mesh.depth[cell + k.width + 1];
        for (const TriangleBit bit : {kUpperTriangle, kLowerTriangle}) {
          if (!(mesh.triangles[cell] & bit)) continue;
          const bool upper = bit == kUpperTriangle;
          const float zc = upper ? (z00 + z01 + z10) * third : (z10 + z01 + z11) * third;
          const float x_extra = upper ? z10 * third : (z10 + z11) * third, y_extra = upper ? z01 * third : (z01 + z11) * third;
          const float dz = zc - q.z();
          const float dx = ((static_cast<float>(u) - view.cx) * zc + x_extra) * view.inv_fx - q.x();
          const float dy = ((static_cast<float>(v) - view.cy) * zc + y_extra) * view.inv_fy - q.y();
          if (dx * dx + dy * dy + dz * dz < distance * distance) return true;
        }
      }
    }
    return false;
  };
  // Most points within a few centimetres of one of the two layers, the others anywhere between.
  std::uniform_real_distribution<float> x(-6.0f, k.width + 6.0f), y(-6.0f, k.height + 6.0f), z(2.22f, 2.58f), off(-0.03f, 0.03f);
  auto point_depth = [&] { return random() % 4 == 0 ? z(random) : (random() % 2 ? 2.3f : 2.51f) + off(random); };
  std::map<std::pair<int, bool>, int> cases;  // (window, found) → count
  for (int i = 0; i < 60000; ++i) {
    const float distance = std::array{0.01f, 0.05f, 0.09f, 0.2f}[i % 4];
    const int max_window = i % 8 < 4 ? 4 : kSeamWindow;
    Eigen::Vector3f point = unproject(k, x(random), y(random), point_depth());
    if (i % 5 == 0) {
      // Right in front of or behind a triangle's centre, by just under or over the distance: the
      // depth test's edge.
      const int cell = static_cast<int>(random() % (mesh.triangles.size() - k.width - 1));
      const int u = cell % k.width, v = cell / k.width;
      if (u < k.width - 1 && v < k.height - 1 && (mesh.triangles[cell] & kUpperTriangle)) {
        const float third = 1.0f / 3.0f;
        const float z00 = mesh.depth[cell], z10 = mesh.depth[cell + 1], z01 = mesh.depth[cell + k.width];
        const float zc = (z00 + z01 + z10) * third;
        const float edge = distance * (1.0f + 0.02f * (static_cast<float>(random() % 201) / 100.0f - 1.0f));
        point = {((static_cast<float>(u) - view.cx) * zc + z10 * third) * view.inv_fx, ((static_cast<float>(v) - view.cy) * zc + z01 * third) * view.inv_fy,
                 zc + (random() % 2 ? edge : -edge)};
      }
    }
    const ViewPoint p = project_camera_point(view, point);
    const bool expected = scan(p, distance, max_window);
    ASSERT_EQ(has_triangle_near(view, p, distance, max_window), expected)
        << "at (" << p.x << ", " << p.y << ", " << p.in_camera.z() << "), distance " << distance << ", window at most " << max_window;
    ++cases[{std::clamp(ceil_to_int(distance * view.fx / p.in_camera.z()), 1, max_window), expected}];
  }
  for (int window = 1; window <= 4; ++window) {
    EXPECT_GT((cases[{window, true}]), 100) << window;
    EXPECT_GT((cases[{window, false}]), 100) << window;
  }
  // Windows wider than one read of the column filter (up to 9 cells each way: 19 columns).
  int wide = 0;
  for (int i = 0; i < 5000; ++i) {
    const float distance = i % 2 ? 0.4f : 0.6f;
    const ViewPoint p = project_camera_point(view, unproject(k, x(random), y(random), point_depth()));
    const bool expected = scan(p, distance, 9);
    ASSERT_EQ(has_triangle_near(view, p, distance, 9), expected) << "at (" << p.x << ", " << p.y << ", " << p.in_camera.z() << "), distance " << distance;
    wide += std::clamp(ceil_to_int(distance * view.fx / p.in_camera.z()), 1, 9) > 7;
  }
  EXPECT_GT(wide, 2500);
  // A wide window whose only triangles lie in its last columns: a mesh that starts 8 cells right
  // of the point's cell.
  DepthMesh right_half;
  triangulate_sdc(Image<float>(k.width, k.height, 2.5f), k, Rigid3f::Identity(), {}, right_half);
  for (size_t cell = 0; cell < right_half.triangles.size(); ++cell) {
    if (static_cast<int>(cell) % k.width < 50) right_half.triangles[cell] = 0;
  }
  const MeshView right_view{&right_half, k, Rigid3f::Identity(), nullptr, 0, 0};
  for (const float u : {41.5f, 42.5f}) {
    const ViewPoint p = project_camera_point(right_view, unproject(k, u, 20.5f, 2.5f));
    EXPECT_TRUE(has_triangle_near(right_view, p, 0.45f, 9)) << "a point at column " << u;
  }
}

TEST(Redundancy, OverlapReachesDecidesAsTheFullShareWould) {
  // One camera sees the whole wall, the other only its left half; overlap_reaches stops searching
  // once the share reaches the minimum and must answer as overlap_share ≥ minimum does, at the
  // share itself and just above it too.
  const TriangleMesh half_wall = grid_mesh(60, 160, [](float s, float t) { return Eigen::Vector3f(0, -0.6f + 0.6f * s, 0.2f + 1.6f * t); });
  Scene scene;
  scene.add_camera(look_at({2.2, -0.8, 1.0}, {0, 0, 1.0}), wall_mesh());
  scene.add_camera(look_at({2.2, 0.8, 1.0}, {0, 0, 1.0}), half_wall);
  auto view = [&](int c) {
    return MeshView{&scene.meshes[c], kKinect, scene.models[c].world_from_depth.inverse().cast<float>(), nullptr, c, 0};
  };
  const MeshView a = view(0), b = view(1);
  constexpr float kDistance = 0.03f;
  const double share = overlap_share(a, b, kDistance);
  ASSERT_GT(share, 0.3);
  ASSERT_LT(share, 0.7);
  for (const double minimum : {0.0, 0.01, share / 2, share, std::nextafter(share, 1.0), 0.99}) {
    EXPECT_EQ(overlap_reaches(a, b, kDistance, minimum), share >= minimum) << "minimum share " << minimum;
  }
  // A view of nothing reaches only a minimum of 0.
  DepthMesh empty;
  empty.width = kKinect.width;
  empty.height = kKinect.height;
  empty.depth.assign(static_cast<size_t>(kKinect.width) * kKinect.height, 0.0f);
  empty.triangles.assign(empty.depth.size(), 0);
  const MeshView nothing{&empty, kKinect, a.depth_from_world, nullptr, 2, 0};
  EXPECT_TRUE(overlap_reaches(nothing, b, kDistance, 0.0));
  EXPECT_FALSE(overlap_reaches(nothing, b, kDistance, 0.01));
  EXPECT_FALSE(overlap_reaches(a, nothing, kDistance, 0.01));
}

TEST(Clipping, SeamWindowPreCheckNeverRejectsWhatTheSearchFinds) {
  // The pre-check must say "maybe" wherever a has_triangle_near search with the seam's window
  // finds a triangle: around a cleared hole (its rim is where a smaller window would miss), at
  // the image's edges (a mesh that reaches them) and off the image.
  const Intrinsics k{.width = 64, .height = 48, .fx = 58, .fy = 58, .cx = 31.5, .cy = 23.5};
  Image<float> depth(k.width, k.height, 2.5f);
  DepthMesh mesh;
  triangulate_sdc(depth, k, Rigid3f::Identity(), {}, mesh);
  for (int v = 15; v < 30; ++v) {
    for (int u = 20; u < 44; ++u) mesh.triangles[v * k.width + u] = 0;  // redundancy removal cleared these
  }
  const MeshView view{&mesh, k, Rigid3f::Identity(), nullptr, 0, 0};
  std::mt19937 random(5);
  std::uniform_real_distribution<float> x(-3.0f, k.width + 3.0f), y(-3.0f, k.height + 3.0f), z(2.45f, 2.55f);
  int found = 0, rejected = 0;
  for (int i = 0; i < 20000; ++i) {
    const float px = x(random), py = y(random), pz = z(random);
    const ViewPoint p = project_camera_point(view, unproject(k, px, py, pz));
    const bool near = has_triangle_near(view, p, 0.1f, kSeamWindow);  // a distance wider than the window
    const bool maybe = seam_window_has_triangle(mesh, p);
    if (near) ++found;
    if (!maybe) ++rejected;
    ASSERT_TRUE(maybe || !near) << "rejected (" << px << ", " << py << "), where the search finds a triangle";
  }
  EXPECT_GT(found, 10000);
  EXPECT_GT(rejected, 500);  // the centre of the hole: 20 × 11 cells of 64 × 48
}

// keeps_pixel_grid_unfolded allows a seam point's move exactly when a reference over the whole pixel
// grid does: every grid triangle with the pixel as a corner, kept or not, keeps facing the camera
// in 3-D (its other corners on their pixels, or where this seam put them), and the point stays
// within kMostPixelShift of its pixel, or kMostPixelShiftBesideOtherSeam where one of those
// triangles has a corner of another seam. Random moves of the point and of this seam's
// neighbours, random labels of the neighbours (a point of several seams stays on its pixel) and
// random kept triangles (which must not matter), at a pixel inside the image and at two on its
// border, on a tilted plane seen by a camera that is not at the origin.
TEST(Clipping, SeamPointMovesKeepThePixelGridUnfolded) {
  const Intrinsics k{.width = 16, .height = 12, .fx = 14, .fy = 14, .cx = 7.5, .cy = 5.5};
  Image<float> depth(k.width, k.height, 0.0f);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) depth(u, v) = 2.0f + 0.01f * static_cast<float>(u) - 0.008f * static_cast<float>(v);
  }
  const Rigid3f world_from_depth = Eigen::Translation3f(0.5f, -1.0f, 0.3f) * Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 2, 3).normalized());
  DepthMesh mesh;
  triangulate_sdc(depth, k, world_from_depth, {}, mesh);
  const std::vector<std::uint8_t> all_triangles = mesh.triangles;
  ASSERT_EQ(count_triangles(all_triangles.data(), static_cast<int>(all_triangles.size())), 2 * (k.width - 1) * (k.height - 1));
  const MeshView view{&mesh, k, world_from_depth.inverse(), nullptr, 0, 0};
  const Eigen::Vector3d centre = world_from_depth.translation().cast<double>();
  constexpr std::uint16_t kOwn = 3, kOther = 8;
  std::vector<std::uint16_t> seam_of(mesh.triangles.size(), SeamPixelMap::kNoSeam);
  std::vector<int> vertex_of(mesh.triangles.size(), -1);
  const SeamPixelMap map{seam_of.data(), vertex_of.data()};
  auto world_at = [&](float u, float v, float z) -> Eigen::Vector3f { return world_from_depth * unproject(k, u, v, z); };
  std::mt19937 random(11);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f), shift(-2.0f, 2.0f), small_shift(-0.6f, 0.6f), depth_change(-0.08f, 0.08f);
  int allowed = 0, turned = 0, too_far = 0, too_far_beside_other = 0;
  for (const auto& [pu, pv] : {std::pair{7, 5}, std::pair{0, 0}, std::pair{15, 6}}) {
    const int pixel = pv * k.width + pu;
    for (int trial = 0; trial < 10000; ++trial) {
      mesh.triangles = all_triangles;
      for (int cell = 0; cell < static_cast<int>(mesh.triangles.size()); ++cell) {
        for (const TriangleBit bit : {kUpperTriangle, kLowerTriangle}) {
          if (unit(random) < 0.3f) mesh.triangles[cell] &= static_cast<std::uint8_t>(~bit);  // taken into a seam
        }
      }
      std::fill(seam_of.begin(), seam_of.end(), SeamPixelMap::kNoSeam);
      std::vector<Eigen::Vector3f> positions{world_at(pu, pv, depth(pu, pv))};
      seam_of[pixel] = kOwn;
      vertex_of[pixel] = 0;
      for (int v = std::max(0, pv - 1); v <= std::min(k.height - 1, pv + 1); ++v) {
        for (int u = std::max(0, pu - 1); u <= std::min(k.width - 1, pu + 1); ++u) {
          const int q = v * k.width + u;
          if (q == pixel) continue;
          const float label = unit(random);
          seam_of[q] = label < 0.35f ? SeamPixelMap::kNoSeam : label < 0.85f ? kOwn : label < 0.95f ? kOther : SeamPixelMap::kManySeams;
          if (seam_of[q] != kOwn) continue;
          vertex_of[q] = static_cast<int>(positions.size());
          positions.push_back(world_at(u + small_shift(random), v + small_shift(random), depth(u, v) + depth_change(random)));
        }
      }
      const float du = shift(random), dv = shift(random);
      const Eigen::Vector3f p = world_at(pu + du, pv + dv, depth(pu, pv) + depth_change(random));
      positions[0] = p;

      // The reference: every triangle of the whole grid with the pixel as a corner, in 3-D.
      bool faces = true, beside_other = false;
      double closest_to_edge_on = 1.0;
      for (int cell_v = 0; cell_v + 1 < k.height; ++cell_v) {
        for (int cell_u = 0; cell_u + 1 < k.width; ++cell_u) {
          for (const TriangleBit bit : {kUpperTriangle, kLowerTriangle}) {
            int corners[3];
            triangle_pixels(cell_v * k.width + cell_u, k.width, bit, corners);
            if (corners[0] != pixel && corners[1] != pixel && corners[2] != pixel) continue;
            if (std::any_of(corners, corners + 3, [&](int q) { return seam_of[q] == kOther; })) {
              beside_other = true;
              continue;
            }
            Eigen::Vector3d before[3], after[3];
            for (int c = 0; c < 3; ++c) {
              const int q = corners[c];
              before[c] = mesh.point(q).cast<double>();
              after[c] = (seam_of[q] == kOwn ? positions[vertex_of[q]] : mesh.point(q)).cast<double>();
            }
            auto facing = [&](const Eigen::Vector3d* t) {
              const Eigen::Vector3d normal = (t[1] - t[0]).cross(t[2] - t[0]).normalized();
              return normal.dot((centre - t[0]).normalized());
            };
            const double f_before = facing(before), f_after = facing(after);
            closest_to_edge_on = std::min(closest_to_edge_on, std::abs(f_after));
            faces = faces && (f_before > 0) == (f_after > 0);
          }
        }
      }
      const float most = beside_other ? kMostPixelShiftBesideOtherSeam : kMostPixelShift;
      const float pixel_shift = std::hypot(du, dv);
      if (closest_to_edge_on < 1e-4 || std::abs(pixel_shift - most) < 1e-4f) continue;  // too close to call in floats
      const bool expected = faces && pixel_shift <= most;
      ASSERT_EQ(keeps_pixel_grid_unfolded(view, map, kOwn, pixel, p, positions.data()), expected)
          << "pixel (" << pu << ", " << pv << "), trial " << trial << ": moved (" << du << ", " << dv << ") pixels, beside another seam "
          << beside_other << ", facing " << faces;
      // Knowing no labels, only the bound for corners of another seam holds.
      if (std::abs(pixel_shift - kMostPixelShiftBesideOtherSeam) > 1e-4f) {
        EXPECT_EQ(keeps_pixel_grid_unfolded(view, SeamPixelMap{}, kOwn, pixel, p, positions.data()), pixel_shift <= kMostPixelShiftBesideOtherSeam);
      }
      allowed += expected;
      turned += !faces;
      too_far += faces && pixel_shift > most && !beside_other;
      too_far_beside_other += faces && pixel_shift > most && beside_other;
    }
    // Behind the camera: never.
    EXPECT_FALSE(keeps_pixel_grid_unfolded(view, map, kOwn, pixel, world_at(pu, pv, -1.0f), std::vector<Eigen::Vector3f>(9).data()));
  }
  std::cout << allowed << " allowed, " << turned << " turned, " << too_far << " too far, " << too_far_beside_other << " too far beside another seam\n";
  // Each way of answering is met many times.
  EXPECT_GT(allowed, 500);
  EXPECT_GT(turned, 500);
  EXPECT_GT(too_far, 500);
  EXPECT_GT(too_far_beside_other, 500);
}

TEST(Redundancy, SmoothnessScoreRanksTheSmootherSheetHigher) {
  // Three views of a plane 2.5 m away at one level of a 160×120 image: noise-free, with 5 mm and
  // with 10 mm of noise along the rays. The area ratio is 1 on the flat sheet (up to rounding),
  // lower on the noisy ones and lowest on the noisiest; the score is 0 off the mesh.
  const Intrinsics k{.width = 160, .height = 120, .fx = 145, .fy = 145, .cx = 79.5, .cy = 59.5};
  constexpr float kExponent = 12;
  std::mt19937 random(11);
  auto sheet = [&](float sigma) {
    std::normal_distribution<float> noise(0.0f, sigma);
    Image<float> depth(k.width, k.height, 0.0f);
    for (int v = 20; v < 100; ++v) {
      for (int u = 30; u < 130; ++u) depth(u, v) = 2.5f + (sigma > 0 ? noise(random) : 0.0f);
    }
    DepthMesh mesh;
    triangulate_sdc(depth, k, Rigid3f::Identity(), {}, mesh);
    OwnershipScore score;
    compute_smoothness(mesh, k, 0, {.window_cells = 13, .exponent = kExponent, .same_surface_m = 0.03f}, score);
    return score;
  };
  const OwnershipScore flat = sheet(0), noisy = sheet(0.005f), noisier = sheet(0.01f);
  const float at_centre = ownership_score_at(flat, 80, 60);
  EXPECT_NEAR(at_centre / smoothness_score(1.0f, kExponent), 1.0f, 1e-3f);
  EXPECT_LT(ownership_score_at(noisy, 80, 60), std::pow(0.9f, kExponent) * at_centre);
  EXPECT_LT(ownership_score_at(noisier, 80, 60), std::pow(0.95f, kExponent) * ownership_score_at(noisy, 80, 60));
  EXPECT_EQ(ownership_score_at(flat, 10, 10), 0.0f);
}

TEST(Redundancy, SmoothnessIsMeasuredOnEachSurfaceApart) {
  // A sheet 2.5 m away with a box 30 cm in front of its middle, both with 5 mm of noise along the
  // rays: beside the box the sheet is as rough as anywhere else. Averaging the depth across the
  // step would make steep slopes there, whose area hides the noise: the sheet would look about
  // 15 % smoother beside the box (the ratio clamped at 1).
  const Intrinsics k{.width = 160, .height = 120, .fx = 145, .fy = 145, .cx = 79.5, .cy = 59.5};
  std::mt19937 random(5);
  std::normal_distribution<float> noise(0.0f, 0.005f);
  Image<float> depth(k.width, k.height, 0.0f);
  for (int v = 10; v < 110; ++v) {
    for (int u = 10; u < 150; ++u) depth(u, v) = ((u >= 60 && u < 100 && v >= 40 && v < 80) ? 2.2f : 2.5f) + noise(random);
  }
  DepthMesh mesh;
  triangulate_sdc(depth, k, Rigid3f::Identity(), {}, mesh);
  OwnershipScore score;
  compute_smoothness(mesh, k, 0, {.window_cells = 13, .exponent = 1, .same_surface_m = 0.03f}, score);
  // Mean score over the cells of (u0..u1, v0..v1) that hold triangles (noise leaves a rare cell
  // without: a step over the SDC threshold), which must be nearly all.
  auto mean = [&](int u0, int u1, int v0, int v1) {
    double sum = 0;
    int n = 0;
    for (int v = v0; v <= v1; ++v) {
      for (int u = u0; u <= u1; ++u) {
        if (score.cell(u, v) > 0) {
          sum += score.cell(u, v);
          ++n;
        }
      }
    }
    EXPECT_GE(n, (u1 - u0 + 1) * (v1 - v0 + 1) * 9 / 10);
    return sum / std::max(n, 1);
  };
  // Windows reach 6 cells each way, the average 2 more: 8 cells from the box's edge, a window
  // holds none of the box, and only an average over the step could reach it. Far away: the
  // sheet's corners, 9 or more cells inside its border.
  const double away = (mean(19, 30, 19, 30) + mean(129, 140, 19, 30) + mean(19, 30, 89, 100) + mean(129, 140, 89, 100)) / 4;
  EXPECT_NEAR(mean(52, 52, 45, 74) / away, 1.0, 0.05) << "left of the box";
  EXPECT_NEAR(mean(107, 107, 45, 74) / away, 1.0, 0.05) << "right of the box";
  EXPECT_NEAR(mean(65, 94, 32, 32) / away, 1.0, 0.05) << "above the box";
  EXPECT_NEAR(mean(65, 94, 87, 87) / away, 1.0, 0.05) << "below the box";
}

TEST(Redundancy, SmoothnessWindowReachesExactlyItsHalfWidth) {
  // A noise-free sheet with one pixel, (80, 60), raised by 1 cm. The raised pixel adds area to
  // the raw triangles of cells 79 and 80 (of its row and the one above); averaging spreads it
  // over pixels 78..82 and makes the averaged surface a little steeper, and so larger, than the
  // raw one in cells 77, 78, 81 and 82, which alone would put the ratio above 1, counted as 1.
  // So a cell whose 13-cell window (6 each way) reaches cell 79 or 80 scores below the flat
  // sheet's score, and one whose window ends a cell short scores exactly that: cells 73 and 86
  // reach, 72 and 87 do not, and likewise down the column. Cells near the sheet's border, whose
  // windows reach past it, score as the flat sheet too.
  const Intrinsics k{.width = 160, .height = 120, .fx = 145, .fy = 145, .cx = 79.5, .cy = 59.5};
  Image<float> depth(k.width, k.height, 0.0f);
  for (int v = 10; v < 110; ++v) {
    for (int u = 20; u < 140; ++u) depth(u, v) = 2.5f;
  }
  depth(80, 60) += 0.01f;
  DepthMesh mesh;
  triangulate_sdc(depth, k, Rigid3f::Identity(), {}, mesh);
  // The scores of a row are powers taken over the row (squarings for a whole exponent, std::pow
  // otherwise); each must be the element function's.
  for (const float exponent : {1.0f, 96.0f, 12.5f}) {
    SCOPED_TRACE(exponent);
    OwnershipScore score;
    compute_smoothness(mesh, k, 0, {.window_cells = 13, .exponent = exponent, .same_surface_m = 0.03f}, score);
    const float flat = smoothness_score(1.0f, exponent);
    EXPECT_EQ(score.cell(72, 60), flat);
    EXPECT_LT(score.cell(73, 60), flat);
    EXPECT_LT(score.cell(86, 60), flat);
    EXPECT_EQ(score.cell(87, 60), flat);
    EXPECT_EQ(score.cell(80, 52), flat);
    EXPECT_LT(score.cell(80, 53), flat);
    EXPECT_LT(score.cell(80, 66), flat);
    EXPECT_EQ(score.cell(80, 67), flat);
    for (const auto& [u, v] : {std::pair{20, 10}, std::pair{138, 10}, std::pair{20, 108}, std::pair{138, 108}, std::pair{21, 60}, std::pair{80, 11}}) {
      EXPECT_EQ(score.cell(u, v), flat) << u << "," << v;
    }
    EXPECT_EQ(score.cell(19, 60), 0.0f);  // no triangle: no score
  }
}

TEST(Redundancy, SmoothnessRowPassesGiveTheElementFunctionsScores) {
  // A noisy sheet, so that the windows' ratios differ from cell to cell. With exponent 1 a cell's
  // score is its base itself (the clamped ratio / 0.6, a float times 1.0), so with any other
  // exponent it must be smoothness_power of that base (clamped at that exponent's lowest ratio),
  // rounded once: the row passes (squarings, or std::pow for a fractional exponent) against the
  // element function, cell by cell.
  const Intrinsics k{.width = 160, .height = 120, .fx = 145, .fy = 145, .cx = 79.5, .cy = 59.5};
  Image<float> depth(k.width, k.height, 0.0f);
  std::mt19937 random(7);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  for (int v = 10; v < 110; ++v) {
    for (int u = 20; u < 140; ++u) depth(u, v) = 2.5f + noise(random);
  }
  DepthMesh mesh;
  triangulate_sdc(depth, k, Rigid3f::Identity(), {}, mesh);
  const SmoothnessOptions base_options{.window_cells = 13, .exponent = 1, .same_surface_m = 0.06f};
  OwnershipScore bases;
  compute_smoothness(mesh, k, 0, base_options, bases);
  std::set<float> distinct;
  for (const float exponent : {96.0f, 12.5f, 7.0f}) {
    SCOPED_TRACE(exponent);
    SmoothnessOptions options = base_options;
    options.exponent = exponent;
    OwnershipScore score;
    compute_smoothness(mesh, k, 0, options, score);
    const float lowest_base = smoothness_lowest_ratio(exponent) / kSmoothnessReference;
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        const float base = bases.cell(u, v);
        const float expected = base > 0 ? static_cast<float>(smoothness_power(std::max(base, lowest_base), exponent)) : 0.0f;
        ASSERT_EQ(score.cell(u, v), expected) << u << "," << v;
        if (base > 0) distinct.insert(base);
      }
    }
  }
  EXPECT_GT(distinct.size(), 1000u);  // the sheet's windows gave many different ratios
}

TEST(Redundancy, SmoothnessScoreIsTheCorrectlyRoundedPower) {
  // Against the power multiplied out in extended precision (long double, 64-bit mantissa):
  // 96 products lose about 96 units of 2^−64, far below the float's half unit, so the float it
  // rounds to is the correctly rounded power. Every 97th float ratio between the lowest one and 1.
  const float lowest = smoothness_lowest_ratio(96.0f);
  int checked = 0;
  for (float ratio = lowest; ratio <= 1.0f; ratio = std::nextafter(ratio, 2.0f)) {
    for (int skip = 0; skip < 96 && ratio < 1.0f; ++skip) ratio = std::nextafter(ratio, 2.0f);
    const long double base = static_cast<long double>(ratio / kSmoothnessReference);
    long double power = 1;
    for (int i = 0; i < 96; ++i) power *= base;
    ASSERT_EQ(smoothness_score(ratio, 96.0f), static_cast<float>(power)) << ratio;
    ++checked;
  }
  EXPECT_GT(checked, 50000);
  // A fractional exponent: std::pow in double, rounded once.
  EXPECT_EQ(smoothness_score(0.5f, 12.5f), static_cast<float>(std::pow(static_cast<double>(0.5f / kSmoothnessReference), 12.5)));
}

TEST(Redundancy, SmoothnessScoreStaysInFloatRangeAndKeepsTheOrder) {
  for (const float exponent : {1.0f, 12.0f, 96.0f, 128.0f}) {
    float previous = 0;
    for (float ratio = 0.2f; ratio <= 1.0f; ratio += 0.01f) {
      const float score = smoothness_score(ratio, exponent);
      EXPECT_TRUE(std::isnormal(score)) << ratio << "^" << exponent;
      EXPECT_GE(score, previous) << ratio << "^" << exponent;
      previous = score;
    }
    EXPECT_EQ(smoothness_score(1.5f, exponent), smoothness_score(1.0f, exponent));
    EXPECT_GT(smoothness_score(0.6f, exponent), smoothness_score(0.55f, exponent));
  }
}

TEST(Redundancy, CellAreaCountsOnlyTheTrianglesThatExist) {
  // A unit-ish cell 2 m away; the bottom-right corner's depth stands for a pixel without a usable
  // value. The upper triangle's area must not depend on it, whatever it is.
  const float x0 = -0.01f, x1 = 0.01f, y0 = -0.01f, y1 = 0.01f;
  const float upper_only = cell_triangle_area(x0, x1, y0, y1, kUpperTriangle, 2.0f, 2.0f, 2.0f, 2.0f);
  EXPECT_GT(upper_only, 0.0f);
  for (const float z11 : {0.0f, -1.0f, 1e30f, std::numeric_limits<float>::infinity(), std::numeric_limits<float>::quiet_NaN()}) {
    EXPECT_EQ(cell_triangle_area(x0, x1, y0, y1, kUpperTriangle, 2.0f, 2.0f, 2.0f, z11), upper_only) << z11;
    EXPECT_EQ(cell_triangle_area(x0, x1, y0, y1, 0, 2.0f, 2.0f, 2.0f, z11), 0.0f) << z11;
  }
  EXPECT_EQ(cell_triangle_area(x0, x1, y0, y1, kUpperTriangle | kLowerTriangle, 2.0f, 2.0f, 2.0f, 2.0f), 2.0f * upper_only);
}

TEST(Redundancy, CoarseLevelPointsAreTheirFinePixelsPoints) {
  // A tilted plane seen by a rotated, shifted camera: coarse pixel (u, v) of level L is fine pixel
  // (u·2^L, v·2^L), and its point must be that pixel's, to the bit (the steps scale by powers of two).
  const Rigid3f world_from_depth = Eigen::Translation3f(0.3f, -1.2f, 1.4f) * Eigen::AngleAxisf(0.7f, Eigen::Vector3f(0.2f, 1.0f, -0.3f).normalized());
  Image<float> depth(kKinect.width, kKinect.height, 0.0f);
  for (int v = 100; v < 400; ++v) {
    for (int u = 150; u < 500; ++u) depth(u, v) = 2.0f + 0.001f * static_cast<float>(u) - 0.0005f * static_cast<float>(v);
  }
  DepthMesh fine;
  triangulate_sdc(depth, kKinect, world_from_depth, {}, fine);
  EXPECT_TRUE(fine.point(200, 150).isApprox(world_from_depth * unproject(kKinect, 200.0f, 150.0f, depth(200, 150)), 1e-5f));
  for (const int level : {1, 2}) {
    DepthMesh coarse;
    downsample_mesh(fine, level, depth_jump(SdcOptions{}), coarse);
    const int step = 1 << level;
    int compared = 0;
    for (int v = 0; v < coarse.height; v += 7) {
      for (int u = 0; u < coarse.width; u += 5) {
        if (coarse.depth[v * coarse.width + u] <= 0) continue;
        EXPECT_EQ(coarse.point(u, v), fine.point(u * step, v * step)) << "level " << level << " at " << u << ", " << v;
        ++compared;
      }
    }
    EXPECT_GT(compared, 100) << "level " << level;
  }
}

// The coarse levels copy and triangulate only each row's span of the subject: every coarse pixel
// must hold its fine pixel's depth and every coarse cell what sdc_cell gives on that subsampled
// depth (the threshold scaled), on ragged blobs with holes, steps and empty rows, in reused buffers.
TEST(Redundancy, CoarseLevelsMatchTheElementFunctionOnTheSubsampledDepth) {
  std::mt19937 random(5);
  DepthMesh fine, coarse;
  for (int frame = 0; frame < 30; ++frame) {
    const int width = 9 + static_cast<int>(random() % 60), height = 5 + static_cast<int>(random() % 30);
    Image<float> depth(width, height, 0.0f);
    for (int v = 0; v < height; ++v) {
      if (random() % 5 == 0) continue;  // an empty row
      const int a = static_cast<int>(random() % width), b = static_cast<int>(random() % width);
      for (int u = std::min(a, b); u <= std::max(a, b); ++u) {
        if (random() % 9 != 0) depth(u, v) = 2.0f + 0.02f * static_cast<float>(random() % 6);  // holes; steps of up to 10 cm
      }
    }
    const Intrinsics k{.width = width, .height = height, .fx = 100, .fy = 100, .cx = width / 2.0, .cy = height / 2.0};
    triangulate_sdc(depth, k, Rigid3f::Identity(), {}, fine);
    for (const int level : {1, 2}) {
      const DepthJump jump{0.03f};
      downsample_mesh(fine, level, jump, coarse);
      const int step = 1 << level, coarse_width = (width - 1) / step + 1, coarse_height = (height - 1) / step + 1;
      ASSERT_EQ(coarse.width, coarse_width);
      ASSERT_EQ(coarse.height, coarse_height);
      Image<float> subsampled(coarse_width, coarse_height, 0.0f);
      for (int v = 0; v < coarse_height; ++v) {
        for (int u = 0; u < coarse_width; ++u) subsampled(u, v) = depth(u * step, v * step);
      }
      for (int v = 0; v < coarse_height; ++v) {
        for (int u = 0; u < coarse_width; ++u) {
          const int cell = v * coarse_width + u;
          ASSERT_EQ(coarse.depth[cell], subsampled(u, v)) << "frame " << frame << ", level " << level << ", pixel " << u << ", " << v;
          const DepthJump scaled = jump.scaled(static_cast<float>(step));
          ASSERT_EQ(coarse.triangles[cell], sdc_cell(u, v, subsampled.data.data(), coarse_width, coarse_height, scaled))
              << "frame " << frame << ", level " << level << ", cell " << u << ", " << v;
        }
      }
    }
  }
}

// Meshes, coarse levels and ownership scores are reused from frame to frame and cleared only
// where the previous frame wrote: after a frame whose person filled a large box, a frame with a
// small one elsewhere must come out exactly as it does in fresh buffers.
TEST(Redundancy, ReusedBuffersGiveWhatFreshOnesGive) {
  const Intrinsics k{.width = 160, .height = 120, .fx = 145, .fy = 145, .cx = 79.5, .cy = 59.5};
  std::mt19937 random(3);
  std::normal_distribution<float> noise(0.0f, 0.005f);
  auto sheet = [&](int u0, int u1, int v0, int v1) {
    Image<float> depth(k.width, k.height, 0.0f);
    for (int v = v0; v < v1; ++v) {
      for (int u = u0; u < u1; ++u) depth(u, v) = 2.5f + noise(random);
    }
    return depth;
  };
  const Image<float> large = sheet(5, 150, 3, 115), small = sheet(100, 130, 70, 100);
  const SmoothnessOptions smoothness{.window_cells = 13, .exponent = 12, .same_surface_m = 0.03f};
  DepthMesh reused_mesh, reused_coarse, fresh_mesh, fresh_coarse;
  OwnershipScore reused_smoothness, reused_border, fresh_smoothness, fresh_border;
  for (const Image<float>* depth : {&large, &small}) {
    triangulate_sdc(*depth, k, Rigid3f::Identity(), {}, reused_mesh);
    downsample_mesh(reused_mesh, 1, DepthJump{0.06f}, reused_coarse);
    compute_smoothness(reused_mesh, k, 0, smoothness, reused_smoothness);
    compute_border_distance(reused_mesh, 0, 2, reused_border);
  }
  triangulate_sdc(small, k, Rigid3f::Identity(), {}, fresh_mesh);
  downsample_mesh(fresh_mesh, 1, DepthJump{0.06f}, fresh_coarse);
  compute_smoothness(fresh_mesh, k, 0, smoothness, fresh_smoothness);
  compute_border_distance(fresh_mesh, 0, 2, fresh_border);
  EXPECT_EQ(reused_mesh.triangles, fresh_mesh.triangles);
  EXPECT_EQ(reused_coarse.depth, fresh_coarse.depth);
  EXPECT_EQ(reused_coarse.triangles, fresh_coarse.triangles);
  EXPECT_EQ(reused_smoothness.cells, fresh_smoothness.cells);
  EXPECT_EQ(reused_border.cells, fresh_border.cells);
  // Not a vacuous comparison: the small sheet has triangles and scores, and the large one's are gone.
  EXPECT_GT(fresh_mesh.triangle_count(), 1000);
  EXPECT_GT(fresh_smoothness.cell(115, 85), 0.0f);
  EXPECT_EQ(reused_smoothness.cell(20, 20), 0.0f);
  EXPECT_EQ(reused_coarse.triangles[10 * reused_coarse.width + 10], 0);
}

TEST(Zipper, PairsAreScheduledWithoutSharingACamera) {
  const std::vector<std::pair<int, int>> ring = {{0, 1}, {1, 2}, {2, 3}, {0, 3}, {0, 2}};
  const PairRounds rounds = schedule_pairs(ring);
  std::set<int> scheduled;
  for (size_t r = 0; r < rounds.count(); ++r) {
    std::set<int> used;
    int previous = -1;
    for (const int k : rounds.round(r)) {
      ASSERT_GE(k, 0);
      ASSERT_LT(k, static_cast<int>(ring.size()));
      EXPECT_TRUE(scheduled.insert(k).second);
      EXPECT_GT(k, previous);  // in the given order
      previous = k;
      const auto [a, b] = ring[k];
      EXPECT_TRUE(used.insert(a).second);
      EXPECT_TRUE(used.insert(b).second);
      EXPECT_EQ(rounds.round_of_pair[k], static_cast<int>(r));
    }
  }
  EXPECT_EQ(scheduled.size(), ring.size());
  EXPECT_LE(rounds.count(), 3u);
  // Greedy in the given order: (0, 1) and (2, 3) first, then (1, 2) and (0, 3), then (0, 2).
  EXPECT_EQ(rounds.round_of_pair, (std::vector<int>{0, 1, 0, 1, 2}));
  // A second schedule into the same arrays gives the same rounds.
  PairRounds reused = schedule_pairs({{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}, {4, 5}});
  schedule_pairs(ring, reused);
  EXPECT_EQ(reused.by_round, rounds.by_round);
  EXPECT_EQ(reused.round_begin, rounds.round_begin);
}

}  // namespace
}  // namespace zipfusion
