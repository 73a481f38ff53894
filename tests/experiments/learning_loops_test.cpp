// End-to-end tests of hlt_train's outer loops: the online methods log exactly what the code before the
// learner interface logged (reference logs in tests/data/train_reference/), an old checkpoint still
// resumes, and the imitation methods (paper Alg. 3) run, log their tags and resume exactly.
#include <gtest/gtest.h>
#include <signal.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include <fmt/format.h>

#include "agents/saved_policy.h"
#include "envs/registry.h"
#include "experiments/cli_support.h"
#include "hlt/simd/vector_math.h"
#include "hlt/util/blas_kernel.h"
#include "hlt/util/files.h"
#include "hlt/util/scalar_logger.h"

namespace hlt {
namespace {
namespace fs = std::filesystem;
using test::comparable_rows;
using test::fresh_dir;
using test::Result;
using test::run;

const std::string kTrain = HLT_TRAIN_BIN;
const fs::path kReference = fs::path(HLT_SOURCE_DIR) / "tests" / "data" / "train_reference";

// The settings the reference logs were recorded with (tests/data/train_reference/README.md).
const std::string kReferenceArgs =
    " --env pendulum --seed 3 train.update_after=64 train.batch_size=32 model.hidden=32 "
    "model.reward_hidden=32"
    " sac.q_hidden=[32,32] planner.samples=8 eval.episodes=1 --no-progress eval.every=100 "
    "checkpoint.every=100";

std::vector<std::string> lines_of(const fs::path& path) {
  std::vector<std::string> lines;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) lines.push_back(line);
  return lines;
}

// The reference logs hold only if this process runs the BLAS kernel they were recorded with (the same seed
// gives the same numbers only with the same kernel).
bool same_kernel_as_reference(std::string& why) {
  const std::vector<std::string> recorded = lines_of(kReference / "kernel.txt");
  const BlasKernel k = blas_kernel();
  const std::vector<std::string> now = {"core " + k.core, "config " + k.config,
                                        std::string("vector ") + vector_isa()};
  why = fmt::format("reference kernel [{}], this process [{}]", fmt::join(recorded, "; "),
                    fmt::join(now, "; "));
  return recorded == now;
}

TEST(LearningLoops, OnlineMethodsLogWhatTheyLoggedBeforeTheLearnerInterface) {
  std::string why;
  if (!same_kernel_as_reference(why)) GTEST_SKIP() << why;
  const std::vector<std::string> methods = {"sac", "hybrid-stochastic", "hybrid-deterministic", "mppi",
                                            "mpc-deterministic"};
  for (const std::string& method : methods) {
    const std::string dir = fresh_dir("reference_" + method);
    const Result r = run(kTrain + kReferenceArgs + " --method " + method + " --steps 400 --out " + dir);
    ASSERT_EQ(r.code, 0) << method << ": " << r.output;
    const std::vector<std::string> expected = lines_of(kReference / (method + ".csv"));
    ASSERT_GT(expected.size(), 60u) << method;
    EXPECT_EQ(comparable_rows(dir + "/scalars.csv"), expected) << method;
  }
}

TEST(LearningLoops, CheckpointOfOlderCodeResumes) {
  std::string why;
  if (!same_kernel_as_reference(why)) GTEST_SKIP() << why;
  // hybrid-stochastic stopped at 200 agent steps by older code (its config lacks keys added since): resumed
  // to 400 it must keep the old part of the log as it was and log what record.sh recorded for the rest.
  const std::string dir = fresh_dir("old_checkpoint");
  fs::create_directories(dir);
  for (const char* f : {"config.yaml", "checkpoint.pt", "scalars.csv"})
    fs::copy_file(kReference / "old_checkpoint" / f, fs::path(dir) / f);
  const Result r = run(kTrain + " --resume " + dir + " --steps 400 --no-progress");
  ASSERT_EQ(r.code, 0) << r.output;
  const std::vector<std::string> rows = comparable_rows(dir + "/scalars.csv");
  const std::vector<std::string> old_rows =
      comparable_rows((kReference / "old_checkpoint" / "scalars.csv").string());
  ASSERT_GT(old_rows.size(), 20u);
  ASSERT_GT(rows.size(), old_rows.size());
  EXPECT_EQ(std::vector<std::string>(rows.begin(), rows.begin() + old_rows.size()), old_rows);
  EXPECT_EQ(rows, lines_of(kReference / "old_checkpoint_resumed.csv"));
}

// A linear demonstrator for the pendulum in the expert-file format (one layer, no ReLU): a = -sin(theta)
// - 0.5 thetadot, a crude swing-damping rule; all the tests need is a deterministic, non-trivial expert.
std::string write_pendulum_expert(const std::string& dir) {
  const std::string path = dir + "/pendulum_expert.txt";
  fs::create_directories(dir);
  std::ofstream(path) << "linear_w 3 1\n0\n-1\n-0.5\nlinear_b 1 1\n0\n";
  return path;
}

std::string imitation_args(const std::string& method, const std::string& expert) {
  return " --env pendulum --seed 1 --method " + method + " imitation.expert=expert:" + expert +
         " imitation.iterations=3 imitation.demo_steps=30 imitation.test_steps=30 imitation.policy_updates=20"
         " imitation.model_updates=20 train.batch_size=32 train.frame_skip=4 model.hidden=32"
         " model.reward_hidden=32 planner.samples=8 policy.hidden=[32,16] --no-progress";
}

// tag -> values in log order
std::map<std::string, std::vector<double>> by_tag(const std::string& path) {
  std::map<std::string, std::vector<double>> out;
  for (const auto& row : ScalarLogger::read(path))
    out[row.tag].push_back(row.value);
  return out;
}

TEST(LearningLoops, HybridImitationLogsItsTagsAndResumesExactly) {
  const std::string dir = fresh_dir("imitation_straight");
  const std::string expert = write_pendulum_expert(fresh_dir("imitation_expert"));
  const std::string args = imitation_args("hybrid-imitation", expert);
  Result r = run(kTrain + args + " --out " + dir);
  ASSERT_EQ(r.code, 0) << r.output;
  // The closing summary counts the budget's unit: iterations (3 test episodes of 30 agent steps).
  EXPECT_NE(r.output.find("done: 3 iterations (3 demonstrations; 90 agent steps"), std::string::npos)
      << r.output;
  const auto tags = by_tag(dir + "/scalars.csv");
  EXPECT_EQ(tags.at("imitation/demonstrations"), (std::vector<double>{1, 2, 3}));
  for (const char* tag :
       {"imitation/test_return", "imitation/policy_return", "imitation/expert_return",
        "imitation/demonstration_return", "imitation/fallbacks", "loss/bc", "loss/dynamics", "loss/reward",
        "time/iteration_seconds", "imitation/model_error_ratio", "imitation/model_better_components"}) {
    ASSERT_TRUE(tags.count(tag)) << tag;
    EXPECT_EQ(tags.at(tag).size(), 3u) << tag;
  }
  // The dynamics model scored on each test episode before it trains on it: a finite, positive ratio, and a
  // count of the pendulum's three components.
  for (double r : tags.at("imitation/model_error_ratio")) {
    EXPECT_TRUE(std::isfinite(r));
    EXPECT_GT(r, 0.0);
  }
  for (double b : tags.at("imitation/model_better_components")) {
    EXPECT_GE(b, 0.0);
    EXPECT_LE(b, 3.0);
  }
  for (double f : tags.at("imitation/fallbacks"))
    EXPECT_LE(f, 30.0);                                // steps of the 30-step test episode only
  EXPECT_FALSE(tags.count("loss/critic"));             // no SAC in imitation
  EXPECT_FALSE(tags.count("imitation/test_success"));  // the pendulum has no success criterion
  // The planner's weight diagnostics of each test episode: an effective sample size in [1, K].
  ASSERT_TRUE(tags.count("imitation/weight_ess"));
  ASSERT_TRUE(tags.count("imitation/saturated_weight"));
  EXPECT_EQ(tags.at("imitation/weight_ess").size(), 3u);
  for (double ess : tags.at("imitation/weight_ess")) {
    EXPECT_GE(ess, 1.0 - 1e-9);
    EXPECT_LE(ess, 20.0 + 1e-9);  // K = 20 on the pendulum (experiments/configs/pendulum.yaml)
  }
  // The test episode acts with the hybrid, not the policy alone: the two returns differ.
  EXPECT_NE(tags.at("imitation/test_return"), tags.at("imitation/policy_return"));
  EXPECT_TRUE(fs::exists(dir + "/final.pt"));

  // Killed while writing its second checkpoint (after iteration 2 was logged), then resumed: the same log.
  const std::string killed = fresh_dir("imitation_killed");
  r = run("HLT_TEST_KILL_WRITING=checkpoint.pt:2 " + kTrain + args + " --out " + killed);
  EXPECT_EQ(r.code, 128 + SIGKILL) << r.output;
  EXPECT_LT(comparable_rows(killed + "/scalars.csv").size(), comparable_rows(dir + "/scalars.csv").size());
  r = run(kTrain + " --resume " + killed + " --no-progress");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(comparable_rows(killed + "/scalars.csv"), comparable_rows(dir + "/scalars.csv"));
  // --steps counts iterations for an imitation method: resumed with --steps 4, the run adds a fourth
  // demonstration.
  r = run(kTrain + " --resume " + killed + " --steps 4 --no-progress");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(by_tag(killed + "/scalars.csv").at("imitation/demonstrations"),
            (std::vector<double>{1, 2, 3, 4}));
}

// imitation.restart_model_optimizer: the first iteration's updates start from a fresh optimizer either way,
// so its numbers are the same; from the second on the models' updates differ (their optimizer forgot the
// first iteration's moments), and a run stopped after two iterations and resumed repeats the straight one.
TEST(LearningLoops, RestartingTheModelOptimizerChangesOnlyLaterIterationsAndResumesExactly) {
  const std::string expert = write_pendulum_expert(fresh_dir("restart_expert"));
  const std::string plain = fresh_dir("restart_off"), restarted = fresh_dir("restart_on"),
                    resumed = fresh_dir("restart_resumed");
  const std::string args = imitation_args("hybrid-imitation", expert);
  ASSERT_EQ(run(kTrain + args + " --out " + plain).code, 0);
  ASSERT_EQ(run(kTrain + args + " imitation.restart_model_optimizer=true --out " + restarted).code, 0);
  const auto off = by_tag(plain + "/scalars.csv"), on = by_tag(restarted + "/scalars.csv");
  ASSERT_EQ(on.at("loss/dynamics").size(), 3u);
  EXPECT_EQ(on.at("loss/dynamics")[0], off.at("loss/dynamics")[0]);
  EXPECT_NE(on.at("loss/dynamics")[1], off.at("loss/dynamics")[1]);
  EXPECT_NE(on.at("loss/dynamics")[2], off.at("loss/dynamics")[2]);
  Result r = run(kTrain + args + " imitation.restart_model_optimizer=true --steps 2 --out " + resumed);
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(kTrain + " --resume " + resumed + " --steps 3 --no-progress");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(test::comparable_rows(resumed + "/scalars.csv"),
            test::comparable_rows(restarted + "/scalars.csv"));
}

// imitation.demo_noise: the demonstrator's executed actions vary (every demonstration's return changes), the
// noise is seeded per iteration (a run stopped after two iterations and resumed repeats the straight one),
// and with intended labels behaviour cloning learns from the noiseless actions (its loss differs from that
// of the executed ones).
TEST(LearningLoops, DemonstratorNoiseChangesTheDemonstrationsAndResumesExactly) {
  const std::string expert = write_pendulum_expert(fresh_dir("noise_expert"));
  const std::string plain = fresh_dir("noise_off"), noisy = fresh_dir("noise_on"),
                    resumed = fresh_dir("noise_resumed"), intended = fresh_dir("noise_intended");
  const std::string args = imitation_args("bc", expert);
  ASSERT_EQ(run(kTrain + args + " --out " + plain).code, 0);
  ASSERT_EQ(run(kTrain + args + " imitation.demo_noise=0.3 --out " + noisy).code, 0);
  const auto off = by_tag(plain + "/scalars.csv"), on = by_tag(noisy + "/scalars.csv");
  ASSERT_EQ(on.at("imitation/demonstration_return").size(), 3u);
  for (size_t i = 0; i < 3; ++i)
    EXPECT_NE(on.at("imitation/demonstration_return")[i], off.at("imitation/demonstration_return")[i]) << i;
  Result r = run(kTrain + args + " imitation.demo_noise=0.3 --steps 2 --out " + resumed);
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(kTrain + " --resume " + resumed + " --steps 3 --no-progress");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(test::comparable_rows(resumed + "/scalars.csv"), test::comparable_rows(noisy + "/scalars.csv"));
  ASSERT_EQ(
      run(kTrain + args + " imitation.demo_noise=0.3 imitation.intended_labels=true --out " + intended).code,
      0);
  const auto labelled = by_tag(intended + "/scalars.csv");
  EXPECT_EQ(labelled.at("imitation/demonstration_return"), on.at("imitation/demonstration_return"));
  EXPECT_NE(labelled.at("loss/bc"), on.at("loss/bc"));
}

TEST(LearningLoops, ImitationEvalVariantsChangeNoOtherNumber) {
  const std::string expert = write_pendulum_expert(fresh_dir("imitation_expert3"));
  const std::string args =
      imitation_args("hybrid-imitation", expert) + " imitation.iterations=2" + " imitation.eval_episodes=2";
  const std::string plain = fresh_dir("imitation_no_variants"), varied = fresh_dir("imitation_variants");
  Result r = run(kTrain + args + " --out " + plain);
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(kTrain + args + " \"eval.variants=planner.lambda=1000; planner.horizon=2\" --out " + varied);
  ASSERT_EQ(r.code, 0) << r.output;
  std::vector<std::string> others;
  std::map<std::string, std::vector<double>> variant;
  for (const auto& row : ScalarLogger::read(varied + "/scalars.csv")) {
    if (row.tag.rfind("imitation/variant", 0) == 0)
      variant[row.tag].push_back(row.value);
    else if (row.tag.rfind("time/", 0) != 0)
      others.push_back(fmt::format("{},{},{:.17g}", row.step, row.tag, row.value));
  }
  EXPECT_EQ(others, comparable_rows(plain + "/scalars.csv"));
  const auto tags = by_tag(plain + "/scalars.csv");
  ASSERT_EQ(tags.at("imitation/eval_return_mean").size(), 2u);
  for (const char* tag : {"imitation/variant0_return_mean", "imitation/variant0_return_std",
                          "imitation/variant1_return_mean", "imitation/variant1_return_std"}) {
    ASSERT_TRUE(variant.count(tag)) << tag;
    EXPECT_EQ(variant.at(tag).size(), 2u) << tag;
  }
  EXPECT_EQ(variant.size(), 4u);  // the pendulum has no success criterion
  // A 2-step horizon plans differently from the default on the same networks.
  EXPECT_NE(variant.at("imitation/variant1_return_mean"), tags.at("imitation/eval_return_mean"));
}

TEST(LearningLoops, RobotTasksLogTheirSuccess) {
  // Online: every training episode's verdict (0 or 1) and each evaluation's rate.
  const std::string push = fresh_dir("success_push");
  Result r = run(kTrain + " --env block_push --method sac --seed 0 --steps 200 --out " + push +
                 " eval.every=200 eval.episodes=2 train.update_after=1000 --no-progress");
  ASSERT_EQ(r.code, 0) << r.output;
  auto tags = by_tag(push + "/scalars.csv");
  ASSERT_EQ(tags.at("train/success").size(), 2u);  // two 100-step episodes
  for (double v : tags.at("train/success"))
    EXPECT_TRUE(v == 0.0 || v == 1.0) << v;
  ASSERT_EQ(tags.at("eval/success_rate").size(), 2u);  // at step 0 and at the end
  for (double v : tags.at("eval/success_rate"))
    EXPECT_TRUE(v == 0.0 || v == 0.5 || v == 1.0) << v;

  // Imitation: the test episode's, the policy's and the expert's verdicts, and the rate over the extra
  // test episodes. The scripted stacking expert succeeds on most starts.
  const std::string stack = fresh_dir("success_stack");
  r = run(kTrain + " --env block_stack --method bc --seed 0 --steps 2 --out " + stack +
          " imitation.expert=scripted:block_stack imitation.policy_updates=10 imitation.eval_episodes=2"
          " --no-progress");
  ASSERT_EQ(r.code, 0) << r.output;
  tags = by_tag(stack + "/scalars.csv");
  for (const char* tag : {"imitation/test_success", "imitation/policy_success", "imitation/expert_success",
                          "imitation/eval_success_rate", "imitation/eval_return_mean"}) {
    ASSERT_TRUE(tags.count(tag)) << tag;
    EXPECT_EQ(tags.at(tag).size(), 2u) << tag;
  }
  EXPECT_GE(tags.at("imitation/expert_success")[0] + tags.at("imitation/expert_success")[1], 1.0);
  // block_stack.yaml has the policy see its inputs normalised: the checkpoint carries the environment's
  // declared ranges and references, so hlt_rollout rebuilds the same function.
  const SavedPolicy saved = load_saved_policy(stack + "/final.pt");
  const std::optional<ObservationScale> declared = make_env("block_stack")->observation_scale();
  ASSERT_TRUE(declared.has_value());
  const auto as_vector = [](const auto& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
  EXPECT_EQ(saved.options.input_offset, as_vector(declared->offset));
  EXPECT_EQ(saved.options.input_scale, as_vector(declared->scale));
  EXPECT_EQ(saved.options.input_reference,
            std::vector<int64_t>(declared->reference.data(),
                                 declared->reference.data() + declared->reference.size()));
  EXPECT_FALSE(saved.options.input_reference.empty());
}

TEST(LearningLoops, BehaviourCloningAndTheDeterministicVariantRun) {
  const std::string expert = write_pendulum_expert(fresh_dir("imitation_expert2"));
  const std::string bc = fresh_dir("imitation_bc");
  Result r = run(kTrain + imitation_args("bc", expert) + " --out " + bc);
  ASSERT_EQ(r.code, 0) << r.output;
  auto tags = by_tag(bc + "/scalars.csv");
  EXPECT_EQ(tags.at("imitation/demonstrations").size(), 3u);
  EXPECT_EQ(tags.at("loss/bc").size(), 3u);
  EXPECT_FALSE(tags.count("loss/dynamics"));         // behaviour cloning alone trains no models
  EXPECT_FALSE(tags.count("imitation/weight_ess"));  // and has no planner
  // Its test episode is the policy alone.
  EXPECT_EQ(tags.at("imitation/test_return"), tags.at("imitation/policy_return"));
  // More demonstrations fit the expert better on the data seen: the BC loss of the last iteration is below
  // the first's.
  EXPECT_LT(tags.at("loss/bc").back(), tags.at("loss/bc").front());

  const std::string det = fresh_dir("imitation_det");
  r = run(kTrain + imitation_args("hybrid-imitation-deterministic", expert) +
          " imitation.iterations=2 --out " + det);
  ASSERT_EQ(r.code, 0) << r.output;
  tags = by_tag(det + "/scalars.csv");
  EXPECT_EQ(tags.at("imitation/test_return").size(), 2u);
  EXPECT_EQ(tags.at("loss/dynamics").size(), 2u);

  // Without a demonstrator the run stops with a message naming the key.
  r = run(kTrain + " --env pendulum --method bc --no-progress --out " + fresh_dir("imitation_none"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("imitation.expert"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace hlt
