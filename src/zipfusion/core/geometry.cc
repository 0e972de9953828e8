#include "zipfusion/core/geometry.h"

#include <Eigen/SVD>
#include <cassert>
#include <cmath>
#include <numbers>

namespace zipfusion {

bool is_rigid(const Eigen::Matrix4d& m, double tolerance) {
  if (!m.allFinite()) return false;
  if (m.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) return false;
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  const double orthonormality_error = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  return orthonormality_error <= tolerance && std::abs(r.determinant() - 1.0) <= tolerance;
}

Rigid3d nearest_rigid(const Eigen::Matrix4d& m) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m.topLeftCorner<3, 3>(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) {
    Eigen::Matrix3d u = svd.matrixU();
    u.col(2) *= -1;
    r = u * svd.matrixV().transpose();
  }
  Rigid3d t = Rigid3d::Identity();
  t.linear() = r;
  t.translation() = m.topRightCorner<3, 1>();
  return t;
}

double rotation_angle_deg(const Rigid3d& t) {
  return Eigen::AngleAxisd(t.rotation()).angle() * 180.0 / std::numbers::pi;
}

Rigid3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d up(0, 0, 1);
  const Eigen::Vector3d z = (target - eye).normalized();
  assert(z.cross(up).norm() > 1e-9);
  const Eigen::Vector3d x = z.cross(up).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Rigid3d world_from_cam = Rigid3d::Identity();
  world_from_cam.linear().col(0) = x;
  world_from_cam.linear().col(1) = y;
  world_from_cam.linear().col(2) = z;
  world_from_cam.translation() = eye;
  return world_from_cam;
}

}  // namespace zipfusion
