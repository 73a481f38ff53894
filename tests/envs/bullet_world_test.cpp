// The shared Bullet machinery (envs/bullet): engine settings, robot building from data, pure joint forces
// over sub-steps, the planar root, colliders and ground, state snapshots.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include <btBulletDynamicsCommon.h>

#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>

#include "envs/bullet/robot.h"
#include "envs/bullet/world.h"
#include "hlt/util/error.h"

namespace hlt::bullet {
namespace {

// A rod hinged about y at the origin, COM 0.5 m up.
RobotSpec rod() {
  RobotSpec spec;
  spec.name = "rod";
  LinkSpec l;
  l.name = "rod";
  l.joint = JointType::kRevolute;
  l.axis = Eigen::Vector3d::UnitY();
  l.mass = 2.0;
  l.inertia = Eigen::Vector3d(0.2, 0.3, 0.01);
  l.com = Eigen::Vector3d(0, 0, 0.5);
  l.shapes = {Shape::capsule({0, 0, 0}, {0, 0, 1}, 0.05)};
  spec.links = {l};
  return spec;
}

// A floating sphere (radius 0.1, 1 kg) at height z.
RobotSpec ball(double z, bool collides) {
  RobotSpec spec;
  spec.name = "ball";
  spec.fixed_base = false;
  spec.base.name = "ball";
  spec.base.mass = 1.0;
  spec.base.inertia = Eigen::Vector3d::Constant(0.004);
  spec.base.com = Eigen::Vector3d(0, 0, z);
  spec.base.shapes = {Shape::sphere({0, 0, z}, 0.1)};
  spec.base.collides = collides;
  return spec;
}

TEST(BulletWorld, EngineSettings) {
  World world;
  const btMultiBodyDynamicsWorld& w = world.bullet();
  const btContactSolverInfo& info = const_cast<btMultiBodyDynamicsWorld&>(w).getSolverInfo();
  EXPECT_EQ(info.m_numIterations, 5);
  EXPECT_EQ(info.m_erp2, 0.9);
  EXPECT_EQ(info.m_frictionERP, 0.2);
  EXPECT_EQ(info.m_linearSlop, 1e-5);
  EXPECT_EQ(info.m_warmstartingFactor, 0.1);
  EXPECT_EQ(info.m_leastSquaresResidualThreshold, 1e-7);
  EXPECT_TRUE(const_cast<btMultiBodyDynamicsWorld&>(w).getDispatchInfo().m_deterministicOverlappingPairs);
  EXPECT_EQ(w.getGravity().z(), -9.8);
  EXPECT_EQ(w.getGravity().x(), 0.0);
}

TEST(BulletWorld, JointForceActsInEverySubstepThenClears) {
  WorldSettings no_gravity;
  no_gravity.gravity_z = 0.0;
  const double tau = 3.0, dt = 0.0165, pivot_inertia = 0.3 + 2.0 * 0.25;
  for (int substeps : {1, 4}) {
    World world(no_gravity);
    Robot& r = world.add_robot(rod());
    r.set_joint_force(0, tau);
    world.step(dt, substeps);
    // Only the built-in damping (0.04 per second at these speeds) opposes the torque; a torque acting in the
    // first sub-step only would give a quarter of this.
    EXPECT_NEAR(r.joint_velocity(0), tau * dt / pivot_inertia, 1e-3 * tau * dt / pivot_inertia) << substeps;
    const double w1 = r.joint_velocity(0);
    world.step(dt, substeps);  // no force set: only damping acts
    EXPECT_LT(r.joint_velocity(0), w1);
    EXPECT_GT(r.joint_velocity(0), 0.99 * w1);
  }
}

TEST(BulletWorld, PlanarRoot) {
  RobotSpec spec;
  spec.name = "planar";
  LinkSpec torso;
  torso.name = "torso";
  torso.mass = 3.0;
  torso.inertia = Eigen::Vector3d(0.1, 0.2, 0.05);
  torso.com = Eigen::Vector3d(0, 0, 1.25);
  torso.anchor = torso.com;
  torso.shapes = {Shape::capsule({0, 0, 1.05}, {0, 0, 1.45}, 0.05)};
  const int t = add_planar_root(spec, torso);
  ASSERT_EQ(t, 2);
  ASSERT_EQ(spec.links.size(), 3u);
  EXPECT_EQ(spec.links[0].joint, JointType::kPrismatic);
  EXPECT_EQ(spec.links[0].axis, Eigen::Vector3d::UnitX());
  EXPECT_EQ(spec.links[1].axis, Eigen::Vector3d::UnitZ());
  EXPECT_EQ(spec.links[0].mass, 0.0);
  EXPECT_EQ(spec.links[1].mass, 0.0);
  World world;
  Robot& r = world.add_robot(spec);
  EXPECT_EQ(r.link_index("torso"), 2);
  EXPECT_THROW(r.link_index("thigh"), Error);
  // Free fall: the first step from rest is exactly -g dt (no damping at rest); x and pitch stay put.
  const double dt = 0.0165, tau = 0.5;
  r.set_joint_force(2, tau);
  world.step(dt);
  EXPECT_NEAR(r.joint_velocity(1), -9.8 * dt, 1e-12);
  EXPECT_NEAR(r.joint_velocity(0), 0.0, 1e-12);
  // The hinge is at the COM, so the torque only spins the torso, about its own y moment.
  EXPECT_NEAR(r.joint_velocity(2), tau * dt / 0.2, 1e-12);
  for (int i = 0; i < 20; ++i)
    world.step(dt);
  EXPECT_NEAR(r.joint_position(0), 0.0, 1e-12);
  EXPECT_LT(r.joint_position(1), -0.2);
  // The torso's body frame follows the sliders.
  EXPECT_NEAR(r.body_pose(2).translation().z(), 1.25 + r.joint_position(1), 1e-12);
}

TEST(BulletWorld, BallRestsOnGroundOrFallsThrough) {
  World world;
  world.add_ground(0.8, 0.5);
  Robot& solid = world.add_robot(ball(0.5, true));
  Robot& ghost = world.add_robot(ball(0.5, false));
  EXPECT_TRUE(world.has_contacts());
  for (int i = 0; i < 240; ++i)
    world.step(0.0165, 4);
  EXPECT_NEAR(solid.base_position().z(), 0.1, 0.01);
  EXPECT_LT(ghost.base_position().z(), -5.0);
  World empty;
  empty.add_robot(rod());
  EXPECT_FALSE(empty.has_contacts());
}

TEST(BulletWorld, SnapshotsWithoutContactsAreExact) {
  World world;
  Robot& r = world.add_robot(rod());
  r.set_joint_state(0, 0.3, -1.0);
  for (int i = 0; i < 10; ++i)
    world.step(0.0165);
  const std::vector<double> snap = world.save_state();
  std::vector<double> first;
  for (int i = 0; i < 100; ++i) {
    r.set_joint_force(0, std::sin(0.1 * i));
    world.step(0.0165, 4);
    first.push_back(r.joint_position(0));
  }
  world.restore_state(snap);
  for (int i = 0; i < 100; ++i) {
    r.set_joint_force(0, std::sin(0.1 * i));
    world.step(0.0165, 4);
    ASSERT_EQ(r.joint_position(0), first[i]) << i;
  }
  std::vector<double> bad = snap;
  bad.pop_back();
  EXPECT_THROW(world.restore_state(bad), Error);
}

// A capsule (2 kg) thrown spinning onto the ground, so that contact points come and go.
RobotSpec stick() {
  RobotSpec spec;
  spec.name = "stick";
  spec.fixed_base = false;
  spec.base.mass = 2.0;
  spec.base.inertia = Eigen::Vector3d(0.1, 0.1, 0.01);
  spec.base.com = Eigen::Vector3d(0, 0, 0.6);
  spec.base.shapes = {Shape::capsule({-0.3, 0, 0.6}, {0.3, 0, 0.6}, 0.05)};
  spec.base.collides = true;
  return spec;
}

void throw_stick(Robot& b) {
  b.set_base_state({0, 0, 0.6},
                   Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 0).normalized())),
                   {1.0, 0.3, 0}, {2.0, -1.0, 3.0});
}

