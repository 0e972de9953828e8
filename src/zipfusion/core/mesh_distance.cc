#include "zipfusion/core/mesh_distance.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numeric>

namespace zipfusion {
namespace {

constexpr int kLeafSize = 4;        // triangles per leaf at most
constexpr int kSahMaxDepth = 40;    // deeper nodes split at the median: depth <= 40 + 31
constexpr int kMaxStackDepth = 96;  // traversal stack: tree depth + 1

struct BuildInput {
  std::vector<Eigen::Vector3f> box_min, box_max, centroid;  // per triangle
};

float half_area(const Eigen::Vector3f& box_min, const Eigen::Vector3f& box_max) {
  const Eigen::Vector3f e = (box_max - box_min).cwiseMax(0.0f);
  return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
}

// Splits order[begin, end) in two and returns the first index of the second part: the binned
// surface-area heuristic (Wald 2007) over the centroids, or the median of the widest centroid
// axis when all centroids coincide or the heuristic finds no split.
int split(const BuildInput& in, int begin, int end, const Eigen::Vector3f& centroid_min,
          const Eigen::Vector3f& centroid_max, bool use_sah, std::vector<int>& order) {
  constexpr int kBins = 16;
  const Eigen::Vector3f extent = centroid_max - centroid_min;
  float best_cost = std::numeric_limits<float>::infinity();
  int best_axis = -1, best_bin = 0;
  for (int axis = 0; axis < 3 && use_sah; ++axis) {
    if (!(extent[axis] > 0)) continue;
    const float scale = kBins / extent[axis];
    Eigen::Vector3f bin_min[kBins], bin_max[kBins];
    int bin_count[kBins] = {};
    for (int b = 0; b < kBins; ++b) {
      bin_min[b].setConstant(std::numeric_limits<float>::infinity());
      bin_max[b].setConstant(-std::numeric_limits<float>::infinity());
    }
    for (int k = begin; k < end; ++k) {
      const int i = order[k];
      const int b =
          std::min(kBins - 1, static_cast<int>((in.centroid[i][axis] - centroid_min[axis]) * scale));
      ++bin_count[b];
      bin_min[b] = bin_min[b].cwiseMin(in.box_min[i]);
      bin_max[b] = bin_max[b].cwiseMax(in.box_max[i]);
    }
    // cost of splitting after bin b: left area * left count + right area * right count.
    float right_cost[kBins];
    Eigen::Vector3f acc_min = bin_min[kBins - 1], acc_max = bin_max[kBins - 1];
    int acc_count = bin_count[kBins - 1];
    for (int b = kBins - 2; b >= 0; --b) {
      right_cost[b] = half_area(acc_min, acc_max) * static_cast<float>(acc_count);
      acc_min = acc_min.cwiseMin(bin_min[b]);
      acc_max = acc_max.cwiseMax(bin_max[b]);
      acc_count += bin_count[b];
    }
    acc_min = bin_min[0];
    acc_max = bin_max[0];
    acc_count = bin_count[0];
    for (int b = 0; b < kBins - 1; ++b) {
      const float cost = half_area(acc_min, acc_max) * static_cast<float>(acc_count) + right_cost[b];
      if (acc_count > 0 && acc_count < end - begin && cost < best_cost) {
        best_cost = cost;
        best_axis = axis;
        best_bin = b;
      }
      acc_min = acc_min.cwiseMin(bin_min[b + 1]);
      acc_max = acc_max.cwiseMax(bin_max[b + 1]);
      acc_count += bin_count[b + 1];
    }
  }
  if (best_axis >= 0) {
    const float scale = kBins / extent[best_axis];
    const auto middle = std::partition(order.begin() + begin, order.begin() + end, [&](int i) {
      const int b = std::min(kBins - 1,
                             static_cast<int>((in.centroid[i][best_axis] - centroid_min[best_axis]) * scale));
      return b <= best_bin;
    });
    return static_cast<int>(middle - order.begin());
  }
  int axis = 0;
  extent.maxCoeff(&axis);
  const int mid = begin + (end - begin) / 2;
  std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                   [&](int l, int r) { return in.centroid[l][axis] < in.centroid[r][axis]; });
  return mid;
}

}  // namespace

