#include "zipfusion/core/mesh.h"

#include <gtest/gtest.h>

#include <vector>

#include "zipfusion/core/mesh_test_util.h"

namespace zipfusion {
namespace {

// A flat square of cells × cells quads with its corner at x.
TriangleMesh square_at(float x, int cells) {
  return grid_mesh(cells, cells, [x](float u, float v) { return Eigen::Vector3f(x + 0.1f * u, 0, 0.1f * v); });
}

TEST(Mesh, ConnectedComponentsLabelTriangles) {
  TriangleMesh mesh = square_at(0.0f, 2);  // 8 triangles
  mesh.append(square_at(1.0f, 1));         // 2 triangles
  mesh.triangles.emplace_back(0, 0, 0);                    // degenerate, on vertex 0: the first component's
  const MeshComponents c = connected_components(mesh);
  ASSERT_EQ(c.count(), 2);
  EXPECT_EQ(c.triangle_counts, (std::vector<int>{9, 2}));
  EXPECT_EQ(c.triangle_component[0], 0);
  EXPECT_EQ(c.triangle_component[8], 1);
  EXPECT_EQ(c.triangle_component[10], 0);
}

// Pieces under the size go, the others stay in their order; the scratch serves meshes of any
// size in turn.
TEST(Mesh, RemoveSmallComponentsKeepsTheLargeOnesInOrder) {
  TriangleMesh mesh = square_at(1.0f, 1);  // 2 triangles
  mesh.append(square_at(0.0f, 10));        // 200
  mesh.append(square_at(2.0f, 2));         // 8
  const TriangleMesh before = mesh;
  MeshComponents scratch;
  EXPECT_EQ(remove_small_components(mesh, 0, scratch), 0);
  EXPECT_EQ(remove_small_components(mesh, 1, scratch), 0);
  EXPECT_EQ(remove_small_components(mesh, 8, scratch), 2);
  ASSERT_EQ(mesh.triangle_count(), 208u);
  EXPECT_EQ(mesh.triangles.front(), before.triangles[2]);
  EXPECT_EQ(mesh.triangles.back(), before.triangles.back());
  EXPECT_EQ(mesh.positions.size(), before.positions.size());  // vertices stay
  EXPECT_EQ(remove_small_components(mesh, 201, scratch), 208);
  EXPECT_TRUE(mesh.triangles.empty());

  TriangleMesh small = square_at(0.0f, 1);
  small.append(square_at(1.0f, 2));
  EXPECT_EQ(remove_small_components(small, 3, scratch), 2);
  EXPECT_EQ(small.triangle_count(), 8u);
}

}  // namespace
}  // namespace zipfusion
