// The robot tasks observed through the camera (envs/robot/camera_observed.h): the observation has the state
// task's layout and stays close to it over whole episodes (the estimator in the loop, with bounds on its
// error), the robot's own sensors pass through untouched, the reward is the task's reward of what the camera
// saw, snapshots stay exact with the estimator's filter in them, and the stacking expert still stacks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include "envs/registry.h"
#include "envs/robot/block_push.h"
#include "envs/robot/block_stack.h"
#include "envs/robot/camera_observed.h"
#include "envs/rollout.h"
#include "envs/scripted.h"
#include "hlt/util/error.h"

namespace hlt::robot {
namespace {

std::unique_ptr<CameraObserved> make_camera_env(const std::string& name) {
  std::unique_ptr<Env> env = make_env(name);
  auto* camera = dynamic_cast<CameraObserved*>(env.get());
  EXPECT_NE(camera, nullptr) << name;
  env.release();
  return std::unique_ptr<CameraObserved>(camera);
}

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(std::min<double>(v.size() - 1, std::floor(q * (v.size() - 1) + 0.5)))];
}

double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v)
    s += x;
  return s / static_cast<double>(v.size());
}

struct EpisodeErrors {
  std::vector<double> position;  // every object at every step, metres
  std::vector<double> yaw;       // planar tasks only, radians
  int misses = 0, measurements = 0;
  // Object-frames in which an object was hidden under another: not counted in `misses`/`measurements`.
  int covered = 0;
  std::vector<Eigen::VectorXd> camera, state;
};

// Whether object `i` is hidden from the camera by another, judged on the simulator's state observation.
using Covered = std::function<bool(size_t i, const Eigen::VectorXd& state)>;

// One episode with `policy`, collecting the estimator's error against the simulator at every control step.
EpisodeErrors run_episode_errors(CameraObserved& env, PolicySource& policy, uint64_t seed, bool yaw,
                                 const Covered& covered = {}) {
  EpisodeErrors e;
  auto collect = [&](const Eigen::VectorXd& observation) {
    const PerceptionRecord& r = env.last_perception();
    for (size_t i = 0; i < r.position_error.size(); ++i) {
      e.position.push_back(r.position_error[i]);
      if (yaw) e.yaw.push_back(r.yaw_error[i]);
      if (covered && covered(i, r.state_observation)) {
        ++e.covered;
        continue;
      }
      ++e.measurements;
      if (r.source[i] == EstimateSource::kHeld || r.source[i] == EstimateSource::kNone) ++e.misses;
    }
    e.camera.push_back(observation);
    e.state.push_back(r.state_observation);
  };
  collect(env.reset(seed));
  Eigen::VectorXd o = e.camera.back();
  for (;;) {
    const StepResult s = env.step(policy.act(o));
    EXPECT_TRUE(s.failure.empty()) << s.failure;
    collect(s.observation);
    o = s.observation;
    if (s.done()) break;
  }
  return e;
}

TEST(CameraObserved, RegisteredBesideTheStateTasksWithTheSameShape) {
  for (const auto& [camera, state] : {std::pair<std::string, std::string>{"block_push_camera", "block_push"},
                                      {"block_stack_camera", "block_stack"}}) {
    const std::unique_ptr<CameraObserved> c = make_camera_env(camera);
    const std::unique_ptr<Env> s = make_env(state);
    EXPECT_EQ(c->name(), camera);
    EXPECT_EQ(c->task().name(), state);
    EXPECT_EQ(c->observation_dim(), s->observation_dim());
    EXPECT_EQ(c->action_dim(), s->action_dim());
    EXPECT_EQ(c->max_episode_steps(), s->max_episode_steps());
    EXPECT_EQ(c->dt(), s->dt());
    // The wrapper resets its task with the first draw of its own generator: with that seed the state task
    // starts in the same scene, and the camera's observation is the state's, perceived.
    const Eigen::VectorXd oc = c->reset(3), os = s->reset(std::mt19937_64(3)());
    EXPECT_EQ(c->last_perception().state_observation, os);
    EXPECT_LT((oc - os).cwiseAbs().maxCoeff(), 0.01) << camera << "\n"
                                                     << oc.transpose() << "\n"
                                                     << os.transpose();
  }
}

