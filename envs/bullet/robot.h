// Robot descriptions as data, and the btMultiBody built from one.
//
// A RobotSpec lists a base and a tree of links the way the project's specs tabulate them: every position,
// axis and shape is given in world coordinates with all joints at zero, and every body frame is aligned
// with the world there (as PyBullet builds MJCF bodies). The builder turns that into a double-precision
// btMultiBody driven by pure joint forces (no motors), with joint-limit constraints and optional colliders.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

class btMultiBody;
class btMultiBodyDynamicsWorld;
class btMultiBodyConstraint;
class btMultiBodyLinkCollider;
class btCollisionShape;

namespace hlt::bullet {

// A collision/drawing primitive in world coordinates at the zero configuration. A sphere has from == to; a
// box (half_extents set) is centred on `from` with its edges along the body's axes (the world's at the zero
// configuration).
struct Shape {
  Eigen::Vector3d from = Eigen::Vector3d::Zero();
  Eigen::Vector3d to = Eigen::Vector3d::Zero();
  double radius = 0.0;
  // A capsule built as two spheres and their hull (btMultiSphereShape), as PyBullet builds an MJCF "fromto"
  // capsule, instead of a btCapsuleShapeZ. The surface is the same, but Bullet's collision margin, bounding
  // box and hence contact-breaking threshold and inertia estimate differ.
  bool sphere_pair = false;
  Eigen::Vector3d half_extents = Eigen::Vector3d::Zero();

  static Shape capsule(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double radius) {
    return {from, to, radius, false, Eigen::Vector3d::Zero()};
  }
  static Shape sphere_pair_capsule(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double radius) {
    return {from, to, radius, true, Eigen::Vector3d::Zero()};
  }
  static Shape sphere(const Eigen::Vector3d& centre, double radius) {
    return {centre, centre, radius, false, Eigen::Vector3d::Zero()};
  }
  static Shape box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half_extents) {
    return {centre, centre, 0.0, false, half_extents};
  }
  bool is_box() const { return (half_extents.array() > 0).any(); }
  bool is_sphere() const { return from == to && !is_box(); }
};

// What the base and every link share: inertial data and shapes.
struct BodySpec {
  std::string name;
  double mass = 0.0;
  Eigen::Vector3d inertia = Eigen::Vector3d::Zero();  // principal moments about the COM, world-aligned axes
  Eigen::Vector3d com = Eigen::Vector3d::Zero();      // world position at the zero configuration
  std::vector<Shape> shapes;
  // Every link gets a collider, an empty one when it has no shapes (Bullet places a link's joint-limit
  // constraint in a simulation island by the link's own collider, as PyBullet's import does too); one that
  // does not collide is filtered out of every pair.
  bool collides = false;
  double friction = 0.8;
  double restitution = 0.0;
  int collision_group = 1;
  int collision_mask = -1;
  // Give a lone box a bounding box the size of the world, so that every broadphase pair it is in lasts as
  // long as the world (and with it the pair's contact manifold, which snapshots rely on: see World).
  bool world_sized_bounds = false;
};

enum class JointType { kFixed, kRevolute, kPrismatic };

struct LinkSpec : BodySpec {
  int parent = -1;  // index of the parent link; -1 is the base
  JointType joint = JointType::kRevolute;
  Eigen::Vector3d anchor = Eigen::Vector3d::Zero();  // joint position, world, zero configuration
  Eigen::Vector3d axis = Eigen::Vector3d::UnitY();   // joint axis, world, zero configuration
  std::optional<std::pair<double, double>> limits;   // [lower, upper], enforced by a limit constraint
  // The same placement as offsets between frames (parent COM to pivot, pivot to this COM), for a description
  // that has them in local form: derived from world positions they can differ in the last bits, which long
  // chaotic runs amplify. When set, they are used as given.
  std::optional<Eigen::Vector3d> parent_com_to_pivot;
  std::optional<Eigen::Vector3d> pivot_to_com;
};

struct RobotSpec {
  std::string name;
  BodySpec base;  // a massless base (mass 0) must be fixed
  bool fixed_base = true;
  std::vector<LinkSpec> links;  // a link's parent comes before it
  bool self_collision = false;
  // Give every revolute and prismatic joint a switched-off motor (maximum impulse 0), added after all limit
  // constraints, as PyBullet does for every body it loads. The motors produce no solver rows, but they take
  // places in Bullet's constraint list, whose (unstable) sort by island decides the order in which joint
  // limits that are active together get solved, and so the result to the last bits and beyond.
  bool disabled_motors = false;
};

// The planar root PyBullet gives a body whose MJCF root has slide-x, slide-z and hinge-y joints: a massless
// fixed base, a massless link sliding along x, a massless link sliding along z, then `torso` hinged about y
// at `torso.anchor`. Returns the index of the torso link in `spec.links`.
int add_planar_root(RobotSpec& spec, LinkSpec torso);

