#include "zipfusion/eval/eval.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <optional>
#include <sstream>
#include <string>

#include "zipfusion/core/camera.h"
#include "zipfusion/core/error.h"
#include "zipfusion/core/mesh_distance.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/core/rasterizer.h"

namespace zipfusion {
namespace {

constexpr int kMaxSubdivision = 1024;  // sub-triangles per edge at most
constexpr int kChunk = 512;            // triangles per parallel work item
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double triangle_area(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c) {
  return 0.5 * (b - a).cast<double>().cross((c - a).cast<double>()).norm();
}

// Sub-triangles per edge for a triangle of that area (see the file comment of eval.h).
int subdivision(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c, double area, double spacing) {
  const double max_edge = std::sqrt(std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()}));
  const double n = std::ceil(std::max(std::sqrt(area) / spacing, max_edge / (2 * spacing)));
  if (!(n >= 1)) return 1;  // also NaN
  return n >= kMaxSubdivision ? kMaxSubdivision : static_cast<int>(n);
}

// Calls f(point) for the centroids of the n² sub-triangles of the barycentric grid with n steps
// per edge, in a fixed order.
template <typename F>
void for_each_sample(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c, int n, F&& f) {
  const Eigen::Vector3f ab = (b - a) / static_cast<float>(n);
  const Eigen::Vector3f ac = (c - a) / static_cast<float>(n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; i + j < n; ++j) {
      f(a + (static_cast<float>(i) + 1.0f / 3) * ab + (static_cast<float>(j) + 1.0f / 3) * ac);
      if (i + j < n - 1) f(a + (static_cast<float>(i) + 2.0f / 3) * ab + (static_cast<float>(j) + 2.0f / 3) * ac);
    }
  }
}

// The triangles whose centroid lies in the volume (all without one), with only the vertices
// they use (numbered by first use), colours kept.
TriangleMesh crop_to_volume(const TriangleMesh& mesh, const std::optional<Box3d>& volume) {
  assert(mesh.colors.empty() || mesh.colors.size() == mesh.positions.size());
  TriangleMesh out;
  std::vector<int> remap(mesh.positions.size(), -1);
  out.triangles.reserve(mesh.triangles.size());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    assert((t.array() >= 0).all() && (t.array() < static_cast<int>(mesh.positions.size())).all());
    if (volume) {
      const Eigen::Vector3d centroid =
          (mesh.positions[t[0]].cast<double>() + mesh.positions[t[1]].cast<double>() + mesh.positions[t[2]].cast<double>()) / 3;
      if (!volume->contains(centroid)) continue;
    }
    Eigen::Vector3i mapped;
    for (int k = 0; k < 3; ++k) {
      int& index = remap[t[k]];
      if (index < 0) {
        index = static_cast<int>(out.positions.size());
        out.positions.push_back(mesh.positions[t[k]]);
        if (mesh.has_colors()) out.colors.push_back(mesh.colors[t[k]]);
      }
      mapped[k] = index;
    }
    out.triangles.push_back(mapped);
  }
  return out;
}


// One camera's rendering of the truth, for the observed test.
struct CameraView {
  Intrinsics intrinsics;
  Rigid3f cam_from_world;
  RenderBuffers buffers;
};

// Element function: whether the camera observes a true surface point (see eval.h).
bool observed_by(const CameraView& view, const Eigen::Vector3f& p, float min_range, float max_range, float tolerance) {
  const Eigen::Vector3f q = view.cam_from_world * p;
  const float z = q.z();
  if (!(z >= min_range && z <= max_range)) return false;
  const Eigen::Vector2f px = project_pinhole(view.intrinsics, q);
  const Image<float>& depth = view.buffers.depth;
  // The nearest pixel must lie in the image.
  if (!(px.x() >= -0.5f && px.x() < static_cast<float>(depth.width) - 0.5f && px.y() >= -0.5f &&
        px.y() < static_cast<float>(depth.height) - 0.5f)) {
    return false;
  }
  const int u0 = static_cast<int>(std::floor(px.x())), v0 = static_cast<int>(std::floor(px.y()));
  float lo = kNoDepth, hi = -kNoDepth;
  for (int v = v0; v <= v0 + 1; ++v) {
    for (int u = u0; u <= u0 + 1; ++u) {
      if (!depth.contains(u, v)) continue;
      const float d = depth(u, v);
      if (d == kNoDepth) continue;
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
  }
  return lo - tolerance <= z && z <= hi + tolerance;
}

std::string format_number(double value) {
  std::ostringstream s;
  s << value;
  return s.str();
}

}  // namespace

