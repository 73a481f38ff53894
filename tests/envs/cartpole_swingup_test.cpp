#include "envs/cartpole_swingup.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <functional>
#include <iostream>
#include <random>

#include <btBulletDynamicsCommon.h>

#include <BulletCollision/CollisionShapes/btMultiSphereShape.h>

#include <BulletDynamics/Featherstone/btMultiBody.h>

#include "envs/bullet/world.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kG = 9.8;
// btMultiBody's default damping (linear and angular, both coefficients), which the spec keeps. Bullet
// initialises it from a float literal.
constexpr double kDamping = static_cast<double>(0.04f);

// The pole's COM in its own frame, and the inertial data of the spec's table.
const Eigen::Vector3d kPoleCom(0.0005, 0, 0.3);

struct Params {
  double M, m, Iyy, cx, cz;
};

Params params(const CartPoleSwingup& env) {
  const auto& s = env.robot().spec();
  return {s.links[0].mass, s.links[1].mass, s.links[1].inertia.y(), s.links[1].com.x(), s.links[1].com.z()};
}

// Lagrangian of the cart-pole in (x, theta): pole COM at (x + cx cos t + cz sin t, -cx sin t + cz cos t).
double energy(const Params& p, double xd, double th, double thd) {
  const double a = -p.cx * std::sin(th) + p.cz * std::cos(th);  // d(com_x)/dtheta and COM height
  const double kinetic = 0.5 * (p.M + p.m) * xd * xd + p.m * xd * thd * a +
                         0.5 * (p.Iyy + p.m * (p.cx * p.cx + p.cz * p.cz)) * thd * thd;
  return kinetic + p.m * kG * a;
}

// Power drained by btMultiBody's built-in damping: each link feels -(k1 + k2 |v|) m v and
// -(k1 + k2 |w|) I w at its COM.
double damping_power(const Params& p, double xd, double th, double thd) {
  const double vx = xd + thd * (-p.cx * std::sin(th) + p.cz * std::cos(th));
  const double vz = thd * (-p.cx * std::cos(th) - p.cz * std::sin(th));
  const double v = std::hypot(vx, vz), w = std::abs(thd), c = std::abs(xd);
  return p.M * c * c * (kDamping + kDamping * c) + p.m * v * v * (kDamping + kDamping * v) +
         p.Iyy * w * w * (kDamping + kDamping * w);
}

TEST(CartPoleSwingup, BulletIsDoublePrecision) {
#ifndef BT_USE_DOUBLE_PRECISION
  FAIL() << "BT_USE_DOUBLE_PRECISION is not defined";
#endif
  EXPECT_EQ(sizeof(btScalar), 8u);
}

TEST(CartPoleSwingup, MassesAndInertiasAsBuilt) {
  CartPoleSwingup env;
  const btMultiBody& mb = env.robot().multibody();
  ASSERT_EQ(mb.getNumLinks(), 2);
  EXPECT_EQ(mb.getBaseMass(), 0.0);
  EXPECT_TRUE(mb.hasFixedBase());
  // The spec's table (rounded to the digits given there).
  EXPECT_NEAR(mb.getLinkMass(0), 10.472, 5e-4);
  EXPECT_NEAR(mb.getLinkInertia(0).x(), 0.06981, 5e-6);
  EXPECT_NEAR(mb.getLinkInertia(0).y(), 0.17453, 5e-6);
  EXPECT_NEAR(mb.getLinkInertia(0).z(), 0.17453, 5e-6);
  EXPECT_NEAR(mb.getLinkMass(1), 5.0186, 5e-5);
  EXPECT_NEAR(mb.getLinkInertia(1).x(), 0.26639, 5e-6);
  EXPECT_NEAR(mb.getLinkInertia(1).y(), 0.26654, 5e-6);
  EXPECT_NEAR(mb.getLinkInertia(1).z(), 0.02665, 5e-6);
  // Joint layout: prismatic x cart, revolute y pole hinged at the cart origin with its COM at (0.0005, 0,
  // 0.3).
  EXPECT_EQ(mb.getLink(0).m_jointType, btMultibodyLink::ePrismatic);
  EXPECT_EQ(mb.getLink(1).m_jointType, btMultibodyLink::eRevolute);
  EXPECT_EQ(mb.getLink(1).m_parent, 0);
  EXPECT_NEAR(mb.getLink(1).m_dVector.x(), 0.0005, 1e-12);
  EXPECT_NEAR(mb.getLink(1).m_dVector.z(), 0.3, 1e-12);
  // btMultiBody defaults the spec keeps.
  EXPECT_EQ(mb.getLinearDamping(), kDamping);
  EXPECT_EQ(mb.getAngularDamping(), kDamping);
  EXPECT_TRUE(mb.getUseGyroTerm());
  EXPECT_EQ(mb.getMaxCoordinateVelocity(), 100.0);
  EXPECT_FALSE(mb.getCanSleep());
}

