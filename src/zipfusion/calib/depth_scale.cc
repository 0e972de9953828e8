#include "zipfusion/calib/depth_scale.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "zipfusion/core/camera.h"
#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"

namespace zipfusion {
namespace {

// The frame whose centre the wand calibrated: the colour camera's, else the depth camera's.
Rigid3d world_from_calibrated(const CameraModel& model) {
  return model.has_color() ? model.world_from_depth * model.color_from_depth.inverse() : model.world_from_depth;
}

// One camera's depth in one frame: the whole image in metres, which the other cameras' points are
// compared with, and its points (every few pixels, where the pixels around are one surface) with
// their normals, in the depth camera's frame.
struct CameraDepth {
  std::vector<float> depth_m;  // 0 where nothing was measured or outside the range
  int width = 0, height = 0;
  std::vector<Eigen::Vector3f> points, normals;

  float at(int u, int v) const { return u < 0 || v < 0 || u >= width || v >= height ? 0.0f : depth_m[static_cast<size_t>(v) * width + u]; }
};

struct FrameDepth {
  std::vector<CameraDepth> cameras;
};

// What a scaled rig is compared by, for each ordered camera pair (i, j): j_from_i, the direction
// between the two depth centres in j's frame, and how i's points move in j's frame with the scale.
struct PairGeometry {
  Rigid3f j_from_i;
  Eigen::Vector3f baseline_in_j;  // unit
  Eigen::Vector3f d_q_d_scale;    // how a point of i seen from j moves as the scale grows, j's frame
  bool compared = false;          // the two cameras look at most max_pair_angle_deg apart
};

std::vector<PairGeometry> pair_geometry(const Rig& rig, int gauge, double scale, double max_pair_angle_deg) {
  const Rig scaled = scale_rig(rig, gauge, scale);
  const int n = static_cast<int>(rig.cameras.size());
  std::vector<PairGeometry> pairs(static_cast<size_t>(n) * n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      if (i == j) continue;
      const Rigid3d& world_from_i = scaled.cameras[i].world_from_depth;
      const Rigid3d& world_from_j = scaled.cameras[j].world_from_depth;
      PairGeometry& g = pairs[static_cast<size_t>(i) * n + j];
      g.j_from_i = (world_from_j.inverse() * world_from_i).cast<float>();
      g.baseline_in_j = (world_from_j.linear().transpose() * (world_from_j.translation() - world_from_i.translation())).normalized().cast<float>();
      // Every centre moves away from the gauge's as origin + s·(centre − origin): a point of i
      // moves with i's centre, and j's frame with j's, so in j's frame the point moves by
      // R_jᵀ(c_i − c_j) per unit of s (c at scale 1).
      const Eigen::Vector3d offset = world_from_calibrated(rig.cameras[i]).translation() - world_from_calibrated(rig.cameras[j]).translation();
      g.d_q_d_scale = (world_from_j.linear().transpose() * offset).cast<float>();
      g.compared = world_from_i.linear().col(2).dot(world_from_j.linear().col(2)) >= std::cos(max_pair_angle_deg * std::numbers::pi / 180);
    }
  }
  return pairs;
}

// Calls visit(q, normal, measured depth, pixel, pair geometry, j's intrinsics) for every sample of
// camera i whose surface faces camera j and lands on a pixel j measured, over all frames and
// ordered pairs; q and normal in j's frame.
template <typename Visit>
void for_each_covisible(const std::vector<FrameDepth>& frames, const std::vector<PairGeometry>& pairs, const Rig& rig,
                        const DepthScaleOptions& options, Visit&& visit) {
  const auto least_facing_cos = static_cast<float>(std::cos(options.max_view_angle_deg * std::numbers::pi / 180));
  const int n = static_cast<int>(rig.cameras.size());
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      if (i == j) continue;
      const PairGeometry& g = pairs[static_cast<size_t>(i) * n + j];
      if (!g.compared) continue;
      const Intrinsics& k = rig.cameras[j].depth_intrinsics;
      const auto fx = static_cast<float>(k.fx), fy = static_cast<float>(k.fy), cx = static_cast<float>(k.cx), cy = static_cast<float>(k.cy);
      for (const FrameDepth& frame : frames) {
        const CameraDepth& from = frame.cameras[i];
        const CameraDepth& to = frame.cameras[j];
        if (from.points.empty() || to.depth_m.empty()) continue;
        for (size_t s = 0; s < from.points.size(); ++s) {
          const Eigen::Vector3f q = g.j_from_i * from.points[s];
          if (!(q.z() > 0)) continue;
          const int pu = static_cast<int>(std::lround(fx * q.x() / q.z() + cx)), pv = static_cast<int>(std::lround(fy * q.y() / q.z() + cy));
          const float measured = to.at(pu, pv);
          if (measured == 0) continue;
          // Only a surface that faces camera j can be the one j measures there: a point on the
          // far side of a limb would otherwise meet j's near side once the rig is a limb's
          // thickness too small (9 cm of 3.5 m is 2.5 %).
          const Eigen::Vector3f normal = g.j_from_i.linear() * from.normals[s];
          if (!(normal.dot(q) < -least_facing_cos * q.norm())) continue;
          visit(q, normal, measured, pu, pv, g, k);
        }
      }
    }
  }
}

