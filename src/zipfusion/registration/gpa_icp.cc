#include "zipfusion/registration/gpa_icp.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <nanoflann.hpp>
#include <Eigen/Eigenvalues>
#include <numbers>

#include "zipfusion/core/depth_noise.h"
#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"

namespace zipfusion {

void RegistrationOptions::validate() const {
  if (coarsest_level < 0 || coarsest_level > 5) throw InvalidInput("--coarsest-level: must be in [0, 5]");
  if (finest_level < 0 || finest_level > coarsest_level) throw InvalidInput("--finest-level: must be in [0, --coarsest-level]");
  if (iterations_per_level < 1 || iterations_per_level > 100) throw InvalidInput("--iterations: must be in [1, 100] per level");
  if (!(start_distance_m > 0)) throw InvalidInput("--start-distance: must be positive (metres)");
  if (!(end_distance_m > 0 && end_distance_m <= start_distance_m)) throw InvalidInput("--end-distance: must be in (0, --start-distance] (metres)");
  if (!(max_normal_angle_deg > 0 && max_normal_angle_deg <= 180)) throw InvalidInput("registration.max_normal_angle_deg: must be in (0, 180]");
  if (!(max_view_angle_deg > 0 && max_view_angle_deg <= 90)) throw InvalidInput("registration.max_view_angle_deg: must be in (0, 90]");
  if (!(max_pair_view_angle_deg > 0 && max_pair_view_angle_deg <= 90)) throw InvalidInput("--max-pair-view-angle: must be in (0, 90] degrees");
  if (!(min_noise_cos >= 0 && min_noise_cos <= 1)) throw InvalidInput("--min-noise-cos: must be in [0, 1]");
  if (fit_radius_px < 1 || fit_radius_px > 16) throw InvalidInput("--fit-radius: must be in [1, 16] pixels");
  if (!(fit_gate_m > 0)) throw InvalidInput("registration.fit_gate_m: must be positive");
  if (normal_step_px < 1 || normal_step_px > 32) throw InvalidInput("registration.normal_step_px: must be in [1, 32]");
  if (!(trim_fraction >= 0 && trim_fraction < 1)) throw InvalidInput("--trim: must be in [0, 1)");
  if (min_correspondences < 6) throw InvalidInput("registration.min_correspondences: must be at least 6");
  if (!(converged_rad >= 0)) throw InvalidInput("registration.converged_rad: must be >= 0");
  if (!(below_volume_m >= 0)) throw InvalidInput("--below-volume: must be >= 0 (metres)");
  if (num_threads < 0) throw InvalidInput("--threads: must be >= 0");
  filter.validate();
  foreground.validate();
}

namespace {

using Vec3 = Eigen::Vector3f;
using Vector6d = Eigen::Matrix<double, 6, 1>;

// Metres: a rotation's step is measured by how far it moves a point this far away (about the
// distance from a camera to the subject).
constexpr double kLeverArmM = 2.0;

// Share of the correspondence distance one step may move a camera by. With the whole distance, the
// first step on the synthetic 6-camera ring without floor threw the rig 0.4 m away (the rotation
// about the subject's vertical axis is nearly free at 80×60); a third converges there and changes
// nothing on samba-4cam.
constexpr double kLongestStepShare = 1.0 / 3;

// nanoflann's view of a cloud's points (camera frame).
struct CloudAdaptor {
  const std::vector<Vec3>* points = nullptr;
  size_t kdtree_get_point_count() const { return points->size(); }
  float kdtree_get_pt(size_t i, size_t dim) const { return (*points)[i][static_cast<int>(dim)]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};
using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CloudAdaptor>, CloudAdaptor, 3, std::uint32_t>;

// One camera's samples of one frame at one level. Not movable: the tree refers to the adaptor.
struct Cloud {
  std::vector<Vec3> points;   // camera frame
  std::vector<Vec3> normals;  // camera frame, towards the camera
  std::vector<float> sigma;   // axial noise at the point's depth, metres
  Intrinsics intrinsics;
  std::vector<Vec3> world_points, world_normals;
  CloudAdaptor adaptor;
  std::unique_ptr<KdTree> tree;