TEST(CartPoleSwingup, InertiaHelpersAgreeWithBullet) {
  // What PyBullet's MJCF import does: Bullet's inertia estimate of the link's compound shape. A plain
  // capsule (the cart) is a btCapsuleShape child ...
  btVector3 inertia;
  btCapsuleShapeX cart(0.1, 0.2);
  btCompoundShape cart_compound;
  cart_compound.addChildShape(btTransform::getIdentity(), &cart);
  cart_compound.calculateLocalInertia(10.472, inertia);
  const Eigen::Vector3d mine = bullet::capsule_inertia(10.472, 0.1, 0.1, 0);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(mine[i], inertia[i], 1e-12);
  // ... and a from-to capsule (the pole) a two-sphere btMultiSphereShape child.
  const btVector3 ends[2] = {btVector3(0, 0, 0), btVector3(0.001, 0, 0.6)};
  const btScalar radii[2] = {0.049, 0.049};
  btMultiSphereShape pole(ends, radii, 2);
  btCompoundShape pole_compound;
  pole_compound.addChildShape(btTransform::getIdentity(), &pole);
  pole_compound.calculateLocalInertia(5.0186, inertia);
  const Eigen::Vector3d mine2 = bullet::fromto_capsule_inertia(5.0186, {0, 0, 0}, {0.001, 0, 0.6}, 0.049);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(mine2[i], inertia[i], 1e-12);
  // The hopper's torso of the locomotion spec, through the same helpers.
  const double torso_mass = bullet::capsule_mass(0.05, 0.4);
  EXPECT_NEAR(torso_mass, 3.6652, 5e-5);
  const Eigen::Vector3d torso = bullet::fromto_capsule_inertia(torso_mass, {0, 0, 1.45}, {0, 0, 1.05}, 0.05);
  EXPECT_NEAR(torso.x(), 0.11264, 5e-6);
  EXPECT_NEAR(torso.z(), 0.01979, 5e-6);
}

TEST(CartPoleSwingup, ResetAndObservation) {
  CartPoleSwingup env;
  for (uint64_t seed = 0; seed < 50; ++seed) {
    const Eigen::VectorXd obs = env.reset(seed);
    const double theta = env.robot().joint_position(CartPoleSwingup::kPole);
    EXPECT_EQ(obs[0], 0.0);
    EXPECT_EQ(obs[1], 0.0);
    EXPECT_GE(theta, 3.1415 - 0.1);
    EXPECT_LE(theta, 3.1415 + 0.1);
    EXPECT_EQ(obs[2], std::cos(theta));
    EXPECT_EQ(obs[3], std::sin(theta));
    EXPECT_EQ(obs[4], 0.0);
  }
}

TEST(CartPoleSwingup, ZeroActionReturnIsAboutMinus1000) {
  CartPoleSwingup env;
  for (uint64_t seed = 0; seed < 5; ++seed) {
    env.reset(seed);
    double ret = 0;
    int length = 0;
    StepResult r;
    do {
      r = env.step(Eigen::VectorXd::Zero(1));
      ret += r.reward;
      ++length;
      EXPECT_NEAR(r.reward, r.observation[2], 0.0);
    } while (!r.done());
    std::cout << "  cartpole_swingup zero-action return, seed " << seed << ": " << ret << " over " << length
              << " steps\n";
    EXPECT_EQ(length, 1000);
    EXPECT_TRUE(r.truncated);
    EXPECT_FALSE(r.terminated);
    // The pole hangs within 0.1 rad of straight down: cos stays below -cos(0.1) ~ -0.995.
    EXPECT_LT(ret, -990.0);
    EXPECT_GE(ret, -1000.0);
  }
}

TEST(CartPoleSwingup, FirstStepMatchesTheEquationsOfMotion) {
  // From rest the velocity after one step is dt * qdd, with qdd from the mass matrix and the cart force: a
  // check that the action becomes a pure 100 N joint force and nothing else acts.
  CartPoleSwingup env;
  const Params p = params(env);
  for (double a : {1.0, -0.3, 0.0}) {
    for (double th : {3.1415, 2.0, 0.4}) {
      env.reset(0);
      env.robot().set_joint_state(CartPoleSwingup::kPole, th, 0.0);
      env.step(Eigen::VectorXd::Constant(1, a));
      const double c = -p.cx * std::sin(th) + p.cz * std::cos(th);
      Eigen::Matrix2d mass;
      mass << p.M + p.m, p.m * c, p.m * c, p.Iyy + p.m * (p.cx * p.cx + p.cz * p.cz);
      const Eigen::Vector2d force(100.0 * a, p.m * kG * (p.cx * std::cos(th) + p.cz * std::sin(th)));
      const Eigen::Vector2d qdd = mass.ldlt().solve(force);
      EXPECT_NEAR(env.robot().joint_velocity(CartPoleSwingup::kCart), CartPoleSwingup::kDt * qdd[0], 1e-10);
      EXPECT_NEAR(env.robot().joint_velocity(CartPoleSwingup::kPole), CartPoleSwingup::kDt * qdd[1], 1e-10);
    }
  }
}

