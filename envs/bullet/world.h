// World: a double-precision Bullet btMultiBodyDynamicsWorld set up with the engine settings PyBullet's gym
// environments run with (docs/ENVIRONMENTS.md), owning the robots and ground built in it.
#pragma once

#include <memory>
#include <vector>

#include "envs/bullet/robot.h"

class btBroadphaseInterface;
class btCollisionConfiguration;
class btCollisionDispatcher;
class btCollisionObject;
class btCollisionShape;
class btMultiBodyConstraintSolver;

namespace hlt::bullet {

struct WorldSettings {
  double gravity_z = -9.8;
  int solver_iterations = 5;
  double contact_erp = 0.9;
  double friction_erp = 0.2;
  double linear_slop = 1e-5;
  double warmstarting_factor = 0.1;
  double residual_threshold = 1e-7;
  bool deterministic_overlapping_pairs = true;
};

class World {
 public:
  explicit World(const WorldSettings& settings = {});
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  // Builds `spec` in this world; the reference stays valid for the world's lifetime.
  Robot& add_robot(RobotSpec spec);
  // A static plane z = 0.
  void add_ground(double friction, double restitution);
  // A static box (a table), edges along the world axes. Its bounding box is world-sized, so every pair it is
  // in keeps its manifold for the world's lifetime, as a ground plane's do.
  void add_static_box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half_extents, double friction,
                      double restitution);
  // All of the above end by setting up the contact cache for the new set of objects (see save_state).

  // Advances `dt` seconds in `substeps` equal sub-steps. Each robot's pending joint forces act during every
  // sub-step (as a torque set before PyBullet's stepSimulation does) and are cleared afterwards.
  void step(double dt, int substeps = 1);

  // All robots' states, then the contact points Bullet keeps between steps (its persistent manifolds, which
  // warm-start the solver and decide which points survive). Restoring reproduces the next steps bit for bit,
  // with or without contacts. The set of manifolds is fixed when the world is built: every pair that can
  // touch gets its manifold then (pairs with a ground plane never separate in Bullet's broadphase), so a
  // snapshot fits any world built the same way.
  std::vector<double> save_state() const;
  // Throws hlt::Error (leaving the world untouched) for a snapshot of the wrong size or with NaN/Inf values.
  void restore_state(const std::vector<double>& state);
  bool state_is_finite() const;
  // Forgets all contact points (as after building), so that what follows does not depend on past contacts.
  void clear_contacts();
  // Whether anything in this world can collide.
  bool has_contacts() const;
  // The contact points `link` of `robot` (-1: the base) has with static objects (the ground) after the last
  // sub-step's collision detection. Bullet keeps up to 4 per pair, including points up to its
  // contact-breaking threshold apart.
  int ground_contact_points(const Robot& robot, int link) const;
  bool touches_ground(const Robot& robot, int link) const { return ground_contact_points(robot, link) > 0; }

  btMultiBodyDynamicsWorld& bullet() { return *world_; }
  const btMultiBodyDynamicsWorld& bullet() const { return *world_; }
  const std::vector<std::unique_ptr<Robot>>& robots() const { return robots_; }

 private:
  std::unique_ptr<btCollisionConfiguration> collision_config_;
  std::unique_ptr<btCollisionDispatcher> dispatcher_;
  std::unique_ptr<btBroadphaseInterface> broadphase_;
  std::unique_ptr<btMultiBodyConstraintSolver> solver_;
  std::unique_ptr<btMultiBodyDynamicsWorld> world_;
  std::vector<std::unique_ptr<Robot>> robots_;
  std::vector<std::unique_ptr<btCollisionShape>> static_shapes_;
  std::vector<std::unique_ptr<btCollisionObject>> static_objects_;

  void setup_contact_cache();
  size_t robots_state_size() const;
};

}  // namespace hlt::bullet
