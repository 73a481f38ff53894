// ModelCheck (agents/model_check.h): the per-component errors and the ratio against "no change" on models
// whose predictions are known (no change, exact in one component, half right, drifting), in the components'
// own spreads and in declared units.
#include <gtest/gtest.h>

#include <cmath>

#include <torch/torch.h>

#include "agents/model_check.h"
#include "envs/registry.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

// A dynamics model s' = s + W2 relu(W1 [s, a] + b1) + b2 set by hand: with W2 = 0 it predicts s' = s + b2.
DynamicsModel constant_shift_model(const std::vector<float>& shift, int64_t action_dim = 1) {
  DynamicsModelOptions o;
  o.state_dim = static_cast<int64_t>(shift.size());
  o.action_dim = action_dim;
  o.hidden = 4;
  o.activation = Activation::kRelu;
  DynamicsModel m(o);
  torch::NoGradGuard g;
  m->fc2->weight.zero_();
  m->fc2->bias.copy_(torch::tensor(shift));
  return m;
}

// Transitions whose next observation is the observation plus (0.1, 0, 0.3 * action).
ModelCheck transitions() {
  ModelCheck c;
  for (int i = 0; i < 10; ++i) {
    const Eigen::Vector3d o(i, -i, 0.5 * i);
    const Eigen::VectorXd a = Eigen::VectorXd::Constant(1, i % 2 == 0 ? 1.0 : -1.0);
    c.add(o, a, o + Eigen::Vector3d(0.1, 0.0, 0.3 * a[0]));
  }
  return c;
}

TEST(ModelCheck, NoChangeModelScoresRatioOne) {
  const ModelScore s = transitions().score(*constant_shift_model({0, 0, 0}));
  EXPECT_EQ(s.transitions, 10);
  // Predicting o' = o: the error is the change itself in every component.
  EXPECT_NEAR(s.error_rms[0], 0.1, 1e-6);
  EXPECT_NEAR(s.error_rms[1], 0.0, 1e-6);
  EXPECT_NEAR(s.error_rms[2], 0.3, 1e-6);
  EXPECT_NEAR(s.change_rms[0], 0.1, 1e-6);
  EXPECT_EQ(s.change_rms[1], 0.0);
  EXPECT_NEAR(s.change_rms[2], 0.3, 1e-6);
  // Component 1 never changes: it adds nothing to either side of the ratio.
  EXPECT_NEAR(s.error_ratio, 1.0, 1e-5);
  EXPECT_EQ(s.better, 0);
}

// The pooled ratio with each component in its own spread: component 0 of the observations is 0..9
// (standard deviation sqrt(8.25)), component 1 is -(0..9) (the same), component 2 is 0.5 * (0..9).
double pooled(const ModelScore& s, double e0, double e2) {
  const double s0 = std::sqrt(8.25), s2 = 0.5 * s0;
  EXPECT_NEAR(s.spread[0], s0, 1e-12);
  EXPECT_NEAR(s.spread[1], s0, 1e-12);
  EXPECT_NEAR(s.spread[2], s2, 1e-12);
  return std::hypot(e0 / s0, e2 / s2) / std::hypot(0.1 / s0, 0.3 / s2);
}

TEST(ModelCheck, RatioPoolsTheComponentsEachInItsOwnSpread) {
  // Shift (0.1, 0, 0): exact in component 0 (up to float rounding), "no change" in component 2.
  const ModelScore exact0 = transitions().score(*constant_shift_model({0.1f, 0, 0}));
  EXPECT_NEAR(exact0.error_rms[0], 0.0, 1e-6);
  EXPECT_EQ(exact0.better, 1);
  EXPECT_NEAR(exact0.error_ratio, pooled(exact0, 0.0, 0.3), 1e-6);
  EXPECT_LT(exact0.error_ratio, 1.0);
  // Shift (0.05, 0, 0.6): component 0 off by 0.05; component 2 off by 0.3 where the action is +1 and by 0.9
  // where it is -1 (rms sqrt(0.45)): worse than "no change" overall.
  const ModelScore half = transitions().score(*constant_shift_model({0.05f, 0, 0.6f}));
  EXPECT_NEAR(half.error_rms[0], 0.05, 1e-6);
  EXPECT_NEAR(half.error_rms[2], std::sqrt(0.45), 1e-6);
  EXPECT_NEAR(half.error_ratio, pooled(half, 0.05, std::sqrt(0.45)), 1e-5);
  EXPECT_GT(half.error_ratio, 1.0);
  EXPECT_EQ(half.better, 1);
  // A model that moves a component that never changes (component 1, by 1 cm per step) counts that error in
  // the component's own spread, though "no change" is exact there.
  const ModelScore drift = transitions().score(*constant_shift_model({0.1f, 0.01f, 0}));
  const double s0 = std::sqrt(8.25), s2 = 0.5 * s0;
  EXPECT_NEAR(drift.error_rms[1], 0.01, 1e-6);
  EXPECT_NEAR(drift.error_ratio, std::hypot(0.01 / s0, 0.3 / s2) / std::hypot(0.1 / s0, 0.3 / s2), 1e-6);
  EXPECT_GT(drift.error_ratio, exact0.error_ratio);
}