void EvalOptions::validate() const {
  auto fail = [](const std::string& field, const std::string& problem, double value) {
    throw InvalidInput("EvalOptions: " + field + ": " + problem + ", got " + format_number(value));
  };
  if (!(completeness_threshold_m > 0 && completeness_threshold_m <= 1)) fail("completeness_threshold_m", "must be in (0, 1] metres", completeness_threshold_m);
  if (!(visibility_tolerance_m >= 0 && visibility_tolerance_m <= 1)) fail("visibility_tolerance_m", "must be in [0, 1] metres", visibility_tolerance_m);
  if (!(sample_spacing_m >= 1e-4 && sample_spacing_m <= 1)) fail("sample_spacing_m", "must be in [0.0001, 1] metres", sample_spacing_m);
  if (!(color_max_distance_m >= 0 && color_max_distance_m <= 1)) fail("color_max_distance_m", "must be in [0, 1] metres", color_max_distance_m);
  if (min_component_triangles < 1) fail("min_component_triangles", "must be >= 1", min_component_triangles);
  if (!(min_range_m >= 0 && std::isfinite(min_range_m))) fail("min_range_m", "must be >= 0 metres", min_range_m);
  if (!(max_range_m > min_range_m && std::isfinite(max_range_m))) fail("max_range_m", "must be finite and above min_range_m", max_range_m);
  if (num_threads < 0) fail("num_threads", "must be >= 0", num_threads);
}


namespace {

// The undirected edge (a, b) as one sortable key, the same for (b, a).
std::uint64_t undirected_edge_key(std::uint32_t a, std::uint32_t b) { return static_cast<std::uint64_t>(std::min(a, b)) << 32 | std::max(a, b); }

// A triangle that names one vertex twice: no area, no edges of its own; the counts skip it.
bool repeats_a_vertex(const Eigen::Vector3i& t) { return t[0] == t[1] || t[1] == t[2] || t[2] == t[0]; }

}  // namespace

int count_non_manifold_edges(const TriangleMesh& mesh) {
  std::vector<std::uint64_t> edges;
  edges.reserve(3 * mesh.triangles.size());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    if (repeats_a_vertex(t)) continue;
    for (int k = 0; k < 3; ++k) {
      const auto a = static_cast<std::uint32_t>(t[k]), b = static_cast<std::uint32_t>(t[(k + 1) % 3]);
      edges.push_back(undirected_edge_key(a, b));
    }
  }
  std::sort(edges.begin(), edges.end());
  int count = 0;
  for (size_t i = 0; i < edges.size();) {
    size_t j = i + 1;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    count += j - i > 2;
    i = j;
  }
  return count;
}

int count_doubled_triangles(const TriangleMesh& mesh) {
  std::vector<std::array<int, 3>> corners;
  corners.reserve(mesh.triangles.size());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    if (repeats_a_vertex(t)) continue;
    std::array<int, 3> sorted{t[0], t[1], t[2]};
    std::sort(sorted.begin(), sorted.end());
    corners.push_back(sorted);
  }
  std::sort(corners.begin(), corners.end());
  return static_cast<int>(corners.end() - std::unique(corners.begin(), corners.end()));
}

