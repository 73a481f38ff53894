#include "envs/bullet/world.h"

#include <algorithm>
#include <cmath>

// Bullet's inline btBoxShape::getPlane, emitted here, trips GCC 12's -Wmaybe-uninitialized inside Bullet's
// own header (a false positive after inlining btVector3's constructor); the pragma covers Bullet's code only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <btBulletDynamicsCommon.h>

#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/NarrowPhaseCollision/btPersistentManifold.h>
#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyConstraintSolver.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyLinkCollider.h>
#pragma GCC diagnostic pop

#include "envs/bullet/world_sized_box.h"
#include "hlt/util/error.h"

namespace hlt::bullet {

namespace {

// Every field of a contact point that a later step reads (the user pointer is never set here).
constexpr size_t kPointValues = 41;

void put(std::vector<double>& out, const btVector3& v) {
  out.insert(out.end(), {v.x(), v.y(), v.z()});
}

void save_point(const btManifoldPoint& p, std::vector<double>& out) {
  put(out, p.m_localPointA);
  put(out, p.m_localPointB);
  put(out, p.m_positionWorldOnB);
  put(out, p.m_positionWorldOnA);
  put(out, p.m_normalWorldOnB);
  out.insert(out.end(), {p.m_distance1,
                         p.m_combinedFriction,
                         p.m_combinedRollingFriction,
                         p.m_combinedSpinningFriction,
                         p.m_combinedRestitution,
                         double(p.m_partId0),
                         double(p.m_partId1),
                         double(p.m_index0),
                         double(p.m_index1),
                         double(p.m_contactPointFlags),
                         p.m_appliedImpulse,
                         p.m_prevRHS,
                         p.m_appliedImpulseLateral1,
                         p.m_appliedImpulseLateral2,
                         p.m_contactMotion1,
                         p.m_contactMotion2,
                         p.m_contactCFM,
                         p.m_contactERP,
                         p.m_frictionCFM,
                         double(p.m_lifeTime)});
  put(out, p.m_lateralFrictionDir1);
  put(out, p.m_lateralFrictionDir2);
}

class Reader {
 public:
  explicit Reader(const double* d) : d_(d) {}
  double scalar() { return *d_++; }
  int integer() { return static_cast<int>(*d_++); }
  btVector3 vector() {
    const btVector3 v(d_[0], d_[1], d_[2]);
    d_ += 3;
    return v;
  }

 private:
  const double* d_;
};

btManifoldPoint load_point(const double* data) {
  Reader r(data);
  btManifoldPoint p;
  p.m_localPointA = r.vector();
  p.m_localPointB = r.vector();
  p.m_positionWorldOnB = r.vector();
  p.m_positionWorldOnA = r.vector();
  p.m_normalWorldOnB = r.vector();
  p.m_distance1 = r.scalar();
  p.m_combinedFriction = r.scalar();
  p.m_combinedRollingFriction = r.scalar();
  p.m_combinedSpinningFriction = r.scalar();
  p.m_combinedRestitution = r.scalar();
  p.m_partId0 = r.integer();
  p.m_partId1 = r.integer();
  p.m_index0 = r.integer();
  p.m_index1 = r.integer();
  p.m_contactPointFlags = r.integer();
  p.m_appliedImpulse = r.scalar();
  p.m_prevRHS = r.scalar();
  p.m_appliedImpulseLateral1 = r.scalar();
  p.m_appliedImpulseLateral2 = r.scalar();
  p.m_contactMotion1 = r.scalar();
  p.m_contactMotion2 = r.scalar();
  p.m_contactCFM = r.scalar();
  p.m_contactERP = r.scalar();
  p.m_frictionCFM = r.scalar();
  p.m_lifeTime = r.integer();
  p.m_lateralFrictionDir1 = r.vector();
  p.m_lateralFrictionDir2 = r.vector();
  return p;
}

}  // namespace

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
  setup_contact_cache();
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
  setup_contact_cache();
}

void World::add_static_box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half_extents,
                           double friction, double restitution) {
  check(centre.allFinite() && half_extents.allFinite() && (half_extents.array() > 0).all(),
        "Bullet world: a static box needs a finite centre and positive half extents");
  auto shape =
      std::make_unique<WorldSizedBox>(btVector3(half_extents.x(), half_extents.y(), half_extents.z()));
  auto box = std::make_unique<btCollisionObject>();
  box->setCollisionShape(shape.get());
  box->setWorldTransform(
      btTransform(btQuaternion::getIdentity(), btVector3(centre.x(), centre.y(), centre.z())));
  box->setFriction(friction);
  box->setRestitution(restitution);
  world_->addCollisionObject(box.get(), btBroadphaseProxy::StaticFilter,
                             btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::StaticFilter);
  static_shapes_.push_back(std::move(shape));
  static_objects_.push_back(std::move(box));
  setup_contact_cache();
}

