#include "envs/robot/arm.h"

#include <algorithm>
#include <cmath>

#include <btBulletDynamicsCommon.h>

#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointFeedback.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointMotor.h>

#include "hlt/util/error.h"

namespace hlt::robot {

namespace {

constexpr double kPi = 3.14159265358979323846;

using Eigen::Isometry3d;
using Eigen::Matrix3d;
using Eigen::Vector3d;

Matrix3d rot_x(double a) {
  return Eigen::AngleAxisd(a, Vector3d::UnitX()).toRotationMatrix();
}

// A URDF joint origin: translation, then the fixed-axis roll-pitch-yaw rotation Rz(y) Ry(p) Rx(r).
Isometry3d urdf_origin(const Vector3d& xyz, const Vector3d& rpy) {
  Isometry3d t = Isometry3d::Identity();
  t.translation() = xyz;
  t.linear() = (Eigen::AngleAxisd(rpy.z(), Vector3d::UnitZ()) *
                Eigen::AngleAxisd(rpy.y(), Vector3d::UnitY()) * Eigen::AngleAxisd(rpy.x(), Vector3d::UnitX()))
                   .toRotationMatrix();
  return t;
}

// One link of Craig's modified DH convention at theta = 0: Rx(alpha) Tx(a) Tz(d).
Isometry3d craig(double a, double d, double alpha) {
  Isometry3d t = Isometry3d::Identity();
  t.linear() = rot_x(alpha);
  t.translation() = Vector3d(a, 0, 0);
  Isometry3d tz = Isometry3d::Identity();
  tz.translation() = Vector3d(0, 0, d);
  return t * tz;
}

// A cylinder of `length` along the frame's z axis at `centre`, drawn and collided as a capsule of that
// length between its end centres.
bullet::Shape frame_cylinder(const Isometry3d& frame, const Vector3d& centre, double radius, double length) {
  const Vector3d half(0, 0, 0.5 * length);
  return bullet::Shape::capsule(frame * (centre - half), frame * (centre + half), radius);
}

// Principal moments given in a frame turned into the world's axes; off-diagonal terms that appear (none for
// frames that are signed permutations of the world's, as at these arms' zero poses) are dropped.
Vector3d world_moments(const Matrix3d& frame, const Vector3d& moments) {
  const Matrix3d i = frame * moments.asDiagonal() * frame.transpose();
  return i.diagonal();
}

bullet::LinkSpec arm_link(const std::string& name, int parent, const Isometry3d& joint_frame, double mass) {
  bullet::LinkSpec l;
  l.name = name;
  l.parent = parent;
  l.joint = bullet::JointType::kRevolute;
  l.anchor = joint_frame.translation();
  l.axis = joint_frame.linear().col(2);
  l.mass = mass;
  // The arm's own links never touch anything: only the tool, fingers, blocks and table collide.
  l.collides = false;
  return l;
}

Vector3d centroid(const std::vector<bullet::Shape>& shapes) {
  Vector3d c = Vector3d::Zero();
  for (const auto& s : shapes)
    c += 0.5 * (s.from + s.to);
  return c / static_cast<double>(shapes.size());
}

}  // namespace

Eigen::Vector3d orientation_error(const Eigen::Matrix3d& to, const Eigen::Matrix3d& from) {
  const Eigen::AngleAxisd aa(to * from.transpose());
  return aa.angle() * aa.axis();
}

ArmModel sawyer_model(const Eigen::Vector3d& base) {
  struct Joint {
    Vector3d xyz, rpy;
    double lo, hi, speed, effort, mass;
  };
  // Rethink's URDF (ROBOT_TASKS.md): joint origins in the parent link's frame, every axis the child's z.
  const Joint joints[7] = {
      {{0, 0, 0.08}, {0, 0, 0}, -3.0503, 3.0503, 1.74, 80, 5.3213},
      {{0.081, 0.05, 0.237}, {-kPi / 2, kPi / 2, 0}, -3.8095, 2.2736, 1.328, 80, 4.505},
      {{0, -0.14, 0.1425}, {kPi / 2, 0, 0}, -3.0426, 3.0426, 1.957, 40, 1.745},
      {{0, -0.042, 0.26}, {-kPi / 2, 0, 0}, -3.0439, 3.0439, 1.957, 40, 2.5097},
      {{0, -0.125, -0.1265}, {kPi / 2, 0, 0}, -2.9761, 2.9761, 3.485, 9, 1.1136},
      {{0, 0.031, 0.275}, {-kPi / 2, 0, 0}, -2.9761, 2.9761, 3.485, 9, 1.5625},
      {{0, -0.11, 0.1053}, {-kPi / 2, -0.17453, 3.1416}, -4.7124, 4.7124, 4.545, 9, 0.3292},
  };
  ArmModel m;
  m.name = "sawyer";
  m.spec.name = "sawyer";
  m.spec.fixed_base = true;
  Isometry3d frame = Isometry3d::Identity();
  frame.translation() = base;
  // The pedestal under the base (drawn only): r 0.18, 0.62 m tall (a capsule: its cylinder 0.36 m).
  m.spec.base.name = "pedestal";
  m.spec.base.com = base;
  m.spec.base.shapes = {frame_cylinder(frame, Vector3d(0, 0, -0.31), 0.18, 0.62 - 2 * 0.18)};
  for (int k = 0; k < 7; ++k) {
    frame = frame * urdf_origin(joints[k].xyz, joints[k].rpy);
    bullet::LinkSpec l = arm_link("l" + std::to_string(k), k - 1, frame, joints[k].mass);
    // The URDF's collision primitives in the link's frame.
    switch (k) {
      case 0:
        l.shapes = {bullet::Shape::sphere(frame * Vector3d(0.08, 0, 0.23), 0.07)};
        break;
      case 1:
        l.shapes = {bullet::Shape::sphere(frame * Vector3d(0, 0, 0.1225), 0.07),
                    frame_cylinder(frame, Vector3d::Zero(), 0.07, 0.14)};
        break;
      case 2:
        l.shapes = {frame_cylinder(frame, Vector3d(0, 0, 0.08), 0.06, 0.34),
                    bullet::Shape::sphere(frame * Vector3d(0, 0, 0.26), 0.06)};
        break;
      case 3:
        l.shapes = {bullet::Shape::sphere(frame * Vector3d(0, -0.01, -0.12), 0.06)};
        break;
      case 4:
        l.shapes = {frame_cylinder(frame, Vector3d(0, 0, 0.11), 0.045, 0.30),
                    bullet::Shape::sphere(frame * Vector3d(0, 0.01, 0.26), 0.06)};
        break;
      case 5:
        l.shapes = {bullet::Shape::sphere(frame * Vector3d(0, 0, 0.1), 0.06)};
        break;
      case 6:
        l.shapes = {frame_cylinder(frame, Vector3d::Zero(), 0.055, 0.05)};
        break;
    }
    // No centres of mass or inertia tensors are published with these numbers: the COM is the centroid of
    // the link's primitives and the moments Bullet's own estimate for them (their bounding box).
    l.com = centroid(l.shapes);
    l.inertia = bullet::estimated_inertia(l.mass, l.shapes, l.com);
    l.limits = std::make_pair(joints[k].lo, joints[k].hi);
    m.joints[k] = k;
    m.lower[k] = joints[k].lo;
    m.upper[k] = joints[k].hi;
    m.max_speed[k] = joints[k].speed;
    m.max_effort[k] = joints[k].effort;
    m.spec.links.push_back(l);
  }
  // The hand frame, then our pushing tool: a rod r 15 mm from 2 cm to 12 cm along the hand's z, the tool
  // centre point at the centre of its rounded tip.
  const Isometry3d hand = frame * urdf_origin({0, 0, 0.0245}, {0, 0, kPi / 2});
  bullet::LinkSpec h;
  h.name = "hand";
  h.parent = 6;
  h.joint = bullet::JointType::kFixed;
  h.anchor = hand.translation();
  h.mass = 0.3;
  h.shapes = {frame_cylinder(hand, Vector3d::Zero(), 0.035, 0.03),
              bullet::Shape::capsule(hand * Vector3d(0, 0, 0.02), hand * Vector3d(0, 0, 0.12), 0.015)};
  h.com = hand * Vector3d(0, 0, 0.06);
  h.inertia = bullet::estimated_inertia(h.mass, h.shapes, h.com);
  h.collides = true;
  h.friction = 0.5;
  m.hand = 7;
  m.spec.links.push_back(h);
  Isometry3d tool = hand;
  tool.translation() = hand * Vector3d(0, 0, 0.12);
  // The hand's body frame is world-aligned at the zero pose and sits at its COM.
  Isometry3d hand_body = Isometry3d::Identity();
  hand_body.translation() = h.com;
  m.tool_in_hand = hand_body.inverse() * tool;
  // Rethink's "neutral" pose.
  m.seed << 0, -1.18, 0, 2.18, 0, 0.57, 3.3161;
  return m;
}

ArmModel panda_model(const Eigen::Vector3d& base) {
  struct Joint {
    double a, d, alpha, lo, hi, speed, effort, mass;
    Vector3d com, moments;  // in the link's DH frame (Gaz et al. 2019; the tensors' diagonals)
  };
  const Joint joints[7] = {
      {0,
       0.333,
       0,
       -2.8973,
       2.8973,
       2.1750,
       87,
       4.970684,
       {0.003875, 0.002081, -0.04762},
       {0.70337, 0.70661, 0.009117}},
      {0,
       0,
       -kPi / 2,
       -1.7628,
       1.7628,
       2.1750,
       87,
       0.646926,
       {-0.003141, -0.02872, 0.003495},
       {0.007962, 0.02811, 0.025995}},
      {0,
       0.316,
       kPi / 2,
       -2.8973,
       2.8973,
       2.1750,
       87,
       3.228604,
       {0.027518, 0.039252, -0.066502},
       {0.037242, 0.036155, 0.01083}},
      {0.0825,
       0,
       kPi / 2,
       -3.0718,
       -0.0698,
       2.1750,
       87,
       3.587895,
       {-0.05317, 0.104419, 0.027454},
       {0.025853, 0.019552, 0.028323}},
      {-0.0825,
       0.384,
       -kPi / 2,
       -2.8973,
       2.8973,
       2.6100,
       12,
       1.225946,
       {-0.011953, 0.041065, -0.038437},
       {0.035549, 0.029474, 0.008627}},
      {0,
       0,
       kPi / 2,
       -0.0175,
       3.7525,
       2.6100,
       12,
       1.666555,
       {0.060149, -0.014117, -0.010517},
       {0.001964, 0.004354, 0.005433}},
      {0.088,
       0,
       kPi / 2,
       -2.8973,
       2.8973,
       2.6100,
       12,
       0.735522,
       {0.010517, -0.004252, 0.061597},
       {0.012516, 0.010027, 0.004815}},
  };
  ArmModel m;
  m.name = "panda";
  m.spec.name = "panda";
  m.spec.fixed_base = true;
  Isometry3d frame = Isometry3d::Identity();
  frame.translation() = base;
  m.spec.base.name = "link0";
  m.spec.base.com = base;
  m.spec.base.shapes = {
      bullet::Shape::capsule(base + Vector3d(0, 0, 0.06), base + Vector3d(0, 0, 0.2), 0.06)};
  std::vector<Isometry3d> frames;
  for (int k = 0; k < 7; ++k) {
    frame = frame * craig(joints[k].a, joints[k].d, joints[k].alpha);
    frames.push_back(frame);
  }
  const Isometry3d flange = frame * craig(0, 0.107, 0);
  frames.push_back(flange);
  for (int k = 0; k < 7; ++k) {
    bullet::LinkSpec l = arm_link("link" + std::to_string(k + 1), k - 1, frames[k], joints[k].mass);
    // Drawn as a capsule between consecutive DH origins (a sphere where they coincide): no more
    // geometry than that is modelled, since the arm itself does not collide.
    const Vector3d from = k == 0 ? Vector3d(base + Vector3d(0, 0, 0.2)) : frames[k].translation();
    const Vector3d to = frames[k + 1].translation();
    const double radius = k == 6 ? 0.04 : 0.06;
    if ((to - from).norm() < 1e-6) {
      l.shapes = {bullet::Shape::sphere(from, radius)};
    } else {
      l.shapes = {bullet::Shape::capsule(from, to, radius)};
    }
    l.com = frames[k] * joints[k].com;
    l.inertia = world_moments(frames[k].linear(), joints[k].moments);
    l.limits = std::make_pair(joints[k].lo, joints[k].hi);
    m.joints[k] = k;
    m.lower[k] = joints[k].lo;
    m.upper[k] = joints[k].hi;
    m.max_speed[k] = joints[k].speed;
    m.max_effort[k] = joints[k].effort;
    m.spec.links.push_back(l);
  }
  // The hand on the flange, without Franka's -pi/4 turn about the flange axis (so that its box and the
  // fingers' run along the world's axes at the zero pose); joint 7 absorbs the difference.
  bullet::LinkSpec h;
  h.name = "hand";
  h.parent = 6;
  h.joint = bullet::JointType::kFixed;
  h.anchor = flange.translation();
  h.mass = 0.73;
  h.com = flange * Vector3d(-0.01, 0, 0.03);
  h.inertia = world_moments(flange.linear(), Vector3d(0.001, 0.0025, 0.0017));
  // A box 0.06 x 0.2 x 0.058 between the flange and the fingers' roots.
  const Vector3d half_local(0.03, 0.1, 0.029);
  h.shapes = {bullet::Shape::box(h.com, (flange.linear() * half_local).cwiseAbs())};
  // A box's centre must be the body's COM to stay a lone box (Bullet's box-box detector).
  h.collides = true;
  h.friction = 1.0;
  m.hand = 7;
  m.spec.links.push_back(h);
  // Two fingers sliding apart along the hand's +-y from the fingers' root 0.0584 m beyond the flange; each a
  // 2 x 2 x 5 cm pad whose inner face is at the joint's opening.
  for (int side = 0; side < 2; ++side) {
    const double s = side == 0 ? 1.0 : -1.0;
    bullet::LinkSpec f;
    f.name = side == 0 ? "finger_left" : "finger_right";
    f.parent = 7;
    f.joint = bullet::JointType::kPrismatic;
    f.anchor = flange * Vector3d(0, 0, 0.0584);
    f.axis = flange.linear() * Vector3d(0, s, 0);
    f.mass = 0.015;
    f.com = flange * Vector3d(0, s * 0.01, 0.0584 + 0.025);
    f.shapes = {bullet::Shape::box(f.com, (flange.linear() * Vector3d(0.01, 0.01, 0.025)).cwiseAbs())};
    f.inertia = bullet::estimated_inertia(f.mass, f.shapes, f.com);
    f.limits = std::make_pair(0.0, 0.04);
    f.collides = true;
    f.friction = 1.0;
    m.fingers.push_back(8 + side);
    m.spec.links.push_back(f);
  }
  m.finger_travel = 0.04;
  m.finger_max_speed = 0.2;
  m.finger_max_force = 70.0;
  Isometry3d tool = flange;
  tool.translation() = flange * Vector3d(0, 0, 0.1034);
  Isometry3d hand_body = Isometry3d::Identity();
  hand_body.translation() = h.com;
  m.tool_in_hand = hand_body.inverse() * tool;
  m.seed << 0, -0.3, 0, -2.2, 0, 2.0, 0;
  return m;
}

Arm::Arm(bullet::World& world, ArmModel model) : model_(std::move(model)), world_(world.bullet()) {
  for (int k = 0; k < 7; ++k) {
    check(model_.max_speed[k] > 0 && model_.max_effort[k] > 0,
          "arm '{}': joint {} needs speed and effort limits", model_.name, k);
  }
  robot_ = &world.add_robot(model_.spec);
  btMultiBody& mb = robot_->multibody();
  dofs_ = mb.getNumDofs();
  // The motors start switched off (no impulse); drive() sets their target and strength every sub-step.
  for (int k = 0; k < 7; ++k)
    motors_.push_back(std::make_unique<btMultiBodyJointMotor>(&mb, model_.joints[k], 0.0, 0.0));
  for (int f : model_.fingers)
    motors_.push_back(std::make_unique<btMultiBodyJointMotor>(&mb, f, 0.0, 0.0));
  for (auto& motor : motors_)
    world_.addMultiBodyConstraint(motor.get());
  feedback_ = std::make_unique<btMultiBodyJointFeedback>();
  mb.getLink(model_.hand).m_jointFeedback = feedback_.get();
  set_configuration(model_.seed, 0.0);
}

Arm::~Arm() {
  for (auto& motor : motors_)
    world_.removeMultiBodyConstraint(motor.get());
  robot_->multibody().getLink(model_.hand).m_jointFeedback = nullptr;
}

Vector7d Arm::positions() const {
  Vector7d q;
  for (int k = 0; k < 7; ++k)
    q[k] = robot_->joint_position(model_.joints[k]);
  return q;
}

Vector7d Arm::velocities() const {
  Vector7d qd;
  for (int k = 0; k < 7; ++k)
    qd[k] = robot_->joint_velocity(model_.joints[k]);
  return qd;
}

void Arm::set_configuration(const Vector7d& q, double finger_opening) {
  bullet::Robot& r = *robot_;
  for (int k = 0; k < 7; ++k)
    r.set_joint_state(model_.joints[k], q[k], 0.0);
  for (int f : model_.fingers)
    r.set_joint_state(f, std::clamp(finger_opening, 0.0, model_.finger_travel), 0.0);
}

double Arm::finger_opening() const {
  if (model_.fingers.empty()) return 0.0;
  double sum = 0.0;
  for (int f : model_.fingers)
    sum += robot_->joint_position(f);
  return sum / static_cast<double>(model_.fingers.size());
}

Eigen::Isometry3d Arm::tool_pose() const {
  return robot_->body_pose(model_.hand) * model_.tool_in_hand;
}

int Arm::dof(int link) const {
  return robot_->multibody().getLink(link).m_dofOffset;
}

Eigen::VectorXd Arm::jacobian_row(int link, const Eigen::Vector3d& point, const Eigen::Vector3d& normal_ang,
                                  const Eigen::Vector3d& normal_lin) const {
  btAlignedObjectArray<btScalar> scratch_r;
  btAlignedObjectArray<btVector3> scratch_v;
  btAlignedObjectArray<btMatrix3x3> scratch_m;
  std::vector<btScalar> row(6 + dofs_, 0.0);
  robot_->multibody().fillConstraintJacobianMultiDof(
      link, btVector3(point.x(), point.y(), point.z()),
      btVector3(normal_ang.x(), normal_ang.y(), normal_ang.z()),
      btVector3(normal_lin.x(), normal_lin.y(), normal_lin.z()), row.data(), scratch_r, scratch_v, scratch_m);
  // The first six entries belong to the (fixed) base.
  Eigen::VectorXd out(dofs_);
  for (int i = 0; i < dofs_; ++i)
    out[i] = row[6 + i];
  return out;
}

Jacobian Arm::jacobian() const {
  const Vector3d p = tool_pose().translation();
  Jacobian j;
  for (int r = 0; r < 6; ++r) {
    const Vector3d e = Vector3d::Unit(r % 3);
    const Eigen::VectorXd row = r < 3 ? jacobian_row(model_.hand, p, Vector3d::Zero(), e)
                                      : jacobian_row(model_.hand, p, e, Vector3d::Zero());
    for (int k = 0; k < 7; ++k)
      j(r, k) = row[dof(model_.joints[k])];
  }
  return j;
}

void Arm::drive(const Vector7d& qd, double finger_speed, double h) {
  check(qd.allFinite() && std::isfinite(finger_speed) && h > 0, "arm '{}': bad drive command", model_.name);
  for (int k = 0; k < 7; ++k) {
    const double v = std::clamp(qd[k], -model_.max_speed[k], model_.max_speed[k]);
    motors_[k]->setVelocityTarget(v);
    motors_[k]->setMaxAppliedImpulse(model_.max_effort[k] * h);
  }
  for (size_t f = 0; f < model_.fingers.size(); ++f) {
    auto& motor = motors_[7 + f];
    motor->setVelocityTarget(std::clamp(finger_speed, -model_.finger_max_speed, model_.finger_max_speed));
    motor->setMaxAppliedImpulse(model_.finger_max_force * h);
  }
}

Vector6d Arm::wrist_wrench() const {
  // Bullet reports the spatial force the flange applies to the hand's subtree, in the hand's frame (linear
  // part first); what the hand exerts on the flange is its opposite.
  const btSpatialForceVector& f = feedback_->m_reactionForces;
  const Matrix3d r = robot_->body_pose(model_.hand).linear();
  Vector6d w;
  w.head<3>() = -(r * Vector3d(f.m_topVec.x(), f.m_topVec.y(), f.m_topVec.z()));
  w.tail<3>() = -(r * Vector3d(f.m_bottomVec.x(), f.m_bottomVec.y(), f.m_bottomVec.z()));
  return w;
}

double Arm::hand_mass() const {
  double mass = model_.spec.links[model_.hand].mass;
  for (int f : model_.fingers)
    mass += model_.spec.links[f].mass;
  return mass;
}

Vector6d Arm::resting_wrist_wrench(double gravity_z) const {
  Vector6d w = Vector6d::Zero();
  w[2] = hand_mass() * gravity_z;
  return w;
}

Eigen::Vector3d Arm::hand_momentum() const {
  Eigen::Vector3d p = model_.spec.links[model_.hand].mass * robot_->com_linear_velocity(model_.hand);
  for (int f : model_.fingers)
    p += model_.spec.links[f].mass * robot_->com_linear_velocity(f);
  return p;
}

bool Arm::solve_ik(const Eigen::Isometry3d& target, const Vector7d& start, Vector7d* q_out) {
  Vector7d q = start;
  bool converged = false;
  for (int it = 0; it < 500 && !converged; ++it) {
    set_configuration(q, finger_opening());
    const Eigen::Isometry3d pose = tool_pose();
    Vector6d e;
    e.head<3>() = target.translation() - pose.translation();
    e.tail<3>() = orientation_error(target.linear(), pose.linear());
    converged = e.head<3>().norm() < 1e-4 && e.tail<3>().norm() < 1e-3;
    if (converged) break;
    const Jacobian j = jacobian();
    const Eigen::Matrix<double, 6, 6> jjt =
        j * j.transpose() + 1e-4 * Eigen::Matrix<double, 6, 6>::Identity();
    Vector7d dq = j.transpose() * jjt.ldlt().solve(e);
    // Small steps keep the iteration on the branch it started on.
    const double n = dq.norm();
    if (n > 0.2) dq *= 0.2 / n;
    q = (q + dq).cwiseMax(model_.lower).cwiseMin(model_.upper);
  }
  set_configuration(q, finger_opening());
  if (q_out != nullptr) *q_out = q;
  return converged;
}

}  // namespace hlt::robot
