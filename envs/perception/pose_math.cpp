#include "envs/perception/pose_math.h"

#include <algorithm>
#include <cmath>

#include "hlt/util/error.h"

namespace hlt {

Eigen::Isometry3d pose_from_xyz_rpy(double x, double y, double z, double roll, double pitch, double yaw) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  pose.translation() = Eigen::Vector3d(x, y, z);
  return pose;
}

double yaw_of(const Eigen::Matrix3d& R) {
  return std::atan2(R(1, 0), R(0, 0));
}

double wrap_angle(double a) {
  a = std::remainder(a, 2.0 * M_PI);
  return a <= -M_PI ? a + 2.0 * M_PI : a;
}

double rotation_angle_between(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const double c = std::clamp(((a.transpose() * b).trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c);
}

bool is_finite(const Eigen::Isometry3d& pose) {
  return pose.matrix().allFinite();
}

Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                          const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = target - eye;
  check(z.norm() > 1e-9, "look_at: eye and target coincide");
  const Eigen::Vector3d zn = z.normalized();
  Eigen::Vector3d x = zn.cross(up);  // image right = forward x up for a y-down camera frame
  check(x.norm() > 1e-9, "look_at: viewing direction is parallel to the up vector");
  x.normalize();
  const Eigen::Vector3d y = zn.cross(x);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear().col(0) = x;
  pose.linear().col(1) = y;
  pose.linear().col(2) = zn;
  pose.translation() = eye;
  return pose;
}

}  // namespace hlt
