// Properties every registered environment must have: sizes, determinism under a seed, exact save/restore,
// bad-action errors, a finite render.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "envs/env.h"
#include "envs/registry.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

class AllEnvs : public testing::TestWithParam<std::string> {};

struct Trajectory {
  std::vector<Eigen::VectorXd> observations;
  std::vector<double> rewards;
  std::vector<bool> dones;
};

// Runs `steps` steps of uniform-random actions drawn from `action_seed`, resetting when an episode ends.
Trajectory run(Env& env, int steps, uint64_t action_seed) {
  std::mt19937_64 rng(action_seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Trajectory t;
  for (int i = 0; i < steps; ++i) {
    Eigen::VectorXd a(env.action_dim());
    for (int j = 0; j < a.size(); ++j)
      a[j] = u(rng);
    const StepResult r = env.step(a);
    t.observations.push_back(r.observation);
    t.rewards.push_back(r.reward);
    t.dones.push_back(r.done());
    if (r.done()) t.observations.push_back(env.reset());
  }
  return t;
}

void expect_identical(const Trajectory& a, const Trajectory& b) {
  ASSERT_EQ(a.observations.size(), b.observations.size());
  for (size_t i = 0; i < a.observations.size(); ++i) {
    ASSERT_EQ(a.observations[i], b.observations[i]) << "observation " << i;
  }
  EXPECT_EQ(a.rewards, b.rewards);
  EXPECT_EQ(a.dones, b.dones);
}

TEST_P(AllEnvs, SizesAndFirstObservation) {
  auto env = make_env(GetParam());
  EXPECT_EQ(env->name(), GetParam());
  EXPECT_GT(env->observation_dim(), 0);
  EXPECT_GT(env->action_dim(), 0);
  EXPECT_GT(env->max_episode_steps(), 0);
  EXPECT_GT(env->dt(), 0.0);
  const Eigen::VectorXd obs = env->reset(0);
  EXPECT_EQ(obs.size(), env->observation_dim());
  EXPECT_TRUE(obs.allFinite());
}

TEST_P(AllEnvs, SameSeedSameTrajectory) {
  auto a = make_env(GetParam());
  auto b = make_env(GetParam());
  const Eigen::VectorXd oa = a->reset(42), ob = b->reset(42);
  EXPECT_EQ(oa, ob);
  expect_identical(run(*a, 1500, 7), run(*b, 1500, 7));
  // A different seed gives a different start.
  EXPECT_NE(a->reset(42), a->reset(43));
}

TEST_P(AllEnvs, SaveRestoreReproducesNextSteps) {
  auto env = make_env(GetParam());
  env->reset(3);
  run(*env, 37, 1);
  const EnvState snap = env->save_state();
  const Trajectory first = run(*env, 300, 2);
  env->restore_state(snap);
  expect_identical(first, run(*env, 300, 2));
  // A snapshot also carries over to a fresh instance.
  auto other = make_env(GetParam());
  other->restore_state(snap);
  expect_identical(first, run(*other, 300, 2));
}

TEST_P(AllEnvs, FrameSkipSnapshotsAndLimit) {
  FrameSkip env(make_env(GetParam()), 3);
  env.reset(5);
  run(env, 11, 4);
  const EnvState snap = env.save_state();
  const Trajectory first = run(env, 120, 9);
  env.restore_state(snap);
  expect_identical(first, run(env, 120, 9));
  EXPECT_EQ(env.max_episode_steps(), (make_env(GetParam())->max_episode_steps() + 2) / 3);
}

TEST_P(AllEnvs, RejectsBadActions) {
  auto env = make_env(GetParam());
  env->reset(0);
  const int m = env->action_dim();
  EXPECT_THROW(env->step(Eigen::VectorXd::Zero(m + 1)), Error);
  EXPECT_THROW(env->step(Eigen::VectorXd::Zero(0)), Error);
  Eigen::VectorXd bad = Eigen::VectorXd::Zero(m);
  bad[m - 1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(env->step(bad), Error);
  bad[m - 1] = -std::numeric_limits<double>::infinity();
  EXPECT_THROW(env->step(bad), Error);
  try {
    env->step(Eigen::VectorXd::Zero(m + 2));
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("expected " + std::to_string(m)), std::string::npos) << e.what();
  }
  // Rejected actions leave the episode usable.
  EXPECT_NO_THROW(env->step(Eigen::VectorXd::Zero(m)));
}

TEST_P(AllEnvs, RejectsCorruptSnapshots) {
  auto env = make_env(GetParam());
  env->reset(0);
  EnvState s = env->save_state();
  s.sim.push_back(1.0);
  EXPECT_THROW(env->restore_state(s), Error);
  s.sim.pop_back();
  s.sim[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(env->restore_state(s), Error);
}

TEST_P(AllEnvs, RendersAnImage) {
  auto env = make_env(GetParam());
  env->reset(0);
  env->step(Eigen::VectorXd::Constant(env->action_dim(), 0.5));
  const cv::Mat img = env->render(320, 240);
  EXPECT_EQ(img.cols, 320);
  EXPECT_EQ(img.rows, 240);
  EXPECT_EQ(img.type(), CV_8UC3);
  // Something besides the background was drawn.
  cv::Mat grey;
  img.reshape(1).copyTo(grey);
  double lo, hi;
  cv::minMaxLoc(grey, &lo, &hi);
  EXPECT_LT(lo, 200.0);
}

INSTANTIATE_TEST_SUITE_P(Registered, AllEnvs, testing::ValuesIn(env_names()),
                         [](const testing::TestParamInfo<std::string>& info) { return info.param; });

TEST(Registry, KnowsTheEnvironmentsAndListsThemOnError) {
  const std::vector<std::string> names = env_names();
  for (const char* n : {"pendulum", "cartpole_swingup", "acrobot", "hopper", "half_cheetah", "ant",
                        "block_push", "block_stack", "block_push_camera", "block_stack_camera"})
    EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
  try {
    make_env("pendulm");
    FAIL();
  } catch (const Error& e) {
    for (const auto& n : names)
      EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace hlt
