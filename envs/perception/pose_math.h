// Small rigid-transform helpers shared by the perception pieces. Transforms are named `a_from_b`: a point
// in frame b maps to frame a as p_a = a_from_b * p_b.
#pragma once

#include <Eigen/Geometry>

namespace hlt {

// A pose from a translation and roll/pitch/yaw (radians, applied as R = Rz(yaw) Ry(pitch) Rx(roll)).
Eigen::Isometry3d pose_from_xyz_rpy(double x, double y, double z, double roll, double pitch, double yaw);

// Rotation about z of R's x axis, projected on the xy plane (radians, in (-pi, pi]).
double yaw_of(const Eigen::Matrix3d& R);

// Wraps an angle into (-pi, pi].
double wrap_angle(double a);

// The angle of the rotation a^T b (radians, in [0, pi]).
double rotation_angle_between(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);

bool is_finite(const Eigen::Isometry3d& pose);

// A camera pose (camera frame: x right, y down, z forward) at `eye`, looking at `target`, with the image's
// up direction as close as possible to `up`.
Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                          const Eigen::Vector3d& up = Eigen::Vector3d::UnitZ());

}  // namespace hlt