int count_folded_edges(const TriangleMesh& mesh) {
  // Each directed edge as (undirected key, triangle and whether it runs from the lower index).
  struct EdgeUse {
    std::uint64_t key;
    int triangle;
    bool forward;
  };
  std::vector<EdgeUse> uses;
  uses.reserve(3 * mesh.triangles.size());
  std::vector<Eigen::Vector3f> normals(mesh.triangles.size());
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    const Eigen::Vector3i& t = mesh.triangles[i];
    if (repeats_a_vertex(t)) continue;
    const Eigen::Vector3f& a = mesh.positions[t[0]];
    normals[i] = (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a);
    if (!(normals[i].squaredNorm() > 0)) continue;
    normals[i].normalize();
    for (int k = 0; k < 3; ++k) {
      const auto from = static_cast<std::uint32_t>(t[k]), to = static_cast<std::uint32_t>(t[(k + 1) % 3]);
      uses.push_back({undirected_edge_key(from, to), static_cast<int>(i), from < to});
    }
  }
  std::sort(uses.begin(), uses.end(), [](const EdgeUse& x, const EdgeUse& y) { return x.key < y.key || (x.key == y.key && x.triangle < y.triangle); });
  int count = 0;
  for (size_t i = 0; i < uses.size();) {
    size_t j = i + 1;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    if (j - i == 2) {
      // Consistently oriented neighbours run the edge in opposite directions; a pair that runs it
      // the same way is compared as if the second were turned over.
      const float sign = uses[i].forward != uses[i + 1].forward ? 1.0f : -1.0f;
      count += sign * normals[uses[i].triangle].dot(normals[uses[i + 1].triangle]) < -0.5f;
    }
    i = j;
  }
  return count;
}

double surface_area(const TriangleMesh& mesh) {
  double area = 0;
  for (const Eigen::Vector3i& t : mesh.triangles) area += triangle_area(mesh.positions[t[0]], mesh.positions[t[1]], mesh.positions[t[2]]);
  return area;
}

