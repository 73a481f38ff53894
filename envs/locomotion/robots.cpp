#include "envs/locomotion/robots.h"

#include <string>

namespace hlt {

namespace locomotion {

namespace {

using V = Eigen::Vector3d;

// The planar root the 2-D robots' MJCF gives the torso (PyBullet's "ignore" joints: not driven, unlimited).
std::vector<Joint> planar_root() {
  Joint x{"ignorex", bullet::JointType::kPrismatic, V::Zero(), V::UnitX(), std::nullopt, false};
  Joint z{"ignorez", bullet::JointType::kPrismatic, V::Zero(), V::UnitZ(), std::nullopt, false};
  Joint y{"ignorey", bullet::JointType::kRevolute, V::Zero(), V::UnitY(), std::nullopt, false};
  return {x, z, y};
}

Joint hinge(const std::string& name, const V& pos, const V& axis, double lower, double upper,
            double power_coef = 100.0) {
  return {name, bullet::JointType::kRevolute, pos, axis, std::make_pair(lower, upper), true, power_coef};
}

Body body(const std::string& name, const std::string& parent, const V& pos, std::vector<Joint> joints,
          std::vector<Geom> geoms, double friction) {
  Body b;
  b.name = name;
  b.parent = parent;
  b.pos = pos;
  b.joints = std::move(joints);
  b.geoms = std::move(geoms);
  b.friction = friction;
  return b;
}

}  // namespace

WalkerSpec hopper_spec() {
  // hopper.xml uses global coordinates; PyBullet reads them as local with every body at the origin, so the
  // torso turns about a point on the ground (the root joints sit at its frame origin).
  const double mu = 0.8;
  const V down(0, -1, 0);
  Model m;
  m.name = "hopper";
  m.bodies = {
      body("torso", "", V::Zero(), planar_root(), {Geom::fromto({0, 0, 1.45}, {0, 0, 1.05}, 0.05)}, mu),
      body("thigh", "torso", V::Zero(), {hinge("thigh_joint", {0, 0, 1.05}, down, deg(-150), deg(0))},
           {Geom::fromto({0, 0, 1.05}, {0, 0, 0.6}, 0.05)}, mu),
      body("leg", "thigh", V::Zero(), {hinge("leg_joint", {0, 0, 0.6}, down, deg(-150), deg(0))},
           {Geom::fromto({0, 0, 0.6}, {0, 0, 0.1}, 0.04)}, mu),
      body("foot", "leg", V::Zero(), {hinge("foot_joint", {0, 0, 0.1}, down, deg(-45), deg(45))},
           {Geom::fromto({-0.13, 0, 0.1}, {0.26, 0, 0.1}, 0.06)}, mu),
  };
  WalkerSpec s;
  s.name = "hopper";
  s.model = std::move(m);
  s.power = 0.75;
  s.feet = {"foot"};
  s.alive.min_z = 0.8;
  s.alive.max_abs_pitch = 1.0;
  return s;
}

WalkerSpec half_cheetah_spec() {
  const double mu = 0.8, r = 0.046;
  const V y = V::UnitY(), o = V::Zero();
  // half_cheetah.xml gives its ranges in radians, which PyBullet keeps in single precision.
  const auto range_hinge = [&](const std::string& name, double lower, double upper, double power_coef) {
    return hinge(name, o, y, single(lower), single(upper), power_coef);
  };
  Model m;
  m.name = "half_cheetah";
  m.bodies = {
      body("torso", "", {0, 0, 0.7}, planar_root(),
           {Geom::fromto({-0.5, 0, 0}, {0.5, 0, 0}, r), Geom::capsule_about_y({0.6, 0, 0.1}, 0.87, r, 0.15)},
           mu),
      body("bthigh", "torso", {-0.5, 0, 0}, {range_hinge("bthigh", -0.52, 1.05, 120)},
           {Geom::capsule_about_y({0.1, 0, -0.13}, -3.8, r, 0.145)}, mu),
      body("bshin", "bthigh", {0.16, 0, -0.25}, {range_hinge("bshin", -0.785, 0.785, 90)},
           {Geom::capsule_about_y({-0.14, 0, -0.07}, -2.03, r, 0.15)}, mu),
      body("bfoot", "bshin", {-0.28, 0, -0.14}, {range_hinge("bfoot", -0.4, 0.785, 60)},
           {Geom::capsule_about_y({0.03, 0, -0.097}, -0.27, r, 0.094)}, mu),
      body("fthigh", "torso", {0.5, 0, 0}, {range_hinge("fthigh", -1.5, 0.8, 140)},
           {Geom::capsule_about_y({-0.07, 0, -0.12}, 0.52, r, 0.133)}, mu),
      body("fshin", "fthigh", {-0.14, 0, -0.24}, {range_hinge("fshin", -1.2, 1.1, 60)},
           {Geom::capsule_about_y({0.065, 0, -0.09}, -0.6, r, 0.106)}, mu),
      body("ffoot", "fshin", {0.13, 0, -0.18}, {range_hinge("ffoot", -3.1, -0.3, 30)},
           {Geom::capsule_about_y({0.045, 0, -0.07}, -0.6, r, 0.07)}, mu),
  };
  // The feet carry an explicit 10 kg.
  m.bodies[3].mass = 10.0;
  m.bodies[6].mass = 10.0;
  WalkerSpec s;
  s.name = "half_cheetah";
  s.model = std::move(m);
  s.power = 0.9;
  s.feet = {"ffoot", "fshin", "fthigh", "bfoot", "bshin", "bthigh"};
  // Knees and thighs on the floor cost the alive bonus (PyBullet's guard against walking on the knees), but
  // the episode never ends early.
  s.alive.max_abs_pitch = 1.0;
  s.alive.forbidden_feet = {1, 2, 4, 5};
  s.ends_when_not_alive = false;
  return s;
}

WalkerSpec ant_spec() {
  const double mu = 1.5, r = 0.08;
  Model m;
  m.name = "ant";
  m.bodies = {body("torso", "", {0, 0, 0.75}, {}, {Geom::sphere(V::Zero(), 0.25)}, mu)};
  struct Leg {
    const char* leg;
    const char* foot;
    double sx, sy;
    V ankle_axis;
    double ankle_lower, ankle_upper;  // degrees
  };
  const Leg legs[4] = {{"front_left_leg", "front_left_foot", 1, 1, {-1, 1, 0}, 30, 100},
                       {"front_right_leg", "front_right_foot", -1, 1, {1, 1, 0}, -100, -30},
                       {"left_back_leg", "left_back_foot", -1, -1, {-1, 1, 0}, -100, -30},
                       {"right_back_leg", "right_back_foot", 1, -1, {1, 1, 0}, 30, 100}};
  for (int k = 0; k < 4; ++k) {
    const Leg& l = legs[k];
    const std::string n = std::to_string(k + 1);
    const V d(0.2 * l.sx, 0.2 * l.sy, 0);
    m.bodies.push_back(body(l.leg, "torso", V::Zero(), {}, {Geom::fromto(V::Zero(), d, r)}, mu));
    m.bodies.push_back(body("aux_" + n, l.leg, d,
                            {hinge("hip_" + n, V::Zero(), V::UnitZ(), deg(-40), deg(40))},
                            {Geom::fromto(V::Zero(), d, r)}, mu));
    m.bodies.push_back(
        body(l.foot, "aux_" + n, d,
             {hinge("ankle_" + n, V::Zero(), l.ankle_axis, deg(l.ankle_lower), deg(l.ankle_upper))},
             {Geom::fromto(V::Zero(), 2 * d, r)}, mu));
  }
  WalkerSpec s;
  s.name = "ant";
  s.model = std::move(m);
  s.power = 2.5;
  s.feet = {"front_left_foot", "front_right_foot", "left_back_foot", "right_back_foot"};
  s.alive.min_z = 0.26;  // the torso sphere's radius is 0.25
  s.top_view = true;
  return s;
}

}  // namespace locomotion

std::unique_ptr<Env> make_hopper() {
  return std::make_unique<locomotion::Walker>(locomotion::hopper_spec());
}
std::unique_ptr<Env> make_half_cheetah() {
  return std::make_unique<locomotion::Walker>(locomotion::half_cheetah_spec());
}
std::unique_ptr<Env> make_ant() {
  return std::make_unique<locomotion::Walker>(locomotion::ant_spec());
}

}  // namespace hlt
