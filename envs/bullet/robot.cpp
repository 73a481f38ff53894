#include "envs/bullet/robot.h"

#include <algorithm>
#include <cmath>
#include <limits>

// Bullet's inline btBoxShape::getPlane leaves part of a vector unset, which GCC reports wherever the box's
// virtual functions are emitted, as they are here.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <btBulletDynamicsCommon.h>
#pragma GCC diagnostic pop

#include <BulletCollision/CollisionShapes/btMultiSphereShape.h>
#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointLimitConstraint.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointMotor.h>
#include <BulletDynamics/Featherstone/btMultiBodyLinkCollider.h>

#include "envs/bullet/world_sized_box.h"
#include "hlt/util/error.h"

static_assert(sizeof(btScalar) == sizeof(double),
              "hlt_envs must be built against Bullet's double-precision build");

namespace hlt::bullet {

namespace {

constexpr double kPi = 3.14159265358979323846;

btVector3 to_bt(const Eigen::Vector3d& v) {
  return {v.x(), v.y(), v.z()};
}
Eigen::Vector3d to_eigen(const btVector3& v) {
  return {v.x(), v.y(), v.z()};
}

Eigen::Isometry3d to_eigen(const btTransform& t) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  const btMatrix3x3& b = t.getBasis();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      out.linear()(r, c) = b[r][c];
  out.translation() = to_eigen(t.getOrigin());
  return out;
}

bool finite(const Eigen::Vector3d& v) {
  return v.allFinite();
}

// The orientation that turns a btCapsuleShapeZ's axis onto `dir`; shared by the collider and the inertia
// estimate so that both see the same box.
Eigen::Quaterniond capsule_rotation(const Eigen::Vector3d& dir) {
  return Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), dir.normalized());
}

bool is_single_sphere_at(const std::vector<Shape>& shapes, const Eigen::Vector3d& com) {
  return shapes.size() == 1 && shapes[0].is_sphere() && shapes[0].from == com;
}

bool is_single_box_at(const std::vector<Shape>& shapes, const Eigen::Vector3d& com) {
  return shapes.size() == 1 && shapes[0].is_box() && shapes[0].from == com;
}

void check_body(const BodySpec& b, const std::string& robot) {
  check(b.mass >= 0 && std::isfinite(b.mass), "robot '{}': body '{}' has mass {}", robot, b.name, b.mass);
  check(finite(b.inertia) && (b.inertia.array() >= 0).all(), "robot '{}': body '{}' has a negative inertia",
        robot, b.name);
  check(finite(b.com), "robot '{}': body '{}' has a non-finite COM", robot, b.name);
  for (const Shape& s : b.shapes) {
    const bool sized = s.is_box()
                           ? (s.half_extents.array() > 0).all() && finite(s.half_extents) && s.from == s.to
                           : s.radius > 0;
    check(sized && finite(s.from) && finite(s.to), "robot '{}': body '{}' has a degenerate shape", robot,
          b.name);
  }
  check(!b.world_sized_bounds || is_single_box_at(b.shapes, b.com),
        "robot '{}': body '{}' asks for world-sized bounds, which only a lone box at its COM can have", robot,
        b.name);
}

}  // namespace

double capsule_volume(double radius, double length) {
  return 4.0 / 3.0 * kPi * radius * radius * radius + kPi * radius * radius * length;
}

double capsule_mass(double radius, double length, double density) {
  return density * capsule_volume(radius, length);
}

Eigen::Vector3d capsule_inertia(double mass, double radius, double half_length, int axis) {
  check(axis >= 0 && axis < 3, "capsule axis must be 0, 1 or 2, got {}", axis);
  Eigen::Vector3d extent = Eigen::Vector3d::Constant(2 * radius);
  extent[axis] += 2 * half_length;
  const Eigen::Vector3d sq = extent.cwiseProduct(extent);
  return mass / 12.0 * Eigen::Vector3d(sq.y() + sq.z(), sq.x() + sq.z(), sq.x() + sq.y());
}

