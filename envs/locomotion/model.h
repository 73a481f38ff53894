// Locomotion robots as data: bodies, joints and geoms as the MJCF files of PyBullet's locomotion environments
// describe them, and the builder that turns such a description into a bullet::RobotSpec with the link
// structure, masses, centres of mass and inertias PyBullet's MJCF import gives it (docs/ENVIRONMENTS.md).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "envs/bullet/robot.h"

namespace hlt::locomotion {

// A collision shape of a body, in the body's frame.
struct Geom {
  enum class Kind { kFromTo, kCapsule, kSphere };
  Kind kind = Kind::kSphere;
  Eigen::Vector3d from = Eigen::Vector3d::Zero();  // kFromTo: the two ends
  Eigen::Vector3d to = Eigen::Vector3d::Zero();
  Eigen::Vector3d pos = Eigen::Vector3d::Zero();  // kCapsule, kSphere: the centre
  // kCapsule: a capsule along z turned by turn_angle (rad) about turn_axis (MJCF axisangle).
  Eigen::Vector3d turn_axis = Eigen::Vector3d::UnitY();
  double turn_angle = 0.0;
  double half_length = 0.0;  // kCapsule: half the cylinder's length
  double radius = 0.0;

  // MJCF fromto="from to" size="radius".
  static Geom fromto(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double radius);
  // MJCF pos="pos" axisangle="0 1 0 angle" size="radius half_length": a capsule along z turned about y.
  static Geom capsule_about_y(const Eigen::Vector3d& pos, double angle, double radius, double half_length);
  static Geom sphere(const Eigen::Vector3d& pos, double radius);
};

struct Joint {
  std::string name;
  bullet::JointType type = bullet::JointType::kRevolute;  // hinge or slide
  Eigen::Vector3d pos = Eigen::Vector3d::Zero();          // in the body's frame
  Eigen::Vector3d axis = Eigen::Vector3d::UnitY();        // as written (PyBullet does not normalise it)
  // rad or m, as PyBullet holds it: a range the file gives in degrees converted with deg(), one given in
  // radians rounded with single(). None: unlimited.
  std::optional<std::pair<double, double>> range;
  bool actuated = true;       // false: a root joint the agent does not drive
  double power_coef = 100.0;  // torque = power * power_coef * clip(a, -1, 1)
};

struct Body {
  std::string name;
  std::string parent;  // empty for the root body
  Eigen::Vector3d pos =
      Eigen::Vector3d::Zero();  // frame origin in the parent's frame (frames are world-aligned)
  std::vector<Joint> joints;    // to the parent; a root body's joints attach it to the world
  std::vector<Geom> geoms;
  std::optional<double> mass;  // default: 1000 kg/m^3 times the geoms' volume
  double friction = 0.8;
};

struct Model {
  std::string name;
  std::vector<Body> bodies;  // the root first, every parent before its children (MJCF file order)
};

struct ActuatedJoint {
  std::string name;
  int link = -1;  // the robot link whose joint it is
  double lower = 0.0, upper = 0.0;
  double power_coef = 100.0;
};

struct BuiltModel {
  bullet::RobotSpec spec;
  std::vector<ActuatedJoint> joints;           // in file order, which is the action order
  std::map<std::string, int> bodies;           // body name -> link index (-1: the base)
  int link_of(const std::string& body) const;  // throws naming the known bodies
};

// Builds a model the way PyBullet imports MJCF (positions, capsule sizes, axes, angles and frictions are
// first rounded with single(), as PyBullet's MJCF parser reads them; masses and sphere radii it reads in
// double precision): every joint becomes a massless link carrying that joint (named "joint:<name>", placed at
// the joint), and every body a link fixed to the last of its joint links (or to its parent body when it has
// none), its frame at the body origin. A root body with joints hangs from a massless fixed base at the world
// origin; one without joints is a floating base. Links appear depth first in file order. A body's mass is
// 1000 kg/m^3 times its geoms' volume unless given; its COM is the middle of its last geom when that is a
// fromto capsule and its frame origin otherwise (PyBullet's rule); its inertia is bullet::estimated_inertia
// of its shapes. Geoms collide with the ground only. Throws hlt::Error for an inconsistent description
// (unknown or late parent, duplicate names, a floating root without mass, an actuated joint without a range,
// joints of one body at different positions, bad geoms).
BuiltModel build(const Model& model);

// A number as PyBullet's MJCF parser reads it (single precision). The rounding goes through a volatile
// float: GCC 12's SLP vectoriser at -O2 and above drops a double -> float -> double round trip.
inline double single(double x) {
  volatile float f = static_cast<float>(x);
  return f;
}

// Degrees to radians as PyBullet converts MJCF ranges given in degrees: in single precision, with pi in
// single precision (-150 degrees becomes -2.6179940700531006 rad).
inline double deg(double degrees) {
  volatile float f = static_cast<float>(degrees) * static_cast<float>(3.14159265358979323846);
  f = f / 180.0f;
  return f;
}

}  // namespace hlt::locomotion