// Pushing: every entry of the observation means what it means in block_push, within millimetres and a
// degree or two, over a whole episode of random actions (the tool sweeps around, hiding the block now and
// then: the colour tracker or the filter's held value covers those frames).
TEST(CameraObserved, PushingEstimatorInTheLoopOverAnEpisode) {
  const std::unique_ptr<CameraObserved> env = make_camera_env("block_push_camera");
  const std::unique_ptr<PolicySource> policy = make_simple_policy("random", 2, 11);
  const EpisodeErrors e = run_episode_errors(*env, *policy, 5, true);
  ASSERT_EQ(e.camera.size(), 101u);
  for (size_t t = 0; t < e.camera.size(); ++t) {
    const Eigen::VectorXd d = (e.camera[t] - e.state[t]).cwiseAbs();
    // dx, dy of end-effector to block and block to target (metres), and the two yaw differences (radians,
    // compared modulo a full turn).
    for (int i : {0, 1, 3, 4})
      EXPECT_LT(d[i], 0.01) << "step " << t << " entry " << i;
    for (int i : {2, 5})
      EXPECT_LT(std::abs(std::remainder(e.camera[t][i] - e.state[t][i], 2 * M_PI)), 0.06)
          << "step " << t << " entry " << i;
    // The tool's position and command are the robot's own, not the camera's.
    ASSERT_EQ(e.camera[t].size(), BlockPush::kObservationDim);
    EXPECT_EQ(e.camera[t].tail<4>(), e.state[t].tail<4>()) << "step " << t;
  }
  // The bounds docs/ROBOT_TASKS.md's measurements are far inside.
  EXPECT_LT(mean(e.position), 0.002);
  EXPECT_LT(quantile(e.position, 0.95), 0.005);
  EXPECT_LT(quantile(e.yaw, 0.95), 0.03);
  EXPECT_LT(e.misses, e.measurements / 10);
}

// Stacking: the three positions come from the camera, the gripper and the wrench from the robot. The
// scripted expert (which reads only the observation) still stacks through the camera.
TEST(CameraObserved, StackingEstimatorInTheLoopAndTheExpertStillStacks) {
  const std::unique_ptr<CameraObserved> env = make_camera_env("block_stack_camera");
  const std::unique_ptr<PolicySource> expert =
      make_scripted_policy("block_stack_camera", "block_stack_camera", 0);
  // The stacked block hides the base's top tag for the rest of the episode (the expert stacks by step ~40
  // of 200): the estimator then holds the base's last estimate, a static object's, which the error checks
  // below cover. Misses are counted where an object can be seen.
  const auto& objects = env->objects();
  const auto base = static_cast<size_t>(
      std::find_if(objects.begin(), objects.end(), [](const TrackedObject& o) { return o.name == "base"; }) -
      objects.begin());
  ASSERT_LT(base, objects.size());
  const Covered block_on_base = [base](size_t i, const Eigen::VectorXd& s) {
    const Eigen::Vector3d block = s.segment<3>(BlockStack::kBlock), b = s.segment<3>(BlockStack::kBase);
    return i == base && (block - b).head<2>().norm() < 2 * BlockStack::kBlockHalf &&
           block.z() > b.z() + BlockStack::kBlockHalf;
  };
  const EpisodeErrors e = run_episode_errors(*env, *expert, 2, false, block_on_base);
  ASSERT_EQ(e.camera.size(), 201u);
  // Seed 2: the block rests on the base from about step 38 on (163 of the base's 201 frames).
  EXPECT_GT(e.covered, 150);
  for (size_t t = 0; t < e.camera.size(); ++t) {
    EXPECT_EQ(e.camera[t].tail<7>(), e.state[t].tail<7>()) << "the robot's own sensors, step " << t;
    // The largest single difference measured for this episode was 15.2 mm (step 35); typical ones are 1 mm.
    EXPECT_LT((e.camera[t].head<9>() - e.state[t].head<9>()).cwiseAbs().maxCoeff(), 0.02) << "step " << t;
  }
  EXPECT_LT(mean(e.position), 0.003);
  EXPECT_LT(quantile(e.position, 0.95), 0.008);
  EXPECT_LT(e.misses, e.measurements / 10);
  EXPECT_TRUE(dynamic_cast<const BlockStack&>(env->task()).success());
  // The episode loop's verdict is the task's, judged on the simulator's truth.
  EXPECT_EQ(env->episode_success(), std::optional<bool>(true));
}