TEST(BulletWorld, SnapshotsWithContactsAreExact) {
  // Bullet keeps contact points between steps (persistent manifolds: they warm-start the solver and decide
  // which points survive); the snapshot carries them, so a restore reproduces the next steps bit for bit,
  // also in a second world built the same way.
  World world, other;
  world.add_ground(0.8, 0.5);
  other.add_ground(0.8, 0.5);
  Robot& b = world.add_robot(stick());
  Robot& c = other.add_robot(stick());
  throw_stick(b);
  for (int start : {20, 40, 60}) {
    for (int i = 0; i < start; ++i)
      world.step(0.0165, 4);
    const std::vector<double> snap = world.save_state();
    std::vector<Eigen::Vector3d> first;
    int touching = 0;
    for (int i = 0; i < 60; ++i) {
      world.step(0.0165, 4);
      first.push_back(b.base_position());
      touching += world.touches_ground(b, -1);
    }
    EXPECT_GT(touching, 0) << "the stick should be on the ground at some point";
    world.restore_state(snap);
    other.restore_state(snap);
    for (int i = 0; i < 60; ++i) {
      world.step(0.0165, 4);
      other.step(0.0165, 4);
      ASSERT_EQ(b.base_position(), first[i]) << "start " << start << " step " << i;
      ASSERT_EQ(c.base_position(), first[i]) << "start " << start << " step " << i;
    }
  }
  // A snapshot of a world with a different set of contact pairs is refused.
  World lone;
  lone.add_robot(stick());
  EXPECT_THROW(lone.restore_state(world.save_state()), Error);
}