MeshDistance::MeshDistance(const TriangleMesh& mesh) {
  const int n = static_cast<int>(mesh.triangles.size());
  if (n == 0) return;

  BuildInput in;
  in.box_min.resize(n);
  in.box_max.resize(n);
  in.centroid.resize(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3i& t = mesh.triangles[i];
    assert((t.array() >= 0).all() && (t.array() < static_cast<int>(mesh.positions.size())).all());
    const Eigen::Vector3f& a = mesh.positions[t[0]];
    const Eigen::Vector3f& b = mesh.positions[t[1]];
    const Eigen::Vector3f& c = mesh.positions[t[2]];
    in.box_min[i] = a.cwiseMin(b).cwiseMin(c);
    in.box_max[i] = a.cwiseMax(b).cwiseMax(c);
    in.centroid[i] = 0.5f * (in.box_min[i] + in.box_max[i]);
  }

  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  nodes_.reserve(2 * static_cast<size_t>((n + kLeafSize - 1) / kLeafSize) + 1);
  nodes_.emplace_back();

  // Depth-first build with an explicit stack of (node, range of order, depth).
  struct Task {
    int node, begin, end, depth;
  };
  std::vector<Task> tasks = {{0, 0, n, 0}};
  while (!tasks.empty()) {
    const Task task = tasks.back();
    tasks.pop_back();
    Eigen::Vector3f box_min = in.box_min[order[task.begin]];
    Eigen::Vector3f box_max = in.box_max[order[task.begin]];
    Eigen::Vector3f centroid_min = in.centroid[order[task.begin]];
    Eigen::Vector3f centroid_max = centroid_min;
    for (int k = task.begin + 1; k < task.end; ++k) {
      const int i = order[k];
      box_min = box_min.cwiseMin(in.box_min[i]);
      box_max = box_max.cwiseMax(in.box_max[i]);
      centroid_min = centroid_min.cwiseMin(in.centroid[i]);
      centroid_max = centroid_max.cwiseMax(in.centroid[i]);
    }
    nodes_[task.node].box_min = box_min;
    nodes_[task.node].box_max = box_max;
    if (task.end - task.begin <= kLeafSize) {
      nodes_[task.node].first = task.begin;
      nodes_[task.node].count = task.end - task.begin;
      continue;
    }
    const int mid =
        split(in, task.begin, task.end, centroid_min, centroid_max, task.depth < kSahMaxDepth, order);
    const int children = static_cast<int>(nodes_.size());
    nodes_.emplace_back();
    nodes_.emplace_back();
    nodes_[task.node].first = children;
    nodes_[task.node].count = 0;
    tasks.push_back({children, task.begin, mid, task.depth + 1});
    tasks.push_back({children + 1, mid, task.end, task.depth + 1});
  }

  corners_.reserve(3 * static_cast<size_t>(n));
  triangle_ids_ = std::move(order);
  for (const int i : triangle_ids_) {
    for (int k = 0; k < 3; ++k) corners_.push_back(mesh.positions[mesh.triangles[i][k]]);
  }
}

namespace {

template <typename Node>
inline float box_distance2(const Eigen::Vector3f& p, const Node& node) {
  return (node.box_min - p).cwiseMax(p - node.box_max).cwiseMax(0.0f).squaredNorm();
}

}  // namespace

MeshDistance::Hit MeshDistance::closest(const Eigen::Vector3f& p, float max_distance) const {
  Hit hit;
  if (nodes_.empty() || !p.allFinite() || !(max_distance >= 0)) return hit;
  float best2 = max_distance * max_distance;  // inf stays inf
  int best = -1;                              // leaf-order index

  struct Entry {
    int node;
    float distance2;
  };
  Entry stack[kMaxStackDepth];
  int top = 0;
  stack[top++] = {0, box_distance2(p, nodes_[0])};
  while (top > 0) {
    const Entry entry = stack[--top];
    if (entry.distance2 > best2) continue;
    const Node& node = nodes_[entry.node];
    if (node.count > 0) {
      for (int k = node.first; k < node.first + node.count; ++k) {
        const Eigen::Vector3f q =
            closest_point_on_triangle(p, corners_[3 * k], corners_[3 * k + 1], corners_[3 * k + 2]);
        const float d2 = (q - p).squaredNorm();
        if (d2 < best2 || (best < 0 && d2 <= best2)) {
          best2 = d2;
          best = k;
          hit.point = q;
        }
      }
      continue;
    }
    // Visit the nearer child first: push it last.
    const float d_left = box_distance2(p, nodes_[node.first]);
    const float d_right = box_distance2(p, nodes_[node.first + 1]);
    const bool left_first = d_left <= d_right;
    const Entry near_entry = left_first ? Entry{node.first, d_left} : Entry{node.first + 1, d_right};
    const Entry far_entry = left_first ? Entry{node.first + 1, d_right} : Entry{node.first, d_left};
    assert(top + 2 <= kMaxStackDepth);
    if (far_entry.distance2 <= best2) stack[top++] = far_entry;
    if (near_entry.distance2 <= best2) stack[top++] = near_entry;
  }
  if (best >= 0) {
    hit.distance = std::sqrt(best2);
    hit.triangle = triangle_ids_[best];
  }
  return hit;
}

}  // namespace zipfusion