// The reward is the task's reward of the camera's observation (what a real robot could compute), not of the
// simulator's truth.
TEST(CameraObserved, RewardIsTheTasksRewardOfWhatTheCameraSaw) {
  const std::unique_ptr<CameraObserved> push = make_camera_env("block_push_camera");
  push->reset(1);
  const Eigen::Vector2d a(0.3, -2.0);  // clipped to [-1, 1] as the task clips
  const StepResult r = push->step(a);
  EXPECT_DOUBLE_EQ(r.reward, BlockPush::reward(r.observation, Eigen::Vector2d(0.3, -1.0)));
  EXPECT_NE(r.observation, push->last_perception().state_observation);  // it is the camera's
  const std::unique_ptr<CameraObserved> stack = make_camera_env("block_stack_camera");
  stack->reset(1);
  const Eigen::Vector4d b(0.1, 0.2, -0.3, 0.5);
  const StepResult q = stack->step(b);
  EXPECT_DOUBLE_EQ(q.reward, BlockStack::reward(q.observation, b));
}

// Snapshots in camera mode: the estimator's filter, the frame counter and the noise seed are in the
// snapshot, so the steps after a restore repeat bit for bit, also in a fresh environment with another
// history, and also across an occlusion (held estimates).
TEST(CameraObserved, SnapshotsAreExact) {
  for (const char* name : {"block_push_camera", "block_stack_camera"}) {
    const std::unique_ptr<CameraObserved> env = make_camera_env(name);
    std::mt19937_64 rng(4);
    std::uniform_real_distribution<double> u(-1, 1);
    auto action = [&] {
      Eigen::VectorXd a(env->action_dim());
      for (int j = 0; j < a.size(); ++j)
        a[j] = u(rng);
      return a;
    };
    env->reset(9);
    for (int i = 0; i < 15; ++i)
      env->step(action());
    const EnvState saved = env->save_state();
    std::vector<Eigen::VectorXd> actions;
    std::vector<StepResult> first;
    for (int i = 0; i < 12; ++i) {
      actions.push_back(action());
      first.push_back(env->step(actions.back()));
    }
    const std::vector<double> filter_after = env->save_state().sim;
    auto replay = [&](CameraObserved& e) {
      e.restore_state(saved);
      for (int i = 0; i < 12; ++i) {
        const StepResult r = e.step(actions[static_cast<size_t>(i)]);
        ASSERT_EQ(r.observation, first[static_cast<size_t>(i)].observation) << name << " step " << i;
        ASSERT_EQ(r.reward, first[static_cast<size_t>(i)].reward) << name << " step " << i;
      }
      EXPECT_EQ(e.save_state().sim, filter_after) << name;
    };
    replay(*env);
    const std::unique_ptr<CameraObserved> other = make_camera_env(name);
    other->reset(123);
    for (int i = 0; i < 3; ++i)
      other->step(action());
    replay(*other);
    // Without the filter in the snapshot the next observation would differ: the filter carries history.
    EnvState no_filter = saved;
    const std::unique_ptr<CameraObserved> fresh = make_camera_env(name);
    fresh->reset(9);
    EnvState fresh_state = fresh->save_state();
    no_filter.sim = fresh_state.sim;  // a just-reset filter with the same simulator state
    fresh->restore_state(no_filter);
    EXPECT_NE(fresh->step(actions[0]).observation, first[0].observation) << name;
  }
}

TEST(CameraObserved, RejectsCorruptFilterSnapshots) {
  const std::unique_ptr<CameraObserved> env = make_camera_env("block_push_camera");
  env->reset(0);
  EnvState s = env->save_state();
  EnvState short_sim = s;
  short_sim.sim.pop_back();
  short_sim.sim.pop_back();
  short_sim.sim.pop_back();
  EXPECT_THROW(env->restore_state(short_sim), Error);
  EnvState bad_seed = s;
  bad_seed.sim.back() = 0.5;
  EXPECT_THROW(env->restore_state(bad_seed), Error);
  EnvState no_task = s;
  no_task.wrapped.clear();
  EXPECT_THROW(env->restore_state(no_task), Error);
}

}  // namespace
}  // namespace hlt::robot