// Summed agreement of every camera's points with every other camera's depth, the rig scaled by
// `scale`: a depth difference r weighs exp(−r²/2σ²), nothing beyond 3σ (another surface, or the
// point hidden from that camera), times how squarely the point's surface faces along the two
// cameras' baseline. A surface parallel to the baseline (the floor between cameras at one height)
// agrees at every scale and would only add how much of it the two happen to share.
double agreement_at(const std::vector<FrameDepth>& frames, const Rig& rig, int gauge, double scale, const DepthScaleOptions& options) {
  const std::vector<PairGeometry> pairs = pair_geometry(rig, gauge, scale, options.max_pair_angle_deg);
  const double sigma_m = options.agreement_m;
  const auto inv_two_sigma2 = static_cast<float>(1.0 / (2 * sigma_m * sigma_m));
  const auto cutoff = static_cast<float>(3 * sigma_m);
  double total = 0;
  for_each_covisible(frames, pairs, rig, options, [&](const Eigen::Vector3f& q, const Eigen::Vector3f& normal, float measured, int, int, const PairGeometry& g,
                                             const Intrinsics&) {
    const float r = measured - q.z();
    if (std::abs(r) < cutoff) total += std::abs(normal.dot(g.baseline_in_j)) * std::exp(-r * r * inv_two_sigma2);
  });
  return total;
}

// Gauss-Newton steps on the point-to-plane distances between each camera's points and the
// surface the other camera measures where they land (its normal: the point's own, carried into
// that camera), robustly weighted; each distance changes with the scale by the normal's share of
// the two centres' offset, so surfaces parallel to the baseline do not pull.
double refine_scale(const std::vector<FrameDepth>& frames, const Rig& rig, int gauge, double scale, double lowest, double highest,
                    const DepthScaleOptions& options) {
  const double sigma_m = options.agreement_m;
  const auto inv_two_sigma2 = static_cast<float>(1.0 / (2 * sigma_m * sigma_m));
  const auto cutoff = static_cast<float>(3 * sigma_m);
  for (int iteration = 0; iteration < 30; ++iteration) {
    const std::vector<PairGeometry> pairs = pair_geometry(rig, gauge, scale, options.max_pair_angle_deg);
    double jtj = 0, jtr = 0;
    for_each_covisible(frames, pairs, rig, options, [&](const Eigen::Vector3f& q, const Eigen::Vector3f& normal, float measured, int pu, int pv,
                                               const PairGeometry& g, const Intrinsics& k) {
      const Eigen::Vector3f& n = normal;
      const Eigen::Vector3f y = unproject(k, static_cast<float>(pu), static_cast<float>(pv), measured);
      const float r = n.dot(q - y);
      if (!(std::abs(r) < cutoff)) return;
      const float w = std::exp(-r * r * inv_two_sigma2);
      const float jacobian = n.dot(g.d_q_d_scale);
      jtj += w * jacobian * jacobian;
      jtr += w * jacobian * r;
    });
    if (!(jtj > 0)) break;
    const double step = std::clamp(-jtr / jtj, -0.01, 0.01);
    const double before = scale;
    scale = std::clamp(scale + step, lowest, highest);
    if (std::abs(scale - before) < 1e-5) break;
  }
  return scale;
}

}  // namespace