Eigen::Vector3d fromto_capsule_inertia(double mass, const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                       double radius) {
  const Eigen::Vector3d lo = from.cwiseMin(to).array() - radius - kCollisionMargin;
  const Eigen::Vector3d hi = from.cwiseMax(to).array() + radius + kCollisionMargin;
  const Eigen::Vector3d extent = hi - lo;
  const Eigen::Vector3d sq = extent.cwiseProduct(extent);
  return mass / 12.0 * Eigen::Vector3d(sq.y() + sq.z(), sq.x() + sq.z(), sq.x() + sq.y());
}

Eigen::Vector3d estimated_inertia(double mass, const std::vector<Shape>& shapes, const Eigen::Vector3d& com) {
  check(!shapes.empty(), "an inertia estimate needs at least one shape");
  if (is_single_sphere_at(shapes, com))
    return Eigen::Vector3d::Constant(0.4 * mass * shapes[0].radius * shapes[0].radius);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const Shape& s : shapes) {
    Eigen::Vector3d centre = 0.5 * (s.from + s.to) - com;
    Eigen::Vector3d half = Eigen::Vector3d::Constant(s.radius);
    if (s.is_box()) {
      half = s.half_extents;
    } else if (s.sphere_pair) {
      half = 0.5 * (s.to - s.from).cwiseAbs() + Eigen::Vector3d::Constant(s.radius + kCollisionMargin);
    } else if (!s.is_sphere()) {
      // Bullet bounds a capsule by its local box (r, r, r + half length) turned into the parent frame.
      const Eigen::Vector3d d = s.to - s.from;
      const Eigen::Matrix3d r = capsule_rotation(d).toRotationMatrix().cwiseAbs();
      half = r * Eigen::Vector3d(s.radius, s.radius, s.radius + 0.5 * d.norm());
    }
    lo = lo.cwiseMin(centre - half);
    hi = hi.cwiseMax(centre + half);
  }
  const Eigen::Vector3d sq = (hi - lo).cwiseAbs2();
  return mass / 12.0 * Eigen::Vector3d(sq.y() + sq.z(), sq.x() + sq.z(), sq.x() + sq.y());
}

int add_planar_root(RobotSpec& spec, LinkSpec torso) {
  check(spec.links.empty(), "robot '{}': the planar root must come first", spec.name);
  spec.fixed_base = true;
  spec.base.mass = 0.0;
  spec.base.inertia.setZero();
  spec.base.com.setZero();
  const char* names[2] = {"root_x", "root_z"};
  const Eigen::Vector3d axes[2] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ()};
  for (int k = 0; k < 2; ++k) {
    LinkSpec slider;
    slider.name = names[k];
    slider.parent = k - 1;
    slider.joint = JointType::kPrismatic;
    slider.axis = axes[k];
    // The massless sliders sit at the origin, so their coordinates are the torso's displacement.
    spec.links.push_back(slider);
  }
  torso.parent = 1;
  torso.joint = JointType::kRevolute;
  torso.axis = Eigen::Vector3d::UnitY();
  torso.limits.reset();
  spec.links.push_back(std::move(torso));
  return 2;
}