void World::setup_contact_cache() {
  // One collision pass creates the collision algorithm, and with it the manifold, of every pair that can
  // touch; their order in the dispatcher stays fixed from here on, which snapshots rely on.
  world_->performDiscreteCollisionDetection();
  clear_contacts();
}

void World::clear_contacts() {
  btCollisionDispatcher& d = *dispatcher_;
  for (int i = 0; i < d.getNumManifolds(); ++i)
    d.getManifoldByIndexInternal(i)->clearManifold();
}

int World::ground_contact_points(const Robot& robot, int link) const {
  const btCollisionObject* c = robot.collider(link);
  if (c == nullptr) return 0;
  int n = 0;
  const btCollisionDispatcher& d = *dispatcher_;
  for (int i = 0; i < d.getNumManifolds(); ++i) {
    const btPersistentManifold* m = d.getManifoldByIndexInternal(i);
    if (m->getNumContacts() == 0) continue;
    const btCollisionObject* other = m->getBody0() == c   ? m->getBody1()
                                     : m->getBody1() == c ? m->getBody0()
                                                          : nullptr;
    if (other != nullptr && other->isStaticObject()) n += m->getNumContacts();
  }
  return n;
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

size_t World::robots_state_size() const {
  size_t n = 0;
  for (const auto& r : robots_)
    n += r->state_size();
  return n;
}

std::vector<double> World::save_state() const {
  std::vector<double> out;
  out.reserve(robots_state_size() + 1);
  for (const auto& r : robots_) {
    const std::vector<double> s = r->save_state();
    out.insert(out.end(), s.begin(), s.end());
  }
  const btCollisionDispatcher& d = *dispatcher_;
  out.push_back(d.getNumManifolds());
  for (int i = 0; i < d.getNumManifolds(); ++i) {
    const btPersistentManifold* m = d.getManifoldByIndexInternal(i);
    out.push_back(m->getNumContacts());
    for (int k = 0; k < m->getNumContacts(); ++k)
      save_point(m->getContactPoint(k), out);
  }
  return out;
}

void World::restore_state(const std::vector<double>& state) {
  // Checked up front so that a bad snapshot leaves the world untouched.
  check(std::all_of(state.begin(), state.end(), [](double x) { return std::isfinite(x); }),
        "Bullet world: state contains NaN or Inf");
  const size_t bodies = robots_state_size();
  btCollisionDispatcher& d = *dispatcher_;
  const auto bad = [&](const std::string& what) {
    return Error(fmt::format("Bullet world: state does not fit this world ({})", what));
  };
  if (state.size() < bodies + 1)
    throw bad(fmt::format("{} values, expected at least {}", state.size(), bodies + 1));
  if (state[bodies] != d.getNumManifolds())
    throw bad(fmt::format("{} contact manifolds, this world has {}", state[bodies], d.getNumManifolds()));
  std::vector<int> counts;
  size_t pos = bodies + 1;
  for (int i = 0; i < d.getNumManifolds(); ++i) {
    if (pos >= state.size()) throw bad("it ends early");
    const double n = state[pos++];
    if (!(n >= 0 && n <= MANIFOLD_CACHE_SIZE && n == std::floor(n))) throw bad("a bad contact count");
    counts.push_back(static_cast<int>(n));
    pos += counts.back() * kPointValues;
  }
  if (pos != state.size()) throw bad(fmt::format("{} values, expected {}", state.size(), pos));

  size_t offset = 0;
  for (auto& r : robots_) {
    r->restore_state(state.data() + offset, r->state_size());
    offset += r->state_size();
  }
  pos = bodies + 1;
  for (int i = 0; i < d.getNumManifolds(); ++i) {
    btPersistentManifold* m = d.getManifoldByIndexInternal(i);
    m->clearManifold();
    ++pos;
    m->setNumContacts(counts[i]);
    for (int k = 0; k < counts[i]; ++k, pos += kPointValues)
      m->getContactPoint(k) = load_point(state.data() + pos);
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