void DepthScaleOptions::validate() const {
  auto fail = [](const std::string& field, const std::string& problem) { throw InvalidInput(field + ": " + problem); };
  if (frames < 1 || frames > 1000) fail("frames", "must be in [1, 1000]");
  if (pixel_step < 1 || pixel_step > 64) fail("pixel_step", "must be in [1, 64]");
  if (!(min_depth_m > 0 && max_depth_m > min_depth_m)) fail("depth range", "need 0 < min < max metres");
  if (!(lowest_scale > 0 && lowest_scale < 1 && highest_scale > 1 && highest_scale < 10)) fail("scale range", "need 0 < lowest < 1 < highest < 10");
  if (!(agreement_m > 0 && agreement_m < 1)) fail("agreement_m", "must be in (0, 1) metres");
  if (!(min_agreement >= 0) || !(min_peak_ratio >= 1)) fail("min_agreement", "need min_agreement >= 0 and min_peak_ratio >= 1");
  if (!(max_view_angle_deg > 0 && max_view_angle_deg < 90)) fail("max_view_angle_deg", "must be in (0, 90) degrees");
  if (!(max_pair_angle_deg > 0 && max_pair_angle_deg <= 180)) fail("max_pair_angle_deg", "must be in (0, 180] degrees");
}

Rig scale_rig(const Rig& rig, int gauge, double scale) {
  if (gauge < 0 || gauge >= static_cast<int>(rig.cameras.size())) throw InvalidInput("scale_rig: no camera " + std::to_string(gauge));
  Rig out = rig;
  const Eigen::Vector3d origin = world_from_calibrated(rig.cameras[gauge]).translation();
  for (CameraModel& model : out.cameras) {
    Rigid3d world_from_centre = world_from_calibrated(model);
    world_from_centre.translation() = origin + scale * (world_from_centre.translation() - origin);
    model.world_from_depth = model.has_color() ? world_from_centre * model.color_from_depth : world_from_centre;
  }
  return out;
}