FrameQuality evaluate_frame(const TriangleMesh& reconstruction, const TriangleMesh& truth, const Rig& true_rig,
                            const std::optional<Box3d>& volume, const EvalOptions& options) {
  options.validate();
  const int threads = options.num_threads;
  const double spacing = options.sample_spacing_m;
  FrameQuality q;

  // --- Topology of the reconstruction inside the volume ---------------------------------------
  const TriangleMesh recon = crop_to_volume(reconstruction, volume);
  q.triangles = static_cast<int>(recon.triangle_count());
  q.vertices = static_cast<int>(recon.vertex_count());
  const MeshComponents components = connected_components(recon);
  q.components = components.count();
  q.large_components = static_cast<int>(std::count_if(components.triangle_counts.begin(), components.triangle_counts.end(),
                                                      [&](int n) { return n >= options.min_component_triangles; }));
  q.non_manifold_edges = count_non_manifold_edges(recon);
  q.folded_edges = count_folded_edges(recon);
  q.doubled_triangles = count_doubled_triangles(recon);

  // --- Distance structures and the truth as each camera sees it, built side by side -------------
  const int cameras = static_cast<int>(true_rig.cameras.size());
  std::optional<MeshDistance> recon_distance, truth_distance;
  std::vector<CameraView> views(cameras);
  parallel_for(
      0, cameras + 2,
      [&](int task) {
        if (task == 0) {
          recon_distance.emplace(recon);
        } else if (task == cameras + 1) {
          truth_distance.emplace(truth);
        } else {
          const CameraModel& cam = true_rig.cameras[task - 1];
          CameraView& view = views[task - 1];
          view.intrinsics = cam.depth_intrinsics;
          view.cam_from_world = cam.world_from_depth.inverse().cast<float>();
          view.buffers.reset(cam.depth_intrinsics, false);
          rasterize_mesh(truth, cam.depth_intrinsics, cam.world_from_depth.inverse(), view.buffers);
        }
      },
      threads);

  // --- Accuracy: reconstruction samples -> truth ------------------------------------------------
  const int recon_triangles = q.triangles;
  std::vector<int> recon_n(recon_triangles);
  std::vector<double> recon_area(recon_triangles);
  std::vector<std::int64_t> first_sample(recon_triangles + 1, 0);
  for (int i = 0; i < recon_triangles; ++i) {
    const Eigen::Vector3i& t = recon.triangles[i];
    const Eigen::Vector3f &a = recon.positions[t[0]], &b = recon.positions[t[1]], &c = recon.positions[t[2]];
    recon_area[i] = triangle_area(a, b, c);
    recon_n[i] = subdivision(a, b, c, recon_area[i], spacing);
    first_sample[i + 1] = first_sample[i] + static_cast<std::int64_t>(recon_n[i]) * recon_n[i];
  }
  std::vector<float> sample_distance(first_sample.back());
  const int recon_chunks = (recon_triangles + kChunk - 1) / kChunk;
  parallel_for(
      0, recon_chunks,
      [&](int chunk) {
        // d(p) <= d(previous) + |p - previous|: a bound that makes the next query cheap, since
        // consecutive samples are close together. It changes the speed only, not the distance.
        float previous_distance = std::numeric_limits<float>::infinity();
        Eigen::Vector3f previous = Eigen::Vector3f::Zero();
        const int end = std::min(recon_triangles, (chunk + 1) * kChunk);
        for (int i = chunk * kChunk; i < end; ++i) {
          const Eigen::Vector3i& t = recon.triangles[i];
          std::int64_t k = first_sample[i];
          for_each_sample(recon.positions[t[0]], recon.positions[t[1]], recon.positions[t[2]], recon_n[i], [&](const Eigen::Vector3f& p) {
            const float bound = previous_distance + (p - previous).norm();
            MeshDistance::Hit hit = truth_distance->closest(p, bound * 1.0001f + 1e-6f);
            if (hit.triangle < 0) hit = truth_distance->closest(p);
            sample_distance[k++] = hit.distance;
            previous_distance = hit.distance;
            previous = p;
          });
        }
      },
      threads);
  {
    std::vector<std::pair<float, float>> weighted;  // (distance, weight)
    weighted.reserve(sample_distance.size());
    double total_weight = 0, weighted_sum = 0;
    for (int i = 0; i < recon_triangles; ++i) {
      const double weight = recon_area[i] / (static_cast<double>(recon_n[i]) * recon_n[i]);
      q.reconstruction_area_m2 += recon_area[i];
      for (std::int64_t k = first_sample[i]; k < first_sample[i + 1]; ++k) {
        weighted.emplace_back(sample_distance[k], static_cast<float>(weight));
        total_weight += weight;
        weighted_sum += weight * sample_distance[k];
      }
    }
    if (total_weight > 0 && truth_distance->triangle_count() > 0) {
      q.accuracy_mean_mm = 1000 * weighted_sum / total_weight;
      std::sort(weighted.begin(), weighted.end());
      double cumulative = 0;
      q.accuracy_p95_mm = 1000.0 * weighted.back().first;
      for (const auto& [distance, weight] : weighted) {
        cumulative += weight;
        if (cumulative >= 0.95 * total_weight) {
          q.accuracy_p95_mm = 1000.0 * distance;
          break;
        }
      }
    } else {
      q.accuracy_mean_mm = q.accuracy_p95_mm = kNaN;
    }
  }

  // --- Completeness: observed true samples -> reconstruction -------------------------------------
  const int truth_triangles = static_cast<int>(truth.triangle_count());
  struct TruthSums {
    double area = 0, observed = 0, covered = 0;
  };
  std::vector<TruthSums> truth_sums(truth_triangles);
  const float min_range = static_cast<float>(options.min_range_m), max_range = static_cast<float>(options.max_range_m);
  const float tolerance = static_cast<float>(options.visibility_tolerance_m);
  const float threshold = static_cast<float>(options.completeness_threshold_m);
  parallel_for(
      0, (truth_triangles + kChunk - 1) / kChunk,
      [&](int chunk) {
        const int end = std::min(truth_triangles, (chunk + 1) * kChunk);
        for (int i = chunk * kChunk; i < end; ++i) {
          const Eigen::Vector3i& t = truth.triangles[i];
          const Eigen::Vector3f &a = truth.positions[t[0]], &b = truth.positions[t[1]], &c = truth.positions[t[2]];
          const double area = triangle_area(a, b, c);
          const int n = subdivision(a, b, c, area, spacing);
          const double weight = area / (static_cast<double>(n) * n);
          TruthSums sums;
          for_each_sample(a, b, c, n, [&](const Eigen::Vector3f& p) {
            if (volume && !volume->contains(p.cast<double>())) return;
            sums.area += weight;
            bool observed = false;
            for (int cam = 0; cam < cameras && !observed; ++cam) observed = observed_by(views[cam], p, min_range, max_range, tolerance);
            if (!observed) return;
            sums.observed += weight;
            if (recon_distance->closest(p, threshold).triangle >= 0) sums.covered += weight;
          });
          truth_sums[i] = sums;
        }
      },
      threads);
  double covered = 0;
  for (const TruthSums& sums : truth_sums) {
    q.true_area_m2 += sums.area;
    q.observed_true_area_m2 += sums.observed;
    covered += sums.covered;
  }
  if (q.observed_true_area_m2 > 0) {
    q.completeness = covered / q.observed_true_area_m2;
    q.area_ratio = q.reconstruction_area_m2 / q.observed_true_area_m2;
  } else {
    q.completeness = q.area_ratio = kNaN;
  }

  // --- Colour: reconstruction vertices -> colour of the closest true point -----------------------
  q.color_error = kNaN;
  if (recon.has_colors() && truth.has_colors()) {
    assert(truth.colors.size() == truth.positions.size());
    const int vertices = q.vertices;
    std::vector<float> vertex_error(vertices);  // NaN where no true surface is close
    const float max_distance = static_cast<float>(options.color_max_distance_m);
    parallel_for(
        0, vertices,
        [&](int v) {
          const Eigen::Vector3f& p = recon.positions[v];
          const MeshDistance::Hit hit = truth_distance->closest(p, max_distance);
          if (hit.triangle < 0) {
            vertex_error[v] = std::numeric_limits<float>::quiet_NaN();
            return;
          }
          // Barycentric coordinates of the closest point (Ericson §3.4), clamped for rounding.
          const Eigen::Vector3i& t = truth.triangles[hit.triangle];
          const Eigen::Vector3d a = truth.positions[t[0]].cast<double>();
          const Eigen::Vector3d v0 = truth.positions[t[1]].cast<double>() - a, v1 = truth.positions[t[2]].cast<double>() - a;
          const Eigen::Vector3d v2 = hit.point.cast<double>() - a;
          const double d00 = v0.dot(v0), d01 = v0.dot(v1), d11 = v1.dot(v1), d20 = v2.dot(v0), d21 = v2.dot(v1);
          const double denominator = d00 * d11 - d01 * d01;
          Eigen::Vector3d w(1, 0, 0);  // degenerate triangle: its first corner
          if (denominator > 0) {
            const double w1 = std::clamp((d11 * d20 - d01 * d21) / denominator, 0.0, 1.0);
            const double w2 = std::clamp((d00 * d21 - d01 * d20) / denominator, 0.0, 1.0 - w1);
            w = {1 - w1 - w2, w1, w2};
          }
          const Rgb8 c0 = truth.colors[t[0]], c1 = truth.colors[t[1]], c2 = truth.colors[t[2]];
          const Rgb8 mine = recon.colors[v];
          const double r = w[0] * c0.r + w[1] * c1.r + w[2] * c2.r;
          const double g = w[0] * c0.g + w[1] * c1.g + w[2] * c2.g;
          const double b = w[0] * c0.b + w[1] * c1.b + w[2] * c2.b;
          vertex_error[v] = static_cast<float>((std::abs(mine.r - r) + std::abs(mine.g - g) + std::abs(mine.b - b)) / 3);
        },
        threads);
    double sum = 0;
    for (const float e : vertex_error) {
      if (std::isnan(e)) continue;
      sum += e;
      q.color_vertices++;
    }
    if (q.color_vertices > 0) q.color_error = sum / q.color_vertices;
  }
  return q;
}

}  // namespace zipfusion