  Cloud() = default;
  Cloud(const Cloud&) = delete;
  Cloud& operator=(const Cloud&) = delete;
  bool empty() const { return points.empty(); }
};

// `fit_radius`: the disparity fit's half-width in pixels.
std::unique_ptr<Cloud> make_cloud(const Image<float>& depth, const Intrinsics& k, int stride, int fit_radius, const RegistrationOptions& o) {
  auto cloud = std::make_unique<Cloud>();
  cloud->intrinsics = k;
  if (depth.empty()) return cloud;
  const int grid_width = (depth.width + stride - 1) / stride, grid_height = (depth.height + stride - 1) / stride;
  const int step = std::max(stride, o.normal_step_px);
  // kBilateral, kRaw: a neighbour `step` pixels away on a surface seen at up to max_view_angle
  // differs in depth by at most step·z/f·tan(angle); twice that plus 3σ allows for noise.
  const float cos_view = static_cast<float>(std::cos(o.max_view_angle_deg * std::numbers::pi / 180));
  for (int i = 0; i < grid_width * grid_height; ++i) {
    Vec3 p, n;
    const int u = (i % grid_width) * stride, v = (i / grid_width) * stride;
    const float z = depth(std::min(u, depth.width - 1), std::min(v, depth.height - 1));
    const float max_jump = 2.0f * step * z / static_cast<float>(k.fx) * std::tan(std::acos(cos_view)) + 3 * kinect_axial_sigma_m(z);
    const bool ok = o.surface == RegistrationSurface::kDisparityFit
                        ? disparity_fit_sample(i, depth.data.data(), depth.width, depth.height, stride, fit_radius,
                                               static_cast<float>(o.fit_gate_m), k, cos_view, &p, &n)
                        : surface_sample(i, depth.data.data(), depth.width, depth.height, stride, step, k, max_jump, cos_view, &p, &n);
    if (!ok) continue;
    cloud->points.push_back(p);
    cloud->normals.push_back(n);
    cloud->sigma.push_back(kinect_axial_sigma_m(p.z()));
  }
  if (cloud->points.empty()) return cloud;
  cloud->adaptor.points = &cloud->points;
  cloud->tree = std::make_unique<KdTree>(3, cloud->adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  return cloud;
}

void to_world(Cloud& cloud, const Rigid3d& world_from_depth) {
  const Rigid3f t = world_from_depth.cast<float>();
  cloud.world_points.resize(cloud.points.size());
  cloud.world_normals.resize(cloud.points.size());
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    cloud.world_points[i] = t * cloud.points[i];
    cloud.world_normals[i] = t.linear() * cloud.normals[i];
  }
}

// Index of the cloud's point closest to the query (camera frame) within sqrt(max_d2), or −1.
// The bound prunes the search: most queries far from the other surface end near the root.
int nearest(const Cloud& cloud, const Vec3& query_in_cam, float max_d2, float* distance_sq) {
  std::uint32_t index = 0;
  nanoflann::KNNResultSet<float, std::uint32_t> result(1);
  result.init(&index, distance_sq);
  *distance_sq = max_d2;
  cloud.tree->findNeighbors(result, query_in_cam.data(), nanoflann::SearchParams());
  return result.size() == 0 ? -1 : static_cast<int>(index);
}

// One correspondence's linearised residual: r + J·x, with x the 6N pose updates (ω, t) in the world
// frame, J nonzero only in the two cameras' blocks.
// [v]×, the matrix with [v]× w = v × w.
template <typename Scalar>
Eigen::Matrix<Scalar, 3, 3> cross_matrix(const Eigen::Matrix<Scalar, 3, 1>& v) {
  Eigen::Matrix<Scalar, 3, 3> m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

struct Residual {
  int a = 0, b = 0;
  Eigen::Matrix<float, 3, 6> ja, jb;  // point-to-plane uses row 0 only
  Vec3 r;
  float scaled = 0;  // |r| / σ, for trimming
  float weight = 0;
  float support = 1;  // what it counts towards min_correspondences: the floor's 1/F, as its weight
};

struct Poses {
  std::vector<Rigid3d> world_from_depth;
};

// What the residuals of a pair are weighed with besides their noise.
struct PairWeighting {
  float floor_top_z = -std::numeric_limits<float>::infinity();  // world z: both points below it are the floor
  float floor_weight = 1;
};

// Mutual closest points between clouds a and b of one frame within max_distance, as residuals.
void match_pair(const Cloud& ca, const Cloud& cb, int a, int b, const Poses& poses, float max_distance, const PairWeighting& weighting,
                const RegistrationOptions& o, std::vector<Residual>& out) {
  out.clear();
  const Rigid3f b_from_world = poses.world_from_depth[b].inverse().cast<float>();
  const Rigid3f a_from_world = poses.world_from_depth[a].inverse().cast<float>();
  const Vec3 centre_a = poses.world_from_depth[a].translation().cast<float>();
  const Vec3 centre_b = poses.world_from_depth[b].translation().cast<float>();
  const float max_d2 = max_distance * max_distance;
  const float cos_normal = static_cast<float>(std::cos(o.max_normal_angle_deg * std::numbers::pi / 180));
  const float cos_pair_view = static_cast<float>(std::cos(o.max_pair_view_angle_deg * std::numbers::pi / 180));
  const auto min_noise_cos = static_cast<float>(o.min_noise_cos);
  const int count = static_cast<int>(ca.points.size());
  const auto width_b = static_cast<float>(cb.intrinsics.width - 1), height_b = static_cast<float>(cb.intrinsics.height - 1);
  std::vector<int> match(count, -1);
  parallel_for(
      0, count,
      [&](int i) {
        // Only points camera b could see are searched (diagonal pairs share little).
        const Vec3 in_b = b_from_world * ca.world_points[i];
        if (in_b.z() <= 0.0f) return;
        const Eigen::Vector2f px = project_pinhole(cb.intrinsics, in_b);
        if (px.x() < 0.0f || px.y() < 0.0f || px.x() > width_b || px.y() > height_b) return;
        float d2 = 0;
        const int j = nearest(cb, in_b, max_d2, &d2);
        if (j < 0) return;
        if (ca.world_normals[i].dot(cb.world_normals[j]) < cos_normal) return;
        float back_d2 = 0;
        if (nearest(ca, a_from_world * cb.world_points[j], d2 * 1.0001f + 1e-12f, &back_d2) != i) return;
        match[i] = j;
      },
      o.num_threads);
  for (int i = 0; i < count; ++i) {
    const int j = match[i];
    if (j < 0) continue;
    const Vec3& pa = ca.world_points[i];
    const Vec3& pb = cb.world_points[j];
    Residual res;
    res.a = a;
    res.b = b;
    const Vec3 diff = pa - pb;
    const float sa = ca.sigma[i], sb = cb.sigma[j];
    float variance = 0;
    if (o.point_to_plane) {
      const Vec3 n = (ca.world_normals[i] + cb.world_normals[j]).normalized();
      const float along_a = n.dot((pa - centre_a).normalized()), along_b = n.dot((pb - centre_b).normalized());
      // Seen at a grazing angle by either camera, the pair is biased (the more oblique camera's
      // surface lies farther, by 1.2 mm beyond 78°: docs/design.md), and its σ along the normal
      // is so small that it would outweigh the frontal pairs.
      if (std::min(std::abs(along_a), std::abs(along_b)) < cos_pair_view) continue;
      // Axial noise σ(z) seen along the normal is σ(z)·cos θ, but not less than at min_noise_cos:
      // nearer grazing, the fit's errors across the ray are what is left.
      const float cos_a = std::max(std::abs(along_a), min_noise_cos), cos_b = std::max(std::abs(along_b), min_noise_cos);
      variance = sa * sa * cos_a * cos_a + sb * sb * cos_b * cos_b;
      res.r = Vec3(n.dot(diff), 0, 0);
      res.ja.setZero();
      res.jb.setZero();
      res.ja.block<1, 3>(0, 0) = pa.cross(n).transpose();
      res.ja.block<1, 3>(0, 3) = n.transpose();
      res.jb.block<1, 3>(0, 0) = -pb.cross(n).transpose();
      res.jb.block<1, 3>(0, 3) = -n.transpose();
    } else {
      variance = sa * sa + sb * sb;
      res.r = diff;
      // ω × p = −[p]× ω
      res.ja << -cross_matrix(pa), Eigen::Matrix3f::Identity();
      res.jb << cross_matrix(pb), -Eigen::Matrix3f::Identity();
    }
    const float sigma = std::sqrt(std::max(variance, 1e-8f));
    res.scaled = res.r.norm() / sigma;
    // Weights relative to 1 mm so the normal equations stay near unit scale.
    res.weight = o.noise_weights ? 1e-6f / (sigma * sigma) : 1.0f;
    if (pa.z() < weighting.floor_top_z && pb.z() < weighting.floor_top_z) {
      res.weight *= weighting.floor_weight;
      res.support = weighting.floor_weight;
    }
    out.push_back(res);
  }
}

// Drops the trim_fraction of residuals with the largest |r|/σ.
void trim(std::vector<Residual>& residuals, double fraction) {
  if (fraction <= 0 || residuals.empty()) return;
  const size_t keep = residuals.size() - static_cast<size_t>(fraction * static_cast<double>(residuals.size()));
  std::nth_element(residuals.begin(), residuals.begin() + (keep - 1), residuals.end(),
                   [](const Residual& x, const Residual& y) { return x.scaled < y.scaled; });
  residuals.resize(keep);
}

using Clouds = std::vector<std::vector<std::unique_ptr<Cloud>>>;  // [frame][camera]

// Levels count angles, not pixels: level L samples a camera every 2^L pixels of a Kinect v1 at
// 640×480 (f = 580 px), so every 2^L·f/580 of its own (at least 1). At 320×240, pixel levels ran
// 40×30 → 160×120 and the coarsest, with a few dozen samples of the subject per camera, could not
// converge (docs/design.md, "Registration").
int scaled_pixels(double pixels_at_reference, const Intrinsics& k) {
  return std::max(1, static_cast<int>(std::lround(pixels_at_reference * std::max(k.fx, k.fy) / kKinectV1DepthFocalPx)));
}

Clouds make_clouds(const Rig& rig, const std::vector<std::vector<Image<float>>>& depth_m, int level, const RegistrationOptions& o) {
  const int cameras = static_cast<int>(rig.cameras.size());
  const int frames = static_cast<int>(depth_m.size());
  Clouds clouds(frames);
  for (auto& f : clouds) f.resize(cameras);
  parallel_for(
      0, frames * cameras,
      [&](int fc) {
        const int f = fc / cameras, c = fc % cameras;
        const Intrinsics& k = rig.cameras[c].depth_intrinsics;
        const int stride = scaled_pixels(std::ldexp(1.0, level), k);
        // Coarse levels only have to converge: their fit spans the whole stride, so no pixel is
        // ignored and normals are smooth. The finest level decides the accuracy, where a smaller
        // window bends curved surfaces less; it stays fit_radius_px pixels whatever the focal
        // length, as a camera with fewer pixels measures each more coarsely (the disparity's
        // quantisation) and needs as many to average.
        const int fit_radius = level == o.finest_level ? o.fit_radius_px : std::max(o.fit_radius_px, stride);
        clouds[f][c] = make_cloud(depth_m[f][c], k, stride, fit_radius, o);
      },
      o.num_threads);
  return clouds;
}

struct Accumulated {
  std::vector<double> sum_sq;  // per camera
  std::vector<int> count;
  std::vector<char> pair_matched;  // [a · cameras + b], a < b: the pair had enough correspondences over the frames
  // With the normal equations, over the matched pairs' correspondences in them: Σ w·r² and their
  // support (each 1, the floor's 1/F), whose ratio over 1e-6 is the mean (r/σ)², the a posteriori
  // variance factor.
  double weighted_sq = 0;
  double used_support = 0;
};

// One pair's correspondences over all frames, summed: its two cameras' blocks of the normal
// equations, [a; b] (12 unknowns), its squared residuals, and its support before trimming.
struct PairSums {
  Eigen::Matrix<double, 12, 12> h = Eigen::Matrix<double, 12, 12>::Zero();
  Eigen::Matrix<double, 12, 1> g = Eigen::Matrix<double, 12, 1>::Zero();
  double sum_sq = 0;
  int count = 0;
  double support = 0;
  double weighted_sq = 0;   // Σ w·r² of the correspondences in h
  double used_support = 0;  // their support
};

// All pairs' correspondences of all frames at the current poses; with `system`, adds them to the
// normal equations H x = −g. A pair counts when it has min_correspondences over all the frames
// together, not in each: at coarse levels of small depth maps (40×30 samples of a 320×240 camera)
// or for cameras that overlap a little, each frame gives a few dozen, and a per-frame minimum
// left those pairs, and with them whole cameras, out of the coarse levels that have to converge.
// They are counted before trimming (in the solve as in the residuals after it, which decide which
// cameras are joined), the floor's at 1/F: it is the same in every frame, and a pair that shares
// only a few floor points does not place one camera against the other.
Accumulated accumulate(Clouds& clouds, const Poses& poses, float max_distance, const PairWeighting& weighting, const RegistrationOptions& o, Eigen::MatrixXd* h,
                       Eigen::VectorXd* g, bool trimmed) {
  const int cameras = static_cast<int>(poses.world_from_depth.size());
  Accumulated acc{std::vector<double>(cameras, 0), std::vector<int>(cameras, 0), std::vector<char>(static_cast<size_t>(cameras) * cameras, 0)};
  std::vector<PairSums> pairs(static_cast<size_t>(cameras) * cameras);
  std::vector<Residual> residuals;
  const int rows = o.point_to_plane ? 1 : 3;
  for (auto& frame : clouds) {
    for (int c = 0; c < cameras; ++c) {
      if (!frame[c]->empty()) to_world(*frame[c], poses.world_from_depth[c]);
    }
    for (int a = 0; a < cameras; ++a) {
      for (int b = a + 1; b < cameras; ++b) {
        if (frame[a]->empty() || frame[b]->empty()) continue;
        match_pair(*frame[a], *frame[b], a, b, poses, max_distance, weighting, o, residuals);
        PairSums& sums = pairs[static_cast<size_t>(a) * cameras + b];
        for (const Residual& res : residuals) sums.support += res.support;
        if (trimmed) trim(residuals, o.trim_fraction);
        for (const Residual& res : residuals) {
          sums.sum_sq += res.r.squaredNorm();
          ++sums.count;
          if (h == nullptr) continue;
          Eigen::Matrix<double, 3, 12> j;
          j << res.ja.cast<double>(), res.jb.cast<double>();
          const Eigen::Vector3d r = res.r.cast<double>();
          sums.h.noalias() += res.weight * j.topRows(rows).transpose() * j.topRows(rows);
          sums.g.noalias() += res.weight * j.topRows(rows).transpose() * r.head(rows);
          sums.weighted_sq += res.weight * r.head(rows).squaredNorm();
          sums.used_support += res.support * rows;  // a residual row each
        }
      }
    }
  }
  for (int a = 0; a < cameras; ++a) {
    for (int b = a + 1; b < cameras; ++b) {
      const PairSums& sums = pairs[static_cast<size_t>(a) * cameras + b];
      if (sums.support < o.min_correspondences) continue;
      acc.pair_matched[static_cast<size_t>(a) * cameras + b] = 1;
      acc.sum_sq[a] += sums.sum_sq;
      acc.sum_sq[b] += sums.sum_sq;
      acc.count[a] += sums.count;
      acc.count[b] += sums.count;
      if (h == nullptr) continue;
      acc.weighted_sq += sums.weighted_sq;
      acc.used_support += sums.used_support;
      const int ia = 6 * a, ib = 6 * b;
      h->block<6, 6>(ia, ia) += sums.h.block<6, 6>(0, 0);
      h->block<6, 6>(ib, ib) += sums.h.block<6, 6>(6, 6);
      h->block<6, 6>(ia, ib) += sums.h.block<6, 6>(0, 6);
      h->block<6, 6>(ib, ia) += sums.h.block<6, 6>(6, 0);
      g->segment<6>(ia) += sums.g.head<6>();
      g->segment<6>(ib) += sums.g.tail<6>();
    }
  }
  return acc;
}

}  // namespace

std::vector<Image<float>> registration_depth(const Rig& rig, const FrameSet& frames, const RegistrationOptions& options) {
  const int cameras = static_cast<int>(rig.cameras.size());
  assert(static_cast<int>(frames.cameras.size()) == cameras);
  std::vector<Image<float>> depth(cameras);
  const BilateralKernel kernel(options.filter);
  std::optional<Box3d> volume = rig.volume;
  if (volume) volume->min.z() -= options.below_volume_m;
  parallel_for(
      0, cameras,
      [&](int c) {
        if (!frames.cameras[c].has_depth) return;
        Image<float> foreground;
        extract_foreground(frames.cameras[c].depth, rig.depth_unit_m, rig.cameras[c], volume, options.foreground, foreground);
        if (options.surface == RegistrationSurface::kBilateral) {
          bilateral_filter(foreground, kernel, depth[c], 1);
        } else {
          depth[c] = std::move(foreground);
        }
      },
      options.num_threads);
  return depth;
}

RegistrationResult register_rig(const Rig& rig, const std::vector<std::vector<Image<float>>>& depth_m, const RegistrationOptions& options) {
  const int cameras = static_cast<int>(rig.cameras.size());
  Poses poses;
  poses.world_from_depth = world_from_depth_poses(rig);
  // The floor is the same surface in every frame set, with the same quantisation steps: all the
  // frames together are one observation of it, while the moving body gives a new one each frame.
  PairWeighting weighting;
  if (rig.volume) weighting.floor_top_z = static_cast<float>(rig.volume->min.z());
  const auto has_depth = [](const std::vector<Image<float>>& frame) {
    return std::any_of(frame.begin(), frame.end(), [](const Image<float>& d) { return !d.empty(); });
  };
  const auto frames_with_depth = std::count_if(depth_m.begin(), depth_m.end(), has_depth);
  if (options.floor_counts_once && frames_with_depth > 0) weighting.floor_weight = 1.0f / static_cast<float>(frames_with_depth);
  RegistrationResult result;
  const int levels = options.coarsest_level - options.finest_level + 1;
  const int total_iterations = levels * options.iterations_per_level;
  const double shrink = total_iterations > 1 ? std::pow(options.end_distance_m / options.start_distance_m, 1.0 / (total_iterations - 1)) : 1.0;

  // Residuals before, at the input poses: measured on the finest level with the end distance.
  Clouds finest = make_clouds(rig, depth_m, options.finest_level, options);
  const Accumulated before = accumulate(finest, poses, static_cast<float>(options.end_distance_m), weighting, options, nullptr, nullptr, false);
  // Per camera: the RMS of its correspondences (0 where none) and their count.
  const auto per_camera = [cameras](const Accumulated& acc, std::vector<double>& rmse_m, std::vector<int>& count) {
    for (int c = 0; c < cameras; ++c) {
      rmse_m.push_back(acc.count[c] ? std::sqrt(acc.sum_sq[c] / acc.count[c]) : 0.0);
      count.push_back(acc.count[c]);
    }
  };
  per_camera(before, result.rmse_before_m, result.correspondences_before);
  // The gauge, whose pose is held: the first camera with usable depth, samples at the finest
  // level in some frame (a camera without, dead, covered or all outside the volume, cannot hold
  // the others in place).
  result.has_depth.assign(cameras, 0);
  for (const auto& frame : finest) {
    for (int c = 0; c < cameras; ++c) result.has_depth[c] = result.has_depth[c] || !frame[c]->empty();
  }
  const auto first_with_depth = std::find(result.has_depth.begin(), result.has_depth.end(), 1);
  result.gauge = first_with_depth == result.has_depth.end() ? 0 : static_cast<int>(first_with_depth - result.has_depth.begin());
  std::vector<int> free_cameras, free_rows;  // the others, and their rows in the normal equations
  for (int c = 0; c < cameras; ++c) {
    if (c == result.gauge) continue;
    free_cameras.push_back(c);
    for (int k = 0; k < 6; ++k) free_rows.push_back(6 * c + k);
  }

  int schedule_step = 0;
  for (int level = options.coarsest_level; level >= options.finest_level; --level) {
    Clouds coarse;
    if (level != options.finest_level) coarse = make_clouds(rig, depth_m, level, options);
    Clouds& clouds = level == options.finest_level ? finest : coarse;
    for (int it = 0; it < options.iterations_per_level; ++it, ++schedule_step) {
      if (options.cancel != nullptr && options.cancel->load()) {
        result.cancelled = true;
        result.world_from_depth = world_from_depth_poses(rig);
        result.joined_to_gauge.assign(cameras, 0);
        result.rmse_after_m = result.rmse_before_m;
        result.correspondences_after = result.correspondences_before;
        result.least_fixed_m.assign(cameras, 0);
        return result;
      }
      const float distance = static_cast<float>(options.start_distance_m * std::pow(shrink, schedule_step));
      Eigen::MatrixXd h = Eigen::MatrixXd::Zero(6 * cameras, 6 * cameras);
      Eigen::VectorXd g = Eigen::VectorXd::Zero(6 * cameras);
      accumulate(clouds, poses, distance, weighting, options, &h, &g, true);
      // Solved for all but the gauge. A tiny damping keeps cameras without correspondences (or a
      // degenerate overlap) where they are.
      if (free_cameras.empty()) break;
      Eigen::MatrixXd hf = h(free_rows, free_rows);
      const double damping = 1e-9 * std::max(1.0, hf.diagonal().maxCoeff());
      hf.diagonal().array() += damping;
      const Eigen::VectorXd x = hf.ldlt().solve(-g(free_rows));
      ++result.iterations;
      double largest = 0;
      for (size_t k = 0; k < free_cameras.size(); ++k) {
        const int c = free_cameras[k];
        Vector6d step = x.segment<6>(6 * static_cast<Eigen::Index>(k));
        // A step much longer than the correspondence distance trusts the linearisation beyond the
        // correspondences that made it (a nearly degenerate overlap); shorten it.
        const double length = std::max(step.tail<3>().norm(), step.head<3>().norm() * kLeverArmM);
        const double longest = kLongestStepShare * distance;
        if (length > longest) step *= longest / length;
        const Eigen::Vector3d omega = step.head<3>();
        largest = std::max({largest, omega.norm(), step.tail<3>().norm()});
        Rigid3d update = Rigid3d::Identity();
        if (omega.norm() > 0) update.linear() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix();
        update.translation() = step.tail<3>();
        poses.world_from_depth[c] = update * poses.world_from_depth[c];
      }
      const bool last_level = level == options.finest_level;
      result.converged = last_level && largest < options.converged_rad;
      if (largest < options.converged_rad) {
        schedule_step += options.iterations_per_level - 1 - it;
        break;
      }
    }
  }
  Accumulated after = accumulate(finest, poses, static_cast<float>(options.end_distance_m), weighting, options, nullptr, nullptr, false);
  // Cameras reached from the gauge through matched pairs.
  result.joined_to_gauge.assign(cameras, 0);
  result.joined_to_gauge[result.gauge] = 1;
  for (bool grew = true; grew;) {
    grew = false;
    for (int a = 0; a < cameras; ++a) {
      for (int b = a + 1; b < cameras; ++b) {
        if (after.pair_matched[static_cast<size_t>(a) * cameras + b] && result.joined_to_gauge[a] != result.joined_to_gauge[b]) {
          result.joined_to_gauge[a] = result.joined_to_gauge[b] = 1;
          grew = true;
        }
      }
    }
  }
  // A camera the gauge does not reach may have moved with others it overlaps, but nothing places
  // that group in the world: its cameras keep their starting poses.
  const Poses start{world_from_depth_poses(rig)};
  bool restored = false;
  for (int c = 0; c < cameras; ++c) {
    if (result.joined_to_gauge[c]) continue;
    restored = restored || !poses.world_from_depth[c].isApprox(start.world_from_depth[c], 0);
    poses.world_from_depth[c] = start.world_from_depth[c];
  }
  if (restored) after = accumulate(finest, poses, static_cast<float>(options.end_distance_m), weighting, options, nullptr, nullptr, false);
  per_camera(after, result.rmse_after_m, result.correspondences_after);
  result.world_from_depth = poses.world_from_depth;

  // How well the final correspondences fix each camera: the marginal covariance of its pose. The
  // weights are 1e-6/σ² (σ in metres, the sensor model's), so H / 1e-6 is the information in
  // m⁻², and the covariance σ0² · 1e-6 · H⁻¹, with σ0² the mean (r/σ)² of the residuals (the a
  // posteriori variance factor: depth quieter or noisier than the model says fixes the poses
  // better or worse). The damping only keeps a direction nothing fixes finite.
  result.least_fixed_m.assign(cameras, 0);
  if (options.measure_fixed && !free_cameras.empty()) {
    Eigen::MatrixXd h = Eigen::MatrixXd::Zero(6 * cameras, 6 * cameras);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(6 * cameras);
    const Accumulated final_sums = accumulate(finest, poses, static_cast<float>(options.end_distance_m), weighting, options, &h, &g, true);
    const double variance_factor = final_sums.used_support > 0 ? final_sums.weighted_sq / (1e-6 * final_sums.used_support) : 1.0;
    Eigen::MatrixXd hf = h(free_rows, free_rows);
    hf.diagonal().array() += 1e-12 * std::max(1.0, hf.diagonal().maxCoeff());
    const Eigen::MatrixXd covariance = variance_factor * 1e-6 * hf.ldlt().solve(Eigen::MatrixXd::Identity(hf.rows(), hf.cols()));
    for (size_t k = 0; k < free_cameras.size(); ++k) {
      const Eigen::Index at = 6 * static_cast<Eigen::Index>(k);
      // The unknowns (ω, t) turn the camera about the world's origin and shift it: its centre c
      // moves by ω × c + t. Taken as a turn about its own centre and that centre's move, scaled
      // to metres at the lever arm, the figure does not change with where the world's origin is.
      const Eigen::Vector3d centre = poses.world_from_depth[free_cameras[k]].translation();
      Eigen::Matrix<double, 6, 6> about_centre = Eigen::Matrix<double, 6, 6>::Zero();
      about_centre.topLeftCorner<3, 3>() = kLeverArmM * Eigen::Matrix3d::Identity();
      about_centre.bottomLeftCorner<3, 3>() = -cross_matrix(centre);
      about_centre.bottomRightCorner<3, 3>() = Eigen::Matrix3d::Identity();
      const Eigen::Matrix<double, 6, 6> block = about_centre * covariance.block<6, 6>(at, at) * about_centre.transpose();
      const double largest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(block, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
      result.least_fixed_m[free_cameras[k]] = std::sqrt(std::max(largest, 0.0));
    }
  }
  return result;
}

std::vector<RelativePoseError> relative_pose_errors(const std::vector<Rigid3d>& world_from_depth, const std::vector<Rigid3d>& true_world_from_depth,
                                                    int reference) {
  assert(world_from_depth.size() == true_world_from_depth.size() && reference >= 0 && reference < static_cast<int>(world_from_depth.size()));
  std::vector<RelativePoseError> errors;
  const Rigid3d first_from_world = world_from_depth[reference].inverse(), true_first_from_world = true_world_from_depth[reference].inverse();
  for (size_t c = 0; c < world_from_depth.size(); ++c) {
    const Rigid3d first_from_cam = first_from_world * world_from_depth[c];
    const Rigid3d true_first_from_cam = true_first_from_world * true_world_from_depth[c];
    errors.push_back({(first_from_cam.translation() - true_first_from_cam.translation()).norm(),
                      rotation_angle_deg(true_first_from_cam.inverse() * first_from_cam)});
  }
  return errors;
}

RelativePoseError worst_relative_pose_error(const std::vector<Rigid3d>& world_from_depth, const std::vector<Rigid3d>& true_world_from_depth) {
  RelativePoseError worst;
  for (const RelativePoseError& e : relative_pose_errors(world_from_depth, true_world_from_depth)) {
    worst.translation_m = std::max(worst.translation_m, e.translation_m);
    worst.rotation_deg = std::max(worst.rotation_deg, e.rotation_deg);
  }
  return worst;
}

}  // namespace zipfusion