DepthScaleResult measure_depth_scale(const Capture& capture, const Rig& rig, int gauge, const DepthScaleOptions& options) {
  options.validate();
  DepthScaleResult result;
  const int n = capture.camera_count();
  if (static_cast<int>(rig.cameras.size()) != n) throw InvalidInput("measure_depth_scale: the rig has another number of cameras than the capture");
  // Frames spread over the capture: a moving subject shows the cameras different surfaces.
  const int compared = std::min(options.frames, capture.frame_count());
  for (int k = 0; k < compared; ++k) {
    const int frame = static_cast<int>((k + 0.5) * capture.frame_count() / compared);
    if (result.frames.empty() || result.frames.back() != frame) result.frames.push_back(frame);
  }
  std::vector<FrameDepth> frames(result.frames.size());
  for (FrameDepth& f : frames) f.cameras.resize(n);
  std::vector<std::vector<std::string>> unreadable(frames.size() * n);
  parallel_for(0, static_cast<int>(frames.size()) * n, [&](int index) {
    const int f = index / n, c = index % n;
    const CameraFrame image = capture.load_camera_depth(result.frames[f], c);
    unreadable[index] = image.unreadable;
    if (!image.has_depth) return;
    const Intrinsics& k = rig.cameras[c].depth_intrinsics;
    CameraDepth& out = frames[f].cameras[c];
    out.width = image.depth.width;
    out.height = image.depth.height;
    out.depth_m.assign(static_cast<size_t>(out.width) * out.height, 0.0f);
    bool any = false;
    for (int v = 0; v < out.height; ++v) {
      for (int u = 0; u < out.width; ++u) {
        const double z = image.depth(u, v) * capture.rig().depth_unit_m;
        if (z < options.min_depth_m || z > options.max_depth_m) continue;
        out.depth_m[static_cast<size_t>(v) * out.width + u] = static_cast<float>(z);
        any = true;
      }
    }
    if (!any) {
      out.depth_m.clear();
      return;
    }
    const int step = std::max(1, static_cast<int>(std::lround(options.pixel_step * out.width / 640.0)));
    // Normals by a plane through the pixels of a window about 3 cm across at 2.5 m (5×5 of them,
    // every half-window), those within 5 cm of the point's depth: the Kinect's centimetre of
    // noise and its disparity steps would tilt a normal from the next pixels by tens of degrees.
    // Fewer than 12 such pixels (an edge, a thin part) leave the normal zero.
    const int reach = std::max(2, static_cast<int>(std::lround(4.0 * out.width / 640.0)));
    for (int v = step / 2; v < out.height; v += step) {
      for (int u = step / 2; u < out.width; u += step) {
        const float z = out.at(u, v);
        if (z == 0) continue;
        const Eigen::Vector3f p = unproject(k, static_cast<float>(u), static_cast<float>(v), z);
        Eigen::Vector3f sum = Eigen::Vector3f::Zero();
        Eigen::Matrix3f second = Eigen::Matrix3f::Zero();
        int count = 0;
        for (int dv = -2; dv <= 2; ++dv) {
          for (int du = -2; du <= 2; ++du) {
            const int wu = u + du * reach / 2, wv = v + dv * reach / 2;
            const float d = out.at(wu, wv);
            if (d == 0 || std::abs(d - z) > 0.05f) continue;
            const Eigen::Vector3f w = unproject(k, static_cast<float>(wu), static_cast<float>(wv), d) - p;
            sum += w;
            second += w * w.transpose();
            ++count;
          }
        }
        if (count < 12) continue;
        const Eigen::Vector3f mean = sum / static_cast<float>(count);
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> solver(second / static_cast<float>(count) - mean * mean.transpose());
        Eigen::Vector3f normal = solver.eigenvectors().col(0);
        if (normal.dot(p) > 0) normal = -normal;
        out.points.push_back(p);
        out.normals.push_back(normal);
      }
    }
  }, options.num_threads);
  for (const auto& files : unreadable) result.unreadable.insert(result.unreadable.end(), files.begin(), files.end());
  for (const FrameDepth& f : frames) {
    for (const CameraDepth& c : f.cameras) result.samples += static_cast<int>(c.points.size());
  }
  char frame_span[64];
  std::snprintf(frame_span, sizeof frame_span, "%d frames from %d to %d", static_cast<int>(result.frames.size()),
                result.frames.empty() ? 0 : result.frames.front(), result.frames.empty() ? 0 : result.frames.back());
  if (result.samples == 0) {
    result.not_measured = std::string("no depth in the ") + frame_span;
    return result;
  }

  // Every 1.5 % over the range for the start, then Gauss-Newton from the best, within a step and a
  // half of it.
  const double ratio = 1.015;
  const int steps = static_cast<int>(std::floor(std::log(options.highest_scale / options.lowest_scale) / std::log(ratio))) + 1;
  auto factor = [&](double index) { return options.lowest_scale * std::pow(ratio, index); };
  std::vector<double> values(steps);
  parallel_for(0, steps, [&](int s) { values[s] = agreement_at(frames, rig, gauge, factor(s), options); }, options.num_threads);
  // Surfaces that fix the size agree within a percent or two of it: the best agreement must stand
  // above its shoulders, 4.5 % to either side. What changes slowly with the size (how much of a
  // plane the cameras happen to share, where a floor ends) makes broad humps that do not.
  const int shoulder = 3;
  const auto best = static_cast<int>(std::max_element(values.begin(), values.end()) - values.begin());
  const bool inside = best >= shoulder && best + shoulder < steps;
  const double peak_ratio = inside ? values[best] / std::max({values[best - shoulder], values[best + shoulder], 1e-9}) : 1.0;
  char detail[512];
  const double highest = values[best];
  if (highest < options.min_agreement) {
    std::snprintf(detail, sizeof detail,
                  "the depth in the %s shows too little that two cameras both see, facing partly along the line between them, at any "
                  "size from %.2f to %.2f times the rig's (agreement %.0f of %.0f needed; a floor alone, or cameras facing each other, show "
                  "too little)",
                  frame_span, options.lowest_scale, options.highest_scale, highest, options.min_agreement);
    result.not_measured = detail;
    return result;
  }
  if (peak_ratio < options.min_peak_ratio) {
    std::snprintf(detail, sizeof detail,
                  "the depth in the %s shows no size from %.2f to %.2f times the rig's at which the cameras' surfaces clearly meet (its best, "
                  "%.2f, stands %.2f times over the agreement 4.5 %% to either side, %.2f needed)",
                  frame_span, options.lowest_scale, options.highest_scale, factor(best), peak_ratio, options.min_peak_ratio);
    result.not_measured = detail;
    return result;
  }
  const double start = factor(static_cast<double>(best));
  result.scale = refine_scale(frames, rig, gauge, start, factor(best - 1.5), factor(best + 1.5), options);
  result.agreement = agreement_at(frames, rig, gauge, result.scale, options);
  result.measured = true;
  return result;
}

}  // namespace zipfusion
