#include "envs/bullet/world.h"

#include <algorithm>
#include <cmath>

#include <btBulletDynamicsCommon.h>

#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyConstraintSolver.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>

#include "hlt/util/error.h"

namespace hlt::bullet {

World::World(const WorldSettings& s) {
  check(s.solver_iterations >= 1, "Bullet world: solver iterations must be >= 1, got {}",
        s.solver_iterations);
  // PyBullet's server zeroes the broadphase's AABB growth margin; it is a process-wide Bullet global.
  gDbvtMargin = 0;
  collision_config_ = std::make_unique<btDefaultCollisionConfiguration>();
  dispatcher_ = std::make_unique<btCollisionDispatcher>(collision_config_.get());
  broadphase_ = std::make_unique<btDbvtBroadphase>();
  solver_ = std::make_unique<btMultiBodyConstraintSolver>();
  world_ = std::make_unique<btMultiBodyDynamicsWorld>(dispatcher_.get(), broadphase_.get(), solver_.get(),
                                                      collision_config_.get());
  world_->setGravity(btVector3(0, 0, s.gravity_z));
  world_->setForceUpdateAllAabbs(false);
  btContactSolverInfo& info = world_->getSolverInfo();
  info.m_numIterations = s.solver_iterations;
  info.m_erp2 = s.contact_erp;
  info.m_frictionERP = s.friction_erp;
  info.m_linearSlop = s.linear_slop;
  info.m_warmstartingFactor = s.warmstarting_factor;
  info.m_leastSquaresResidualThreshold = s.residual_threshold;
  // PyBullet's server default: every island is solved on its own, never batched with others.
  info.m_minimumSolverBatchSize = 0;
  world_->getDispatchInfo().m_deterministicOverlappingPairs = s.deterministic_overlapping_pairs;
}

World::~World() {
  robots_.clear();
  for (auto& o : static_objects_)
    world_->removeCollisionObject(o.get());
  static_objects_.clear();
  static_shapes_.clear();
}

Robot& World::add_robot(RobotSpec spec) {
  robots_.push_back(std::unique_ptr<Robot>(new Robot(*world_, std::move(spec))));
  return *robots_.back();
}

void World::add_ground(double friction, double restitution) {
  auto shape = std::make_unique<btStaticPlaneShape>(btVector3(0, 0, 1), 0);
  auto ground = std::make_unique<btCollisionObject>();
  ground->setCollisionShape(shape.get());
  ground->setFriction(friction);
  ground->setRestitution(restitution);
  world_->addCollisionObject(ground.get(), btBroadphaseProxy::StaticFilter,
                             btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::StaticFilter);
  static_shapes_.push_back(std::move(shape));
  static_objects_.push_back(std::move(ground));
}

void World::step(double dt, int substeps) {
  check(dt > 0 && substeps >= 1, "Bullet world: bad step dt={} substeps={}", dt, substeps);
  const double h = dt / substeps;
  for (int k = 0; k < substeps; ++k) {
    for (auto& r : robots_)
      r->apply_pending_forces();
    // One fixed-size step per call: no time accumulator carries over, so the world's state is exactly what
    // save_state() records.
    world_->stepSimulation(h, 0, h);
  }
  for (auto& r : robots_)
    r->clear_joint_forces();
}

std::vector<double> World::save_state() const {
  std::vector<double> out;
  for (const auto& r : robots_) {
    const std::vector<double> s = r->save_state();
    out.insert(out.end(), s.begin(), s.end());
  }
  return out;
}

void World::restore_state(const std::vector<double>& state) {
  size_t expected = 0;
  for (const auto& r : robots_)
    expected += r->state_size();
  check(state.size() == expected, "Bullet world: state has {} values, expected {}", state.size(), expected);
  // Checked up front so that a bad snapshot leaves the world untouched.
  check(std::all_of(state.begin(), state.end(), [](double x) { return std::isfinite(x); }),
        "Bullet world: state contains NaN or Inf");
  size_t offset = 0;
  for (auto& r : robots_) {
    r->restore_state(state.data() + offset, r->state_size());
    offset += r->state_size();
  }
}

bool World::state_is_finite() const {
  for (const auto& r : robots_) {
    if (!r->state_is_finite()) return false;
  }
  return true;
}

bool World::has_contacts() const {
  if (!static_objects_.empty()) return true;
  return std::any_of(robots_.begin(), robots_.end(), [](const auto& r) { return r->can_collide(); });
}

}  // namespace hlt::bullet