TEST(CartPoleSwingup, ForceIsClippedAt100N) {
  CartPoleSwingup a, b;
  a.reset(1);
  b.reset(1);
  for (int i = 0; i < 50; ++i) {
    const StepResult ra = a.step(Eigen::VectorXd::Constant(1, i < 25 ? 7.0 : -3.0));
    const StepResult rb = b.step(Eigen::VectorXd::Constant(1, i < 25 ? 1.0 : -1.0));
    ASSERT_EQ(ra.observation, rb.observation);
  }
}

// Small oscillations about hanging down: measured period against the physical-pendulum period.
double measured_period(bullet::World& world, bullet::Robot& robot, int pole, double amplitude, int steps) {
  robot.set_joint_state(pole, kPi + amplitude, 0.0);
  std::vector<double> turns;  // times where the pole's velocity changes sign
  double prev = 0;
  for (int i = 1; i <= steps; ++i) {
    world.step(CartPoleSwingup::kDt);
    const double v = robot.joint_velocity(pole);
    if (i > 1 && (v > 0) != (prev > 0)) {
      turns.push_back(CartPoleSwingup::kDt * (i - 1 + prev / (prev - v)));  // linear interpolation
    }
    prev = v;
  }
  EXPECT_GE(turns.size(), 5u);
  // Two turning points per period.
  return 2.0 * (turns.back() - turns.front()) / static_cast<double>(turns.size() - 1);
}

TEST(CartPoleSwingup, SmallAnglePeriodWithCartHeldAndFree) {
  CartPoleSwingup env;
  const Params p = params(env);
  const double d2 = p.cx * p.cx + p.cz * p.cz, d = std::sqrt(d2);
  {
    // Held cart: the same model with the cart's joint fixed.
    bullet::RobotSpec spec = CartPoleSwingup::model();
    spec.links[0].joint = bullet::JointType::kFixed;
    spec.links[0].limits.reset();
    bullet::World world;
    bullet::Robot& robot = world.add_robot(spec);
    const double period = measured_period(world, robot, 1, 0.02, 800);
    const double expected = 2 * kPi * std::sqrt((p.Iyy + p.m * d2) / (p.m * kG * d));
    std::cout << "  pole period, cart held: " << period << " s, physical pendulum " << expected << " s\n";
    EXPECT_NEAR(period / expected, 1.0, 2e-3);
  }
  {
    // Free cart, no force: x-momentum couples the cart in, I_eff = I + m d^2 M / (M + m).
    CartPoleSwingup free;
    free.reset(0);
    const double period = measured_period(free.world(), free.robot(), CartPoleSwingup::kPole, 0.02, 800);
    const double expected = 2 * kPi * std::sqrt((p.Iyy + p.m * d2 * p.M / (p.M + p.m)) / (p.m * kG * d));
    std::cout << "  pole period, cart free: " << period << " s, linearised model " << expected << " s\n";
    EXPECT_NEAR(period / expected, 1.0, 2e-3);
  }
}

struct EnergyAudit {
  double loss = 0;     // energy lost by the last turning point
  double damping = 0;  // work done by btMultiBody's damping up to then
  double worst = 0;    // largest |loss - damping work| over all turning points
  int turns = 0;
};

// Large free swings (1.2 rad, cart free, no force) for `seconds`, stepped with `h`. Energies are compared at
// the pole's turning points, where the kinetic energy (and the integrator's in-swing error) is near zero.
EnergyAudit audit_energy(double h, double seconds) {
  CartPoleSwingup env;
  env.reset(0);
  const Params p = params(env);
  auto& robot = env.robot();
  robot.set_joint_state(CartPoleSwingup::kPole, kPi + 1.2, 0.0);
  auto state = [&]() {
    return std::array<double, 3>{robot.joint_velocity(0), robot.joint_position(1), robot.joint_velocity(1)};
  };
  auto s = state();
  const double e0 = energy(p, s[0], s[1], s[2]);
  double dissipated = 0, prev_power = damping_power(p, s[0], s[1], s[2]), prev_thd = s[2];
  EnergyAudit audit;
  const int steps = static_cast<int>(seconds / h);
  for (int i = 0; i < steps; ++i) {
    env.world().step(h);
    s = state();
    EXPECT_LT(std::abs(robot.joint_position(0)), 0.9);  // never reaches the rail's ends
    const double power = damping_power(p, s[0], s[1], s[2]);
    dissipated += 0.5 * (power + prev_power) * h;
    prev_power = power;
    if (i > 0 && (s[2] > 0) != (prev_thd > 0)) {
      ++audit.turns;
      audit.loss = e0 - energy(p, s[0], s[1], s[2]);
      audit.damping = dissipated;
      audit.worst = std::max(audit.worst, std::abs(audit.loss - dissipated));
    }
    prev_thd = s[2];
  }
  return audit;
}