Robot::Robot(btMultiBodyDynamicsWorld& world, RobotSpec spec) : world_(world), spec_(std::move(spec)) {
  const std::string& rn = spec_.name;
  check_body(spec_.base, rn);
  check(spec_.fixed_base || spec_.base.mass > 0, "robot '{}': a floating base needs a mass", rn);
  const int n = num_links();
  for (int i = 0; i < n; ++i) {
    const LinkSpec& l = spec_.links[i];
    check_body(l, rn);
    check(l.parent >= -1 && l.parent < i,
          "robot '{}': link '{}' has parent {}; a parent must come before its child", rn, l.name, l.parent);
    check(finite(l.anchor) && finite(l.axis), "robot '{}': link '{}' has a non-finite joint", rn, l.name);
    if (l.joint != JointType::kFixed) {
      check(l.axis.norm() > 1e-9, "robot '{}': link '{}' has a zero joint axis", rn, l.name);
    }
    if (l.limits) {
      check(l.joint != JointType::kFixed, "robot '{}': fixed link '{}' cannot have limits", rn, l.name);
      check(l.limits->first <= l.limits->second, "robot '{}': link '{}' has limits [{}, {}]", rn, l.name,
            l.limits->first, l.limits->second);
    }
  }

  body_ = std::make_unique<btMultiBody>(n, spec_.base.mass, to_bt(spec_.base.inertia), spec_.fixed_base,
                                        /*canSleep=*/false);
  body_->setBaseWorldTransform(btTransform(btQuaternion::getIdentity(), to_bt(spec_.base.com)));
  const btQuaternion identity = btQuaternion::getIdentity();
  for (int i = 0; i < n; ++i) {
    const LinkSpec& l = spec_.links[i];
    const Eigen::Vector3d parent_com = l.parent < 0 ? spec_.base.com : spec_.links[l.parent].com;
    // Every body frame is world-aligned at the zero configuration, so world offsets are frame offsets.
    const btVector3 parent_to_pivot = to_bt(l.parent_com_to_pivot.value_or(l.anchor - parent_com));
    const btVector3 pivot_to_com = to_bt(l.pivot_to_com.value_or(l.com - l.anchor));
    // The axis goes in as given: PyBullet passes MJCF axes unnormalised too.
    switch (l.joint) {
      case JointType::kFixed:
        body_->setupFixed(i, l.mass, to_bt(l.inertia), l.parent, identity, parent_to_pivot, pivot_to_com);
        break;
      case JointType::kRevolute:
        body_->setupRevolute(i, l.mass, to_bt(l.inertia), l.parent, identity, to_bt(l.axis), parent_to_pivot,
                             pivot_to_com, /*disableParentCollision=*/true);
        break;
      case JointType::kPrismatic:
        body_->setupPrismatic(i, l.mass, to_bt(l.inertia), l.parent, identity, to_bt(l.axis), parent_to_pivot,
                              pivot_to_com, /*disableParentCollision=*/true);
        break;
    }
  }
  body_->finalizeMultiDof();
  body_->setHasSelfCollision(spec_.self_collision);
  world_.addMultiBody(body_.get());

  for (int i = 0; i < n; ++i) {
    const LinkSpec& l = spec_.links[i];
    if (!l.limits) continue;
    limits_.push_back(
        std::make_unique<btMultiBodyJointLimitConstraint>(body_.get(), i, l.limits->first, l.limits->second));
    world_.addMultiBodyConstraint(limits_.back().get());
  }
  for (int i = 0; spec_.disabled_motors && i < n; ++i) {
    if (spec_.links[i].joint == JointType::kFixed) continue;
    limits_.push_back(std::make_unique<btMultiBodyJointMotor>(body_.get(), i, 0, 0.0, 0.0));
    world_.addMultiBodyConstraint(limits_.back().get());
  }

  link_colliders_.assign(n + 1, nullptr);
  for (int i = -1; i < n; ++i) {
    const BodySpec& b = i < 0 ? static_cast<const BodySpec&>(spec_.base) : spec_.links[i];
    // A base without shapes needs no collider: a fixed base is static and joins no island, and a floating one
    // has no constraints of its own.
    if (i < 0 && b.shapes.empty()) continue;
    btCollisionShape* shape = nullptr;
    if (is_single_sphere_at(b.shapes, b.com)) {
      // PyBullet uses a lone shape sitting at the COM directly instead of wrapping it in a compound.
      shapes_.push_back(std::make_unique<btSphereShape>(b.shapes[0].radius));
      shape = shapes_.back().get();
    } else if (is_single_box_at(b.shapes, b.com)) {
      // Likewise a lone box at the COM, which keeps box-box pairs on Bullet's box-box detector.
      const btVector3 half = to_bt(b.shapes[0].half_extents);
      if (b.world_sized_bounds) {
        shapes_.push_back(std::make_unique<WorldSizedBox>(half));
      } else {
        shapes_.push_back(std::make_unique<btBoxShape>(half));
      }
      shape = shapes_.back().get();
    } else {
      auto compound = std::make_unique<btCompoundShape>();
      for (const Shape& s : b.shapes) {
        std::unique_ptr<btCollisionShape> child;
        btTransform local = btTransform::getIdentity();
        if (s.is_box()) {
          child = std::make_unique<btBoxShape>(to_bt(s.half_extents));
          local.setOrigin(to_bt(s.from - b.com));
        } else if (s.is_sphere()) {
          child = std::make_unique<btSphereShape>(s.radius);
          local.setOrigin(to_bt(s.from - b.com));
        } else if (s.sphere_pair) {
          const btVector3 centres[2] = {to_bt(s.from - b.com), to_bt(s.to - b.com)};
          const btScalar radii[2] = {s.radius, s.radius};
          child = std::make_unique<btMultiSphereShape>(centres, radii, 2);
        } else {
          const Eigen::Vector3d d = s.to - s.from;
          child = std::make_unique<btCapsuleShapeZ>(s.radius, d.norm());
          const Eigen::Quaterniond q = capsule_rotation(d);
          local.setOrigin(to_bt(0.5 * (s.from + s.to) - b.com));
          local.setRotation(btQuaternion(q.x(), q.y(), q.z(), q.w()));
        }
        compound->addChildShape(local, child.get());
        shapes_.push_back(std::move(child));
      }
      shape = compound.get();
      shapes_.push_back(std::move(compound));
    }
    auto collider = std::make_unique<btMultiBodyLinkCollider>(body_.get(), i);
    collider->setCollisionShape(shape);
    collider->setFriction(b.friction);
    collider->setRestitution(b.restitution);
    if (i < 0) {
      body_->setBaseCollider(collider.get());
    } else {
      body_->getLink(i).m_collider = collider.get();
    }
    const bool collides = b.collides && !b.shapes.empty();
    world_.addCollisionObject(collider.get(), collides ? b.collision_group : 0,
                              collides ? b.collision_mask : 0);
    link_colliders_[i + 1] = collider.get();
    colliders_.push_back(std::move(collider));
  }
  pending_forces_.assign(n, 0.0);
  refresh_kinematics();
}