// Component 1 stands still at 5 up to 1e-12 jitter (as a block that is never touched does in a simulator).
ModelCheck transitions_with_a_still_component() {
  ModelCheck c;
  for (int i = 0; i < 10; ++i) {
    const Eigen::Vector3d o(i, 5.0 + 1e-12 * i, 0.5 * i);
    const Eigen::VectorXd a = Eigen::VectorXd::Constant(1, i % 2 == 0 ? 1.0 : -1.0);
    c.add(o, a, o + Eigen::Vector3d(0.1, 0.0, 0.3 * a[0]));
  }
  return c;
}

TEST(ModelCheck, ANumericallyConstantComponentIsLeftOutUnlessUnitsAreDeclared) {
  // The model moves the still component by 1 mm per step. In its own spread (1e-12) that would be an error
  // of 1e9 spreads; it counts as constant instead, and the ratio is the other two components'.
  const ModelCheck c = transitions_with_a_still_component();
  DynamicsModel moving = constant_shift_model({0.1f, 0.001f, 0});
  const ModelScore own = c.score(*moving);
  EXPECT_EQ(own.unit[1], 0.0);
  const double s0 = std::sqrt(8.25), s2 = 0.5 * s0;
  EXPECT_NEAR(own.error_ratio, std::hypot(own.error_rms[0] / s0, 0.3 / s2) / std::hypot(0.1 / s0, 0.3 / s2),
              1e-6);
  EXPECT_LT(own.error_ratio, 1.0);
  // With declared units (metres for all three) the millimetre counts, at its size.
  const ModelScore declared = c.score(*moving, Eigen::Vector3d(1.0, 1.0, 1.0));
  EXPECT_EQ(declared.unit, Eigen::VectorXd(Eigen::Vector3d(1.0, 1.0, 1.0)));
  EXPECT_NEAR(declared.error_rms[1], 0.001, 1e-5);
  EXPECT_NEAR(declared.error_ratio,
              std::sqrt(std::pow(declared.error_rms[0], 2) + std::pow(declared.error_rms[1], 2) + 0.09) /
                  std::sqrt(0.01 + 0.09),
              1e-6);
  EXPECT_THROW(c.score(*moving, Eigen::Vector3d(1.0, 0.0, 1.0)), Error);
  EXPECT_THROW(c.score(*moving, Eigen::Vector2d(1.0, 1.0)), Error);
}

// With an environment, the units are the ones it declares (block_push), or none (pendulum: the spread).
TEST(ModelCheck, AnEnvironmentGivesItsDeclaredUnits) {
  for (const char* name : {"block_push", "pendulum"}) {
    auto env = make_env(name);
    const int n = env->observation_dim();
    ModelCheck c;
    Eigen::VectorXd o = env->reset(3);
    for (int t = 0; t < 5; ++t) {
      const Eigen::VectorXd a = Eigen::VectorXd::Constant(env->action_dim(), 0.5);
      const StepResult r = env->step(a);
      c.add(o, a, r.observation);
      o = r.observation;
    }
    DynamicsModel model =
        constant_shift_model(std::vector<float>(static_cast<size_t>(n), 0.01f), env->action_dim());
    const std::optional<ObservationScale> declared = env->observation_scale();
    const ModelScore with_env = c.score(*model, *env);
    const ModelScore expected =
        c.score(*model, declared ? std::optional<Eigen::VectorXd>(declared->scale) : std::nullopt);
    EXPECT_EQ(with_env.unit, expected.unit) << name;
    EXPECT_EQ(with_env.error_ratio, expected.error_ratio) << name;
    EXPECT_EQ(declared.has_value(), std::string(name) == "block_push");
  }
}

TEST(ModelCheck, RefusesMismatchedSizesAndAnEmptyCheck) {
  ModelCheck c;
  EXPECT_THROW(c.score(*constant_shift_model({0, 0, 0})), Error);
  c.add(Eigen::Vector3d::Zero(), Eigen::VectorXd::Zero(1), Eigen::Vector3d::Ones());
  EXPECT_THROW(c.add(Eigen::Vector2d::Zero(), Eigen::VectorXd::Zero(1), Eigen::Vector2d::Ones()), Error);
  EXPECT_THROW(c.score(*constant_shift_model({0, 0})), Error);
  EXPECT_EQ(c.size(), 1);
  c.clear();
  EXPECT_EQ(c.size(), 0);
}

}  // namespace
}  // namespace hlt