TEST(CartPoleSwingup, EnergyBalanceWithBuiltInDamping) {
  // The energy lost equals the work of btMultiBody's built-in damping and nothing else (no hidden motor,
  // joint friction or gravity change), up to the integrator's own first-order loss: btMultiBody steps
  // velocities then positions (semi-implicit Euler on the joint velocities, not momenta), which bleeds a
  // little energy in proportion to the step. Measured with the model exactly as built.
  const double dt = CartPoleSwingup::kDt;
  const EnergyAudit fine = audit_energy(dt / 16, 20.0);
  const EnergyAudit medium = audit_energy(dt / 4, 20.0);
  const EnergyAudit env_step = audit_energy(dt, 20.0);
  for (const auto& [name, a] : {std::pair{"dt/16", fine}, {"dt/4", medium}, {"dt", env_step}}) {
    std::cout << "  step " << name << ": energy lost " << a.loss << " J over " << a.turns
              << " turning points, damping work " << a.damping << " J, worst mismatch " << a.worst << " J\n";
  }
  EXPECT_GT(fine.turns, 25);
  EXPECT_GT(fine.loss, 5.0);                // damping is really there
  EXPECT_LT(fine.worst, 0.02 * fine.loss);  // and explains the loss
  // The remainder is the integrator's: it shrinks in proportion to the step.
  const double r_env = env_step.loss - env_step.damping, r_medium = medium.loss - medium.damping;
  EXPECT_GT(r_env, 0.0);
  EXPECT_NEAR(r_env / r_medium, 4.0, 1.0);
}

// Drives the cart with `policy(step)` for 1000 steps and checks the rail limit: Bullet's joint-limit rows act
// once the joint is past its limit and carry no position correction, so the cart stops within the step that
// crossed the end (at most one step of travel beyond it) and never moves further out while it is past it.
void check_rail(const std::function<double(int)>& policy, const std::string& label) {
  CartPoleSwingup env;
  env.reset(2);
  const double dt = CartPoleSwingup::kDt, limit = CartPoleSwingup::kRailLimit;
  double extreme = 0, top_speed = 0, x_prev = 0;
  for (int i = 0; i < 1000; ++i) {
    env.step(Eigen::VectorXd::Constant(1, policy(i)));
    const double x = env.robot().joint_position(CartPoleSwingup::kCart);
    const double v = env.robot().joint_velocity(CartPoleSwingup::kCart);
    if (std::abs(x_prev) > limit) {
      // Past the end: no further outward travel.
      ASSERT_LE(std::abs(x), std::abs(x_prev) + 1e-12) << label << " step " << i;
    }
    extreme = std::max(extreme, std::abs(x));
    top_speed = std::max(top_speed, std::abs(v));
    x_prev = x;
  }
  std::cout << "  " << label << ": furthest cart position " << extreme << " m, top speed " << top_speed
            << " m/s\n";
  EXPECT_GT(extreme, limit);  // the end was reached
  EXPECT_LE(extreme - limit, top_speed * dt * 1.1);
  EXPECT_LT(extreme, limit + 0.1);
}

TEST(CartPoleSwingup, RailLimitHolds) {
  check_rail([](int) { return 1.0; }, "constant +1");
  check_rail([](int) { return -1.0; }, "constant -1");
  check_rail([](int i) { return (i / 60) % 2 ? -1.0 : 1.0; }, "bang-bang");
  std::mt19937_64 rng(5);
  check_rail([&](int i) { return (i / 30) % 2 ? 1.0 : std::uniform_real_distribution<double>(-1, 1)(rng); },
             "random with pushes");
}

TEST(CartPoleSwingup, NonFiniteStateEndsTheEpisode) {
  CartPoleSwingup env;
  env.reset(0);
  env.robot().set_joint_state(CartPoleSwingup::kPole, 1.0, 1e200);
  const StepResult r = env.step(Eigen::VectorXd::Zero(1));
  EXPECT_TRUE(r.terminated);
  EXPECT_NE(r.failure.find("non-finite"), std::string::npos) << r.failure;
  EXPECT_TRUE(r.observation.allFinite());
  EXPECT_THROW(env.step(Eigen::VectorXd::Zero(1)), Error);
  // A reset recovers.
  env.reset(0);
  EXPECT_TRUE(env.step(Eigen::VectorXd::Zero(1)).observation.allFinite());
}

}  // namespace
}  // namespace hlt
