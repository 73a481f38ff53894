#include "envs/env.h"

#include <gtest/gtest.h>

#include <limits>

#include "envs/registry.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

// A 1-D integrator: x' = x + a, reward -x^2, terminal when |x| > 5, limit 10 steps. Enough to test the base
// class's bookkeeping without any simulator.
class Integrator : public Env {
 public:
  std::string name() const override { return "integrator"; }
  int observation_dim() const override { return 1; }
  int action_dim() const override { return 1; }
  int max_episode_steps() const override { return 10; }
  double dt() const override { return 1.0; }
  cv::Mat render(int w, int h) const override { return cv::Mat::zeros(h, w, CV_8UC3); }
  double x = 0;
  bool blow_up = false;

 protected:
  Eigen::VectorXd reset_impl(std::mt19937_64& rng) override {
    x = std::uniform_real_distribution<double>(-0.1, 0.1)(rng);
    return Eigen::VectorXd::Constant(1, x);
  }
  StepResult step_impl(const Eigen::VectorXd& a) override {
    x += a[0];
    StepResult r;
    r.observation = Eigen::VectorXd::Constant(1, blow_up ? std::numeric_limits<double>::quiet_NaN() : x);
    r.reward = -x * x;
    r.terminated = std::abs(x) > 5;
    return r;
  }
  std::vector<double> save_sim() const override { return {x}; }
  void restore_sim(const std::vector<double>& s) override { x = s.at(0); }
};

TEST(EnvApi, TimeLimitIsTruncationNotTermination) {
  Integrator env;
  env.reset(1);
  StepResult r;
  for (int i = 0; i < 10; ++i)
    r = env.step(Eigen::VectorXd::Constant(1, 0.1));
  EXPECT_TRUE(r.truncated);
  EXPECT_FALSE(r.terminated);
  EXPECT_THROW(env.step(Eigen::VectorXd::Zero(1)), Error);  // must reset first
}

TEST(EnvApi, RejectsBadActions) {
  Integrator env;
  env.reset(0);
  EXPECT_THROW(env.step(Eigen::VectorXd::Zero(2)), Error);
  EXPECT_THROW(env.step(Eigen::VectorXd::Constant(1, std::numeric_limits<double>::quiet_NaN())), Error);
  EXPECT_THROW(env.step(Eigen::VectorXd::Constant(1, std::numeric_limits<double>::infinity())), Error);
}

TEST(EnvApi, NonFiniteSimulationEndsEpisodeWithReport) {
  Integrator env;
  const Eigen::VectorXd obs0 = env.reset(0);
  env.blow_up = true;
  const StepResult r = env.step(Eigen::VectorXd::Constant(1, 0.5));
  EXPECT_TRUE(r.terminated);
  EXPECT_FALSE(r.failure.empty());
  EXPECT_TRUE(r.observation.allFinite());
  EXPECT_EQ(r.observation[0], obs0[0]);
}

TEST(EnvApi, SeedsAndSnapshots) {
  Integrator a, b;
  EXPECT_EQ(a.reset(7)[0], b.reset(7)[0]);
  EXPECT_NE(a.reset(7)[0], a.reset(8)[0]);
  a.reset(3);
  a.step(Eigen::VectorXd::Constant(1, 0.2));
  const EnvState snap = a.save_state();
  const double after1 = a.step(Eigen::VectorXd::Constant(1, 0.3)).observation[0];
  const double next_reset = a.reset()[0];
  a.restore_state(snap);
  EXPECT_EQ(a.elapsed_steps(), 1);
  EXPECT_EQ(a.step(Eigen::VectorXd::Constant(1, 0.3)).observation[0], after1);
  EXPECT_EQ(a.reset()[0], next_reset);  // the generator was restored too
}

TEST(EnvApi, FrameSkipSumsRewardsAndKeepsSimulatorLimit) {
  FrameSkip env(std::make_unique<Integrator>(), 4);
  EXPECT_EQ(env.max_episode_steps(), 3);  // ceil(10 / 4)
  env.reset(0);
  const StepResult r1 = env.step(Eigen::VectorXd::Constant(1, 0.0));
  EXPECT_EQ(env.last_step_frames(), 4);
  EXPECT_EQ(env.inner_elapsed_steps(), 4);
  EXPECT_LE(r1.reward, 0.0);
  env.step(Eigen::VectorXd::Zero(1));
  const StepResult r3 = env.step(Eigen::VectorXd::Zero(1));
  EXPECT_EQ(env.last_step_frames(), 2);  // only 2 simulator steps were left of the 10
  EXPECT_TRUE(r3.truncated);
  // Snapshots of a wrapper restore the inner environment too.
  env.reset(5);
  env.step(Eigen::VectorXd::Constant(1, 0.5));
  const EnvState snap = env.save_state();
  const StepResult x = env.step(Eigen::VectorXd::Constant(1, 0.5));
  env.restore_state(snap);
  EXPECT_EQ(env.step(Eigen::VectorXd::Constant(1, 0.5)).observation[0], x.observation[0]);
  EXPECT_EQ(env.inner_elapsed_steps(), 8);
}

TEST(EnvApi, UnknownNameListsKnownOnes) {
  try {
    make_env("no_such_env");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("unknown environment 'no_such_env'"), std::string::npos);
  }
}

}  // namespace
}  // namespace hlt