TEST(BulletWorld, ContactCacheMattersAndCanBeCleared) {
  // The same poses and velocities with and without the remembered contact points lead to different motion
  // (that is why snapshots carry them); after clear_contacts() the past no longer matters.
  World world;
  world.add_ground(0.8, 0.5);
  Robot& b = world.add_robot(stick());
  throw_stick(b);
  // Once the stick lies on the ground with points at both ends: a fresh cache starts with one of them.
  int steps = 0;
  while (world.ground_contact_points(b, -1) < 2 && steps < 200) {
    world.step(0.0165, 4);
    ++steps;
  }
  ASSERT_EQ(world.ground_contact_points(b, -1), 2) << steps;
  std::vector<double> bodies = b.save_state();
  const auto run = [&](World& w, Robot& r) {
    for (int i = 0; i < 30; ++i)
      w.step(0.0165, 4);
    return r.base_position();
  };
  World fresh;
  fresh.add_ground(0.8, 0.5);
  Robot& f = fresh.add_robot(stick());
  f.restore_state(bodies.data(), bodies.size());
  const Eigen::Vector3d without_cache = run(fresh, f);
  b.restore_state(bodies.data(), bodies.size());
  const Eigen::Vector3d with_cache = run(world, b);
  EXPECT_NE(with_cache, without_cache);
  b.restore_state(bodies.data(), bodies.size());
  world.clear_contacts();
  EXPECT_FALSE(world.touches_ground(b, -1));
  EXPECT_EQ(run(world, b), without_cache);
}

TEST(BulletWorld, RecoversFromANonFiniteState) {
  // Bullet removes a collider whose bounding box overflows from the simulation; restoring a good state must
  // bring it back, or the ball would fall through the ground afterwards.
  World world;
  world.add_ground(0.8, 0.5);
  Robot& b = world.add_robot(ball(0.5, true));
  const std::vector<double> good = world.save_state();
  b.set_base_state({0, 0, 0.5}, Eigen::Quaterniond::Identity(), {1e300, 0, 0}, {0, 0, 0});
  world.step(0.0165);
  world.step(0.0165);
  EXPECT_FALSE(world.state_is_finite());
  world.restore_state(good);
  for (int i = 0; i < 200; ++i)
    world.step(0.0165, 4);
  EXPECT_NEAR(b.base_position().z(), 0.1, 0.01);
}

TEST(BulletWorld, RejectsBadSpecs) {
  World world;
  RobotSpec s = rod();
  s.links[0].parent = 0;  // its own parent
  EXPECT_THROW(world.add_robot(s), Error);
  s = rod();
  s.links[0].limits = std::make_pair(1.0, -1.0);
  EXPECT_THROW(world.add_robot(s), Error);
  s = rod();
  s.links[0].axis.setZero();
  EXPECT_THROW(world.add_robot(s), Error);
  s = ball(1.0, true);
  s.base.mass = 0.0;
  EXPECT_THROW(world.add_robot(s), Error);
  s = rod();
  s.links[0].mass = std::nan("");
  EXPECT_THROW(world.add_robot(s), Error);
  EXPECT_THROW(world.step(0.0, 1), Error);
  EXPECT_THROW(world.step(0.01, 0), Error);
}

}  // namespace
}  // namespace hlt::bullet