Robot::~Robot() {
  for (auto& c : limits_)
    world_.removeMultiBodyConstraint(c.get());
  for (auto& c : colliders_)
    world_.removeCollisionObject(c.get());
  world_.removeMultiBody(body_.get());
}

int Robot::link_index(const std::string& name) const {
  std::vector<std::string> names;
  for (int i = 0; i < num_links(); ++i) {
    if (spec_.links[i].name == name) return i;
    names.push_back(spec_.links[i].name);
  }
  throw Error(
      fmt::format("robot '{}' has no link '{}'; its links: {}", spec_.name, name, fmt::join(names, ", ")));
}

int Robot::bullet_link(int link) const {
  check(link >= 0 && link < num_links(), "robot '{}': link {} out of range [0, {})", spec_.name, link,
        num_links());
  return link;
}

double Robot::joint_position(int link) const {
  const int i = bullet_link(link);
  check(body_->getLink(i).m_posVarCount == 1, "robot '{}': link '{}' has no 1-D joint", spec_.name,
        spec_.links[i].name);
  return body_->getJointPos(i);
}

double Robot::joint_velocity(int link) const {
  const int i = bullet_link(link);
  check(body_->getLink(i).m_dofCount == 1, "robot '{}': link '{}' has no 1-D joint", spec_.name,
        spec_.links[i].name);
  return body_->getJointVel(i);
}

