#include "zipfusion/synth/human.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "zipfusion/core/error.h"

namespace zipfusion {
namespace {

using Eigen::Isometry3d;
using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;
constexpr double deg(double d) { return d * kPi / 180.0; }

// Rest-pose skeleton of the 1.72 m reference figure, metres (everything scales with
// height_m / kReferenceHeight). Body frame: x forward, y left, z up, floor at z = 0.
constexpr double kReferenceHeight = 1.72;
constexpr double kPelvisHeight = 0.95;   // pelvis joint above the floor
constexpr double kSpineUp = 0.05;        // pelvis joint → base of the waist
constexpr double kWaistLength = 0.22;    // base of the waist → chest joint
constexpr double kNeckUp = 0.23;         // chest joint → base of the neck (C7)
constexpr double kHeadUp = 0.12;         // base of the neck → head joint
constexpr double kShoulderY = 0.18;      // shoulder joints, lateral
constexpr double kShoulderUp = 0.19;     // chest joint → shoulder joints
constexpr double kUpperArmLength = 0.29;
constexpr double kForearmLength = 0.25;
constexpr double kHipY = 0.09;           // hip joints, lateral
constexpr double kHipDown = 0.05;        // pelvis joint → hip joints
constexpr double kThighLength = 0.42;
constexpr double kShinLength = 0.40;     // ankle 0.08 above the floor, the sole of the foot on it

// Head ellipsoid (semi-axes, centre above the head joint) and its face features.
constexpr double kHeadSemiX = 0.10, kHeadSemiY = 0.078, kHeadSemiZ = 0.115;
constexpr double kHeadCentreX = 0.01, kHeadCentreZ = 0.035;  // top of head at exactly 1.72
constexpr double kEyeAzimuth = 0.38, kEyeElevation = 0.12, kEyeRadius = 0.018;  // rad, rad, m
constexpr double kMouthElevation = -0.42, kMouthHalfWidth = 0.028, kMouthHalfHeight = 0.008;
constexpr double kLegStripeHalfWidth = 0.02;

enum class Segment {
  kPelvis, kWaist, kChest, kShoulders, kNeck, kHead, kUpperArm, kForearm, kHand, kThigh, kShin, kFoot
};
enum class Shape { kCapsule, kEllipsoid };

// One primitive in its own frame. Capsule: sphere-swept segment along local +z from 0 (radius r0)
// to length (radius r1), cross-section scaled by scale_x along local x. Ellipsoid: centred at the
// origin, semi-axes `semi`, lathed about local z.
struct PartShape {
  Segment segment;
  int side;  // +1 left, -1 right, 0 centre
  Shape shape;
  double length = 0, r0 = 0, r1 = 0, scale_x = 1;
  Vector3d semi = Vector3d::Zero();
  double spacing = 1;  // vertex spacing relative to the figure's default
};

constexpr int kPartCount = 18;

// Joint state of one frame. Side index 0 = left (+y), 1 = right (−y).
struct Joints {
  Vector3d root = Vector3d::Zero();  // point on the floor below the pelvis, world
  double heading = 0;                // body +x direction, rad about world z
  double pelvis_height = kPelvisHeight;  // reference metres
  double pelvis_yaw = 0, lean = 0, chest_yaw = 0;  // rad
  std::array<double, 2> hip_flex{0, 0}, knee_flex{0, 0};  // rad, forward hip flexion / backward knee flexion
  std::array<Matrix3d, 2> shoulder{Matrix3d::Identity(), Matrix3d::Identity()};
  std::array<Matrix3d, 2> elbow{Matrix3d::Identity(), Matrix3d::Identity()};
  std::array<Matrix3d, 2> wrist{Matrix3d::Identity(), Matrix3d::Identity()};
};

Matrix3d rot_x(double a) { return Eigen::AngleAxisd(a, Vector3d::UnitX()).toRotationMatrix(); }
Matrix3d rot_y(double a) { return Eigen::AngleAxisd(a, Vector3d::UnitY()).toRotationMatrix(); }
Matrix3d rot_z(double a) { return Eigen::AngleAxisd(a, Vector3d::UnitZ()).toRotationMatrix(); }

// A child frame at `origin` in its parent, rotated by `rotation`.
Isometry3d frame(const Vector3d& origin, const Matrix3d& rotation = Matrix3d::Identity()) {
  Isometry3d t = Isometry3d::Identity();
  t.linear() = rotation;
  t.translation() = origin;
  return t;
}

// Forward rotation about the local y axis of a limb pointing down (−z): the foot/hand moves to +x.
Matrix3d flex_forward(double a) { return rot_y(-a); }

std::array<PartShape, kPartCount> part_shapes(double s) {
  auto capsule = [s](Segment seg, int side, double length, double r0, double r1, double scale_x = 1.0,
                     double spacing = 1.0) {
    return PartShape{.segment = seg, .side = side, .shape = Shape::kCapsule, .length = length * s, .r0 = r0 * s,
                     .r1 = r1 * s, .scale_x = scale_x, .spacing = spacing};
  };
  auto ellipsoid = [s](Segment seg, int side, double x, double y, double z, double spacing = 1.0) {
    return PartShape{.segment = seg, .side = side, .shape = Shape::kEllipsoid, .semi = Vector3d(x, y, z) * s,
                     .spacing = spacing};
  };
  // The trunk is a little finer (≤ 1.6 cm at segments = 32) to resolve the shirt stripes; the head
  // finer still for the eyes.
  constexpr double kTrunk = 0.85, kFace = 0.45;
  return {
      ellipsoid(Segment::kPelvis, 0, 0.11, 0.165, 0.11, kTrunk),
      capsule(Segment::kWaist, 0, kWaistLength, 0.125, 0.145, 0.72, kTrunk),
      ellipsoid(Segment::kChest, 0, 0.115, 0.165, 0.18, kTrunk),
      capsule(Segment::kShoulders, 0, 2 * 0.165, 0.06, 0.06, 0.85, kTrunk),
      capsule(Segment::kNeck, 0, 0.13, 0.055, 0.05),
      ellipsoid(Segment::kHead, 0, kHeadSemiX, kHeadSemiY, kHeadSemiZ, kFace),
      capsule(Segment::kUpperArm, 1, kUpperArmLength, 0.045, 0.037),
      capsule(Segment::kUpperArm, -1, kUpperArmLength, 0.045, 0.037),
      capsule(Segment::kForearm, 1, kForearmLength, 0.037, 0.028),
      capsule(Segment::kForearm, -1, kForearmLength, 0.037, 0.028),
      ellipsoid(Segment::kHand, 1, 0.045, 0.022, 0.09),
      ellipsoid(Segment::kHand, -1, 0.045, 0.022, 0.09),
      capsule(Segment::kThigh, 1, kThighLength, 0.075, 0.05),
      capsule(Segment::kThigh, -1, kThighLength, 0.075, 0.05),
      capsule(Segment::kShin, 1, kShinLength, 0.05, 0.035),
      capsule(Segment::kShin, -1, kShinLength, 0.05, 0.035),
      ellipsoid(Segment::kFoot, 1, 0.13, 0.045, 0.04),
      ellipsoid(Segment::kFoot, -1, 0.13, 0.045, 0.04),
  };
}

// world_from_part for each part of part_shapes, by forward kinematics.
std::array<Isometry3d, kPartCount> part_frames(const Joints& j, double s) {
  const Matrix3d down = rot_x(kPi);  // capsule axis +z → −z (limbs hang from their joint)
  std::array<Isometry3d, kPartCount> f;
  const Isometry3d body = frame(j.root, rot_z(j.heading));
  const Isometry3d pelvis = body * frame({0, 0, j.pelvis_height * s}, rot_z(j.pelvis_yaw));
  f[0] = pelvis * frame({0, 0, -0.01 * s});
  const Isometry3d spine = pelvis * frame({0, 0, kSpineUp * s}, rot_y(j.lean));
  f[1] = spine;
  const Isometry3d chest = spine * frame({0, 0, kWaistLength * s}, rot_z(j.chest_yaw));
  f[2] = chest * frame({0, 0, 0.08 * s});
  f[3] = chest * frame({0, -0.165 * s, 0.18 * s}, rot_x(-kPi / 2));  // axis along +y
  const Isometry3d neck = chest * frame({0, 0, kNeckUp * s}, rot_y(-j.lean));
  f[4] = neck * frame({0, 0, -0.02 * s});
  const Isometry3d head = neck * frame({0, 0, kHeadUp * s});
  f[5] = head * frame({kHeadCentreX * s, 0, kHeadCentreZ * s});
  for (int i = 0; i < 2; ++i) {
    const double side = i == 0 ? 1.0 : -1.0;
    const Isometry3d shoulder = chest * frame({0, side * kShoulderY * s, kShoulderUp * s}, j.shoulder[i]);
    f[6 + i] = shoulder * frame(Vector3d::Zero(), down);
    const Isometry3d elbow = shoulder * frame({0, 0, -kUpperArmLength * s}, j.elbow[i]);
    f[8 + i] = elbow * frame(Vector3d::Zero(), down);
    const Isometry3d wrist = elbow * frame({0, 0, -kForearmLength * s}, j.wrist[i]);
    f[10 + i] = wrist * frame({0, 0, -0.085 * s});
    const Isometry3d hip = pelvis * frame({0, side * kHipY * s, -kHipDown * s}, flex_forward(j.hip_flex[i]));
    f[12 + i] = hip * frame(Vector3d::Zero(), down);
    const Isometry3d knee = hip * frame({0, 0, -kThighLength * s}, flex_forward(-j.knee_flex[i]));
    f[14 + i] = knee * frame(Vector3d::Zero(), down);
    // The ankle undoes hip and knee, so the foot stays level.
    const Isometry3d ankle = knee * frame({0, 0, -kShinLength * s}, flex_forward(j.knee_flex[i] - j.hip_flex[i]));
    f[16 + i] = ankle * frame({0.055 * s, 0, -0.04 * s});
  }
  return f;
}

Joints pose_at(double t, const HumanOptions& o) {
  Joints j;
  const double walk = 2 * kPi * t / o.walk_period_s;
  j.root = {o.walk_radius_m * std::cos(walk), o.walk_radius_m * std::sin(walk), 0};
  j.heading = walk + kPi / 2;  // counter-clockwise tangent

  const double p = 2 * kPi * t / o.stride_period_s;  // left leg: swing while cos p > 0
  const double sp = std::sin(p), cp = std::cos(p);
  j.hip_flex = {deg(25) * sp, -deg(25) * sp};
  j.knee_flex = {deg(55) * std::pow(std::max(0.0, cp), 2), deg(55) * std::pow(std::max(0.0, -cp), 2)};
  j.pelvis_yaw = -deg(5) * sp;  // the forward hip leads
  j.chest_yaw = deg(9) * sp;    // shoulders counter-rotate (net +4°)
  j.lean = deg(3);

  // Bob: the lower ankle sits where a straight vertical leg would put it.
  double reach = 0;
  for (int i = 0; i < 2; ++i) {
    reach = std::max(reach, kThighLength * std::cos(j.hip_flex[i]) +
                                kShinLength * std::cos(j.hip_flex[i] - j.knee_flex[i]));
  }
  j.pelvis_height = kPelvisHeight - (kThighLength + kShinLength - reach);

  // Left arm swings against the left leg, slightly abducted to clear the hip.
  const double swing = -deg(20) * sp;
  j.shoulder[0] = flex_forward(swing) * rot_x(deg(8));
  j.elbow[0] = flex_forward(deg(15) + 0.5 * std::max(0.0, swing));
  // Right arm raised sideways (a little forward), forearm waving in the frontal plane, palm forward.
  const double wave = std::sin(2 * kPi * t / o.wave_period_s);
  j.shoulder[1] = rot_z(deg(15)) * rot_x(-deg(110));
  j.elbow[1] = rot_x(-(deg(70) + deg(30) * wave));
  j.wrist[1] = rot_z(kPi / 2);
  return j;
}

// Profile of a lathed surface: rings (z, radius) from bottom to top between two poles on the axis.
struct Ring {
  double z, rho;
};

int bands(double arc_length, double spacing, int minimum) {
  return std::max(minimum, static_cast<int>(std::lround(arc_length / spacing)));
}

// Tapered capsule: bottom sphere cap, the tangent cone, top sphere cap, rings about `spacing` apart.
void capsule_profile(const PartShape& p, double spacing, std::vector<Ring>& rings, double& z_bottom, double& z_top) {
  assert(std::abs(p.r0 - p.r1) < p.length);
  const double b0 = std::asin((p.r0 - p.r1) / p.length);  // elevation of the cone's normal
  const int na = bands(p.r0 * (b0 + kPi / 2), spacing, 2);
  const int nc = bands(std::sqrt(p.length * p.length - (p.r0 - p.r1) * (p.r0 - p.r1)), spacing, 1);
  const int nb = bands(p.r1 * (kPi / 2 - b0), spacing, 2);
  rings.clear();
  for (int k = 1; k <= na; ++k) {
    const double b = -kPi / 2 + (b0 + kPi / 2) * k / na;
    rings.push_back({p.r0 * std::sin(b), p.r0 * std::cos(b)});
  }
  const Ring a = rings.back();
  const Ring c{p.length + p.r1 * std::sin(b0), p.r1 * std::cos(b0)};
  for (int k = 1; k < nc; ++k) {
    const double u = static_cast<double>(k) / nc;
    rings.push_back({a.z + u * (c.z - a.z), a.rho + u * (c.rho - a.rho)});
  }
  for (int k = 0; k < nb; ++k) {
    const double b = b0 + (kPi / 2 - b0) * k / nb;
    rings.push_back({p.length + p.r1 * std::sin(b), p.r1 * std::cos(b)});
  }
  z_bottom = -p.r0;
  z_top = p.length + p.r1;
}

// Unit-radius profile of an ellipsoid of half-height semi.z (x and y are applied in the lathe).
void ellipsoid_profile(const PartShape& p, double spacing, int min_bands, std::vector<Ring>& rings, double& z_bottom,
                       double& z_top) {
  const double radial = std::max(p.semi.x(), p.semi.y());
  const double meridian = kPi * std::sqrt(0.5 * (radial * radial + p.semi.z() * p.semi.z()));
  const int n = bands(meridian, spacing, min_bands);
  rings.clear();
  for (int k = 1; k < n; ++k) {
    const double th = kPi * k / n;
    rings.push_back({-p.semi.z() * std::cos(th), std::sin(th)});
  }
  z_bottom = -p.semi.z();
  z_top = p.semi.z();
}

// Colour of a point of `part`: `local` in the part's frame, `rest` in the rest-pose body frame,
// both in metres of the reference figure.
Rgb8 part_color(const PartShape& part, const Vector3d& local, const Vector3d& rest) {
  const HumanPalette& c = kHumanPalette;
  switch (part.segment) {
    case Segment::kHead: {
      for (double az : {kEyeAzimuth, -kEyeAzimuth}) {
        const Vector3d eye(kHeadSemiX * std::cos(kEyeElevation) * std::cos(az),
                           kHeadSemiY * std::cos(kEyeElevation) * std::sin(az), kHeadSemiZ * std::sin(kEyeElevation));
        if ((local - eye).norm() < kEyeRadius) return c.eye;
      }
      const double mouth_z = kHeadSemiZ * std::sin(kMouthElevation);
      if (local.x() > 0 && std::abs(local.y()) < kMouthHalfWidth && std::abs(local.z() - mouth_z) < kMouthHalfHeight) {
        return c.mouth;
      }
      if (local.z() > 0.06 || (local.x() < -0.02 && local.z() > -0.05)) return c.hair;
      return c.skin;
    }
    case Segment::kNeck:
    case Segment::kForearm:
    case Segment::kHand:
      return c.skin;
    case Segment::kWaist:
    case Segment::kChest:
    case Segment::kShoulders:
    case Segment::kUpperArm:
      return (static_cast<long>(std::floor(rest.z() / kHumanStripeWidth)) & 1) == 0 ? c.shirt_a : c.shirt_b;
    case Segment::kPelvis:
      return c.trousers;
    case Segment::kThigh:
    case Segment::kShin:
      return part.side * rest.y() > kHipY && std::abs(rest.x()) < kLegStripeHalfWidth ? c.trouser_stripe
                                                                                       : c.trousers;
    case Segment::kFoot:
      return c.shoe;
  }
  return c.skin;
}

// Appends the lathed surface of one part: bottom pole, rings of `around` vertices, top pole.
void append_part(const PartShape& part, const std::vector<Ring>& rings, double z_bottom, double z_top, int around,
                 const Isometry3d& world_from_part, const Isometry3d& rest_from_part, double s,
                 std::vector<double>& cos_sin, TriangleMesh& mesh) {
  const bool ellipsoid = part.shape == Shape::kEllipsoid;
  const double sx = ellipsoid ? part.semi.x() : part.scale_x;
  const double sy = ellipsoid ? part.semi.y() : 1.0;
  cos_sin.resize(2 * static_cast<size_t>(around));
  for (int k = 0; k < around; ++k) {
    const double phi = 2 * kPi * k / around;
    cos_sin[2 * k] = sx * std::cos(phi);
    cos_sin[2 * k + 1] = sy * std::sin(phi);
  }
  const int base = static_cast<int>(mesh.positions.size());
  auto emit = [&](const Vector3d& local) {
    mesh.positions.push_back((world_from_part * local).cast<float>());
    mesh.colors.push_back(part_color(part, local / s, rest_from_part * local / s));
  };
  emit({0, 0, z_bottom});
  for (const Ring& r : rings) {
    for (int k = 0; k < around; ++k) emit({r.rho * cos_sin[2 * k], r.rho * cos_sin[2 * k + 1], r.z});
  }
  emit({0, 0, z_top});

  const int n_rings = static_cast<int>(rings.size());
  auto v = [&](int ring, int k) { return base + 1 + ring * around + (k % around); };
  const int top = base + 1 + n_rings * around;
  for (int k = 0; k < around; ++k) mesh.triangles.emplace_back(base, v(0, k + 1), v(0, k));
  for (int r = 0; r + 1 < n_rings; ++r) {
    for (int k = 0; k < around; ++k) {
      mesh.triangles.emplace_back(v(r, k), v(r, k + 1), v(r + 1, k + 1));
      mesh.triangles.emplace_back(v(r, k), v(r + 1, k + 1), v(r + 1, k));
    }
  }
  for (int k = 0; k < around; ++k) mesh.triangles.emplace_back(top, v(n_rings - 1, k), v(n_rings - 1, k + 1));
}

}  // namespace

void HumanOptions::validate() const {
  auto fail = [](const char* field, const char* what) {
    throw InvalidInput(std::string("human.") + field + ": " + what);
  };
  if (!(std::isfinite(height_m) && height_m >= 0.3 && height_m <= 3.0)) fail("height_m", "must be in [0.3, 3] m");
  if (!(std::isfinite(walk_radius_m) && walk_radius_m >= 0)) fail("walk_radius_m", "must be finite and >= 0");
  if (!(std::isfinite(walk_period_s) && walk_period_s > 0)) fail("walk_period_s", "must be finite and > 0");
  if (!(std::isfinite(stride_period_s) && stride_period_s > 0)) fail("stride_period_s", "must be finite and > 0");
  if (!(std::isfinite(wave_period_s) && wave_period_s > 0)) fail("wave_period_s", "must be finite and > 0");
  if (segments < 8) fail("segments", "must be >= 8");
  if (segments > 1024) fail("segments", "must be <= 1024");
}

TriangleMesh make_human(double time_s, const HumanOptions& options) {
  assert(options.height_m > 0 && options.segments >= 8 && options.walk_period_s > 0 &&
         options.stride_period_s > 0 && options.wave_period_s > 0);
  const double s = options.height_m / kReferenceHeight;
  const std::array<PartShape, kPartCount> shapes = part_shapes(s);
  const std::array<Isometry3d, kPartCount> world_from_part = part_frames(pose_at(time_s, options), s);
  const std::array<Isometry3d, kPartCount> rest_from_part = part_frames(Joints{}, s);

  // Profiles first, to size the mesh once.
  const double spacing = 0.6 * s / options.segments;
  const int min_around = std::max(6, options.segments / 2), max_around = 2 * options.segments;
  std::array<std::vector<Ring>, kPartCount> rings;
  std::array<double, kPartCount> z_bottom{}, z_top{};
  std::array<int, kPartCount> around{};
  size_t vertex_count = 0, triangle_count = 0;
  for (int i = 0; i < kPartCount; ++i) {
    const PartShape& p = shapes[i];
    const double h = spacing * p.spacing;
    double circumference = 0;
    if (p.shape == Shape::kCapsule) {
      capsule_profile(p, h, rings[i], z_bottom[i], z_top[i]);
      const double r = std::max(p.r0, p.r1);
      circumference = 2 * kPi * r * std::sqrt(0.5 * (1 + p.scale_x * p.scale_x));
    } else {
      ellipsoid_profile(p, h, std::max(4, options.segments / 4), rings[i], z_bottom[i], z_top[i]);
      circumference = 2 * kPi * std::sqrt(0.5 * (p.semi.x() * p.semi.x() + p.semi.y() * p.semi.y()));
    }
    around[i] = std::clamp(4 * static_cast<int>(std::lround(circumference / (4 * h))), min_around, max_around);
    vertex_count += 2 + rings[i].size() * around[i];
    triangle_count += 2 * rings[i].size() * around[i];
  }

  TriangleMesh mesh;
  mesh.positions.reserve(vertex_count);
  mesh.colors.reserve(vertex_count);
  mesh.triangles.reserve(triangle_count);
  std::vector<double> cos_sin;
  for (int i = 0; i < kPartCount; ++i) {
    append_part(shapes[i], rings[i], z_bottom[i], z_top[i], around[i], world_from_part[i], rest_from_part[i], s,
                cos_sin, mesh);
  }
  assert(mesh.positions.size() == vertex_count && mesh.triangles.size() == triangle_count);

  // Rest the lowest vertex on the floor.
  float min_z = std::numeric_limits<float>::infinity();
  for (const Eigen::Vector3f& p : mesh.positions) min_z = std::min(min_z, p.z());
  for (Eigen::Vector3f& p : mesh.positions) p.z() -= min_z;
  return mesh;
}

}  // namespace zipfusion
