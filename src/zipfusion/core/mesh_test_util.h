#pragma once
//! \file
//! Meshes that several tests build (header only, for tests).

#include <functional>

#include "zipfusion/core/mesh.h"

namespace zipfusion {

//! A grid of nu × nv quads, two triangles each, vertex (i, j) at point(i / nu, j / nv) and
//! numbered j·(nu + 1) + i; no colours.
inline TriangleMesh grid_mesh(int nu, int nv, const std::function<Eigen::Vector3f(float, float)>& point) {
  TriangleMesh mesh;
  for (int j = 0; j <= nv; ++j) {
    for (int i = 0; i <= nu; ++i) mesh.positions.push_back(point(static_cast<float>(i) / nu, static_cast<float>(j) / nv));
  }
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const int a = j * (nu + 1) + i;
      mesh.triangles.emplace_back(a, a + 1, a + nu + 2);
      mesh.triangles.emplace_back(a, a + nu + 2, a + nu + 1);
    }
  }
  return mesh;
}

}  // namespace zipfusion