void Robot::set_joint_state(int link, double position, double velocity) {
  const int i = bullet_link(link);
  check(body_->getLink(i).m_dofCount == 1, "robot '{}': link '{}' has no 1-D joint", spec_.name,
        spec_.links[i].name);
  check(std::isfinite(position) && std::isfinite(velocity), "robot '{}': joint state must be finite",
        spec_.name);
  body_->setJointPos(i, position);
  body_->setJointVel(i, velocity);
  refresh_kinematics();
}

Eigen::Vector3d Robot::base_position() const {
  return to_eigen(body_->getBasePos());
}

Eigen::Quaterniond Robot::base_orientation() const {
  const btQuaternion q = body_->getWorldToBaseRot().inverse();
  return {q.w(), q.x(), q.y(), q.z()};
}

Eigen::Vector3d Robot::base_linear_velocity() const {
  return to_eigen(body_->getBaseVel());
}
Eigen::Vector3d Robot::base_angular_velocity() const {
  return to_eigen(body_->getBaseOmega());
}

void Robot::set_base_state(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                           const Eigen::Vector3d& linear_velocity, const Eigen::Vector3d& angular_velocity) {
  check(finite(position) && orientation.coeffs().allFinite() && finite(linear_velocity) &&
            finite(angular_velocity),
        "robot '{}': base state must be finite", spec_.name);
  const Eigen::Quaterniond q = orientation.normalized();
  body_->setBasePos(to_bt(position));
  body_->setWorldToBaseRot(btQuaternion(q.x(), q.y(), q.z(), q.w()).inverse());
  body_->setBaseVel(to_bt(linear_velocity));
  body_->setBaseOmega(to_bt(angular_velocity));
  refresh_kinematics();
}

void Robot::set_joint_force(int link, double force) {
  const int i = bullet_link(link);
  check(body_->getLink(i).m_dofCount == 1, "robot '{}': link '{}' has no actuated joint", spec_.name,
        spec_.links[i].name);
  check(std::isfinite(force), "robot '{}': joint force must be finite", spec_.name);
  pending_forces_[i] = force;
  has_pending_forces_ = true;
}

void Robot::clear_joint_forces() {
  std::fill(pending_forces_.begin(), pending_forces_.end(), 0.0);
  has_pending_forces_ = false;
}

void Robot::apply_pending_forces() {
  if (!has_pending_forces_) return;
  for (int i = 0; i < num_links(); ++i) {
    if (pending_forces_[i] != 0.0) body_->addJointTorque(i, pending_forces_[i]);
  }
}

Eigen::Isometry3d Robot::body_pose(int link) const {
  if (link < 0) return to_eigen(body_->getBaseWorldTransform());
  const int i = bullet_link(link);
  btTransform t;
  t.setOrigin(body_->localPosToWorld(i, btVector3(0, 0, 0)));
  t.setBasis(body_->localFrameToWorld(i, btMatrix3x3::getIdentity()));
  return to_eigen(t);
}

Eigen::Vector3d Robot::com_position(int link) const {
  if (link < 0) return to_eigen(body_->getBasePos());
  return to_eigen(body_->getLink(bullet_link(link)).m_cachedWorldTransform.getOrigin());
}

Eigen::Quaterniond Robot::com_orientation(int link) const {
  if (link < 0) return base_orientation();
  const btQuaternion q = body_->getLink(bullet_link(link)).m_cachedWorldTransform.getRotation();
  return {q.w(), q.x(), q.y(), q.z()};
}

Eigen::Vector3d Robot::com_linear_velocity(int link) const {
  if (link < 0) return base_linear_velocity();
  const int i = bullet_link(link);
  btAlignedObjectArray<btVector3> omega, velocity;
  omega.resize(num_links() + 1);
  velocity.resize(num_links() + 1);
  body_->compTreeLinkVelocities(&omega[0], &velocity[0]);
  // Bullet gives each link's velocity in the link's frame; turned into the world with the cached pose.
  return to_eigen(body_->getLink(i).m_cachedWorldTransform.getBasis() * velocity[i + 1]);
}