// PyBullet's default density for MJCF shapes without an explicit mass (kg/m^3).
constexpr double kDefaultDensity = 1000.0;
// Bullet's default collision margin, which its bounding-box inertia estimates include.
constexpr double kCollisionMargin = 0.04;

double capsule_volume(double radius, double length);
// density * volume, for a capsule whose cylinder part is `length` long.
double capsule_mass(double radius, double length, double density = kDefaultDensity);
// The moments PyBullet's MJCF import gives a capsule without an explicit inertia: Bullet's estimate for the
// link's compound shape, i.e. those of the shape's bounding box. `axis` is 0, 1 or 2 for a capsule along x, y
// or z.
Eigen::Vector3d capsule_inertia(double mass, double radius, double half_length, int axis);
// The same for an MJCF "fromto" capsule, which PyBullet builds as a two-sphere btMultiSphereShape: its
// bounding box includes the collision margin on every side.
Eigen::Vector3d fromto_capsule_inertia(double mass, const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                       double radius);
// The moments Bullet estimates for a body's collision shape, as PyBullet's MJCF import uses them: a single
// sphere centred on the COM is a solid sphere (0.4 m r^2); anything else is a compound, whose estimate is the
// box of its bounding box about `com` (sphere pairs include Bullet's 0.04 m margin, capsules do not).
Eigen::Vector3d estimated_inertia(double mass, const std::vector<Shape>& shapes, const Eigen::Vector3d& com);

class World;

// A btMultiBody built from a RobotSpec, living in a World. Joint forces set here are pending: they act during
// every sub-step of the next World::step and are then cleared.
class Robot {
 public:
  ~Robot();
  Robot(const Robot&) = delete;
  Robot& operator=(const Robot&) = delete;

  const RobotSpec& spec() const { return spec_; }
  int num_links() const { return static_cast<int>(spec_.links.size()); }
  int link_index(const std::string& name) const;  // throws naming the known links

  // Joint coordinate of a revolute/prismatic link (rad or m) and its rate.
  double joint_position(int link) const;
  double joint_velocity(int link) const;
  void set_joint_state(int link, double position, double velocity);
  // Base pose and velocity (world). Meaningful for a floating base.
  Eigen::Vector3d base_position() const;
  Eigen::Quaterniond base_orientation() const;
  Eigen::Vector3d base_linear_velocity() const;
  Eigen::Vector3d base_angular_velocity() const;
  void set_base_state(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                      const Eigen::Vector3d& linear_velocity, const Eigen::Vector3d& angular_velocity);

  // A pure generalised force on a revolute (N m) or prismatic (N) joint for the next step.
  void set_joint_force(int link, double force);
  void clear_joint_forces();

  // The pose of a body frame (its COM; world-aligned at the zero configuration). link -1 is the base.
  Eigen::Isometry3d body_pose(int link) const;
  // The COM pose and velocity as PyBullet's getLinkState / getBasePositionAndOrientation report them. A
  // link's pose is Bullet's cached one, which World::step leaves as it was at the start of the last sub-step
  // (Bullet refreshes it before each sub-step's solve); the base pose and all velocities are current. link -1
  // is the base.
  Eigen::Vector3d com_position(int link) const;
  Eigen::Quaterniond com_orientation(int link) const;
  Eigen::Vector3d com_linear_velocity(int link) const;
  // A body's shapes in world coordinates at the current configuration (a box's edges run along the body's
  // current axes, body_pose(link).linear()).
  std::vector<Shape> world_shapes(int link) const;

  // Everything that determines the next step: base pose and velocity, joint positions and velocities.
  std::vector<double> save_state() const;
  // Restores save_state(); throws hlt::Error on a wrong size or non-finite values.
  void restore_state(const double* data, size_t size);
  size_t state_size() const;
  bool state_is_finite() const;
  // Whether any of its bodies can touch something.
  bool can_collide() const;

  btMultiBody& multibody() { return *body_; }
  const btMultiBody& multibody() const { return *body_; }
  // The link's collider (link -1: the base's; null when the base has none).
  const btMultiBodyLinkCollider* collider(int link) const;

 private:
  friend class World;
  Robot(btMultiBodyDynamicsWorld& world, RobotSpec spec);
  void apply_pending_forces();
  // Brings cached link transforms and collider poses up to date after the state was set from outside.
  void refresh_kinematics();
  int bullet_link(int link) const;

  btMultiBodyDynamicsWorld& world_;
  RobotSpec spec_;
  std::unique_ptr<btMultiBody> body_;
  std::vector<std::unique_ptr<btMultiBodyConstraint>> limits_;
  std::vector<std::unique_ptr<btMultiBodyLinkCollider>> colliders_;
  std::vector<const btMultiBodyLinkCollider*> link_colliders_;  // by link index + 1 (base first)
  std::vector<std::unique_ptr<btCollisionShape>> shapes_;
  std::vector<double> pending_forces_;
  bool has_pending_forces_ = false;
};

}  // namespace hlt::bullet