const btMultiBodyLinkCollider* Robot::collider(int link) const {
  check(link >= -1 && link < num_links(), "robot '{}': link {} out of range", spec_.name, link);
  return link_colliders_[link + 1];
}

std::vector<Shape> Robot::world_shapes(int link) const {
  const BodySpec& b = link < 0 ? static_cast<const BodySpec&>(spec_.base) : spec_.links[bullet_link(link)];
  const Eigen::Isometry3d pose = body_pose(link);
  std::vector<Shape> out;
  for (const Shape& s : b.shapes)
    out.push_back({pose * (s.from - b.com), pose * (s.to - b.com), s.radius, s.sphere_pair, s.half_extents});
  return out;
}

size_t Robot::state_size() const {
  return 13 + static_cast<size_t>(body_->getNumPosVars()) + static_cast<size_t>(body_->getNumDofs());
}

std::vector<double> Robot::save_state() const {
  std::vector<double> s;
  s.reserve(state_size());
  const btVector3& p = body_->getBasePos();
  const btQuaternion& q = body_->getWorldToBaseRot();
  const btVector3 v = body_->getBaseVel();
  const btVector3 w = body_->getBaseOmega();
  s.insert(s.end(),
           {p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w(), v.x(), v.y(), v.z(), w.x(), w.y(), w.z()});
  for (int i = 0; i < num_links(); ++i) {
    const btMultibodyLink& l = body_->getLink(i);
    const btScalar* jp = body_->getJointPosMultiDof(i);
    const btScalar* jv = body_->getJointVelMultiDof(i);
    s.insert(s.end(), jp, jp + l.m_posVarCount);
    s.insert(s.end(), jv, jv + l.m_dofCount);
  }
  return s;
}

void Robot::restore_state(const double* data, size_t size) {
  check(size == state_size(), "robot '{}': state has {} values, expected {}", spec_.name, size, state_size());
  check(std::all_of(data, data + size, [](double x) { return std::isfinite(x); }),
        "robot '{}': state contains NaN or Inf", spec_.name);
  const double* d = data;
  body_->setBasePos(btVector3(d[0], d[1], d[2]));
  body_->setWorldToBaseRot(btQuaternion(d[3], d[4], d[5], d[6]));
  body_->setBaseVel(btVector3(d[7], d[8], d[9]));
  body_->setBaseOmega(btVector3(d[10], d[11], d[12]));
  d += 13;
  for (int i = 0; i < num_links(); ++i) {
    const btMultibodyLink& l = body_->getLink(i);
    body_->setJointPosMultiDof(i, d);
    d += l.m_posVarCount;
    body_->setJointVelMultiDof(i, d);
    d += l.m_dofCount;
  }
  clear_joint_forces();
  body_->clearForcesAndTorques();
  body_->clearConstraintForces();
  refresh_kinematics();
}

bool Robot::state_is_finite() const {
  const std::vector<double> s = save_state();
  return std::all_of(s.begin(), s.end(), [](double x) { return std::isfinite(x); });
}

bool Robot::can_collide() const {
  if (spec_.base.collides && !spec_.base.shapes.empty()) return true;
  return std::any_of(spec_.links.begin(), spec_.links.end(),
                     [](const LinkSpec& l) { return l.collides && !l.shapes.empty(); });
}

void Robot::refresh_kinematics() {
  btAlignedObjectArray<btQuaternion> world_to_local;
  btAlignedObjectArray<btVector3> local_origin;
  world_to_local.resize(num_links() + 1);
  local_origin.resize(num_links() + 1);
  body_->forwardKinematics(world_to_local, local_origin);
  body_->updateCollisionObjectWorldTransforms(world_to_local, local_origin);
  // Bullet takes a collider whose bounding box overflowed (a state gone non-finite) out of the simulation for
  // good; a state set from outside starts afresh, so bring such colliders back.
  for (auto& c : colliders_) {
    if (c->getActivationState() == DISABLE_SIMULATION) c->forceActivationState(ACTIVE_TAG);
  }
}

}  // namespace hlt::bullet
