// hlt_rollout: runs a registered environment with a simple or saved policy for N episodes and reports the
// returns; optionally writes the trajectory as CSV and the frames as a video or an image strip, and for a
// camera-observed task reports the estimator's error against the simulator and the time per control step.
//
//   hlt_rollout --env cartpole_swingup --episodes 10 --seed 0
//               --policy zero|random|constant:0.5|checkpoint:PATH|expert:PATH|scripted:NAME|oracle:H,K
//               [--frame-skip K] [--csv traj.csv] [--video out.mp4] [--strip out.png] [--demos out.hltd]
//               [--perception] [--models CHECKPOINT --predictions pred.csv]
//               [--controller stochastic_hybrid [--plan-on learned|simulator|simulator-dynamics]
//               [--plan-check N]
//               [key=value ...]]
//               (with checkpoint:PATH)
#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <torch/torch.h>
#include <unistd.h>
#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "agents/controller_policy.h"
#include "agents/demonstrations.h"
#include "agents/model_check.h"
#include "agents/plan_check.h"
#include "agents/policy_spec.h"
#include "agents/saved_policy.h"
#include "agents/simulator_model.h"
#include "envs/env.h"
#include "envs/registry.h"
#include "envs/rollout.h"
#include "experiments/cli_checks.h"
#include "experiments/perception_report.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"
#include "hlt/util/main_guard.h"
#include "hlt/util/random.h"

namespace hlt {
namespace {

constexpr const char* kCheckpointPrefix = "checkpoint:";

bool is_checkpoint(const std::string& spec) {
  return spec.rfind(kCheckpointPrefix, 0) == 0;
}

// A policy named on the command line by the flag `what`: an expert's weights ("expert:PATH"), the mean action
// of a policy trained by hlt_train ("checkpoint:PATH", loaded into `saved` here unless the caller already
// did, e.g. to read its frame skip first), or a simple or scripted one.
std::unique_ptr<PolicySource> make_policy(const std::string& spec, std::optional<SavedPolicy>& saved,
                                          const Env& env, uint64_t seed, const std::string& what) {
  if (!saved && is_checkpoint(spec))
    saved = load_saved_policy(spec.substr(std::string(kCheckpointPrefix).size()));
  if (saved) {
    check(saved->env == env.name(), "{} {}: the policy was trained on {}, not {}", what, spec, saved->env,
          env.name());
    return std::move(saved->source);
  }
  return make_fixed_policy(spec, env, seed, what);
}

std::string extension(const std::string& path) {
  const auto dot = path.find_last_of('.');
  const auto slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

std::string replace_extension(const std::string& path, const std::string& ext) {
  const std::string old = extension(path);
  return (old.empty() ? path : path.substr(0, path.size() - old.size() - 1)) + "." + ext;
}

// Up to `count` frames evenly spread over `frames`, side by side, in rows of at most 8.
cv::Mat image_strip(const std::vector<cv::Mat>& frames, int count) {
  check(!frames.empty(), "no frames were rendered");
  count = std::max(1, std::min<int>(count, static_cast<int>(frames.size())));
  std::vector<cv::Mat> picked;
  for (int i = 0; i < count; ++i) {
    const size_t idx = count == 1 ? 0 : i * (frames.size() - 1) / (count - 1);
    picked.push_back(frames[idx]);
  }
  const int per_row = std::min(count, 8);
  std::vector<cv::Mat> rows;
  for (int start = 0; start < count; start += per_row) {
    std::vector<cv::Mat> row(picked.begin() + start, picked.begin() + std::min(count, start + per_row));
    while (static_cast<int>(row.size()) < per_row)
      row.push_back(cv::Mat(picked[0].size(), picked[0].type(), 255.0));
    cv::Mat joined;
    cv::hconcat(row, joined);
    rows.push_back(joined);
  }
  cv::Mat out;
  cv::vconcat(rows, out);
  return out;
}

void write_png(const std::string& path, const cv::Mat& image) {
  write_atomic_with(path, [&](const std::string& tmp) {
    // cv::imwrite picks the format from the name, so the temporary name must keep the extension.
    const std::string named = tmp + ".png";
    check(cv::imwrite(named, image), "could not write the image {}", path);
    check(std::rename(named.c_str(), tmp.c_str()) == 0, "could not write the image {}", path);
  });
}

// Recorded frames, streamed: each goes to the video encoder as it is rendered (the file is written under a
// temporary name and renamed when complete), and only a bounded, evenly spaced subset is kept for the image
// strip (every stride-th frame, the stride doubling whenever 4 x strip_frames are held), so memory does not
// grow with the number or length of the episodes.
class FrameRecorder {
 public:
  FrameRecorder(std::string video, double fps, int strip_frames)
      : video_(std::move(video)), fps_(fps), keep_(4 * static_cast<size_t>(strip_frames)) {}

  void add(const cv::Mat& frame) {
    if (!video_.empty() && !writer_failed_) {
      if (!writer_.isOpened()) open(frame.size());
      if (writer_.isOpened()) writer_.write(frame);
    }
    if (count_ % stride_ == 0) kept_.push_back(frame.clone());
    ++count_;
    if (kept_.size() >= keep_) {
      std::vector<cv::Mat> half;
      for (size_t i = 0; i < kept_.size(); i += 2)
        half.push_back(kept_[i]);
      kept_.swap(half);
      stride_ *= 2;
    }
  }
  size_t frames() const { return count_; }
  // Closes the video; false if OpenCV had no encoder for its container (nothing is left behind then).
  bool finish_video() {
    if (writer_failed_ || !writer_.isOpened()) return false;
    writer_.release();
    check(std::rename(tmp_.c_str(), video_.c_str()) == 0, "could not write the video {}: {}", video_,
          std::strerror(errno));
    return true;
  }
  const std::vector<cv::Mat>& strip_frames() const { return kept_; }

 private:
  void open(cv::Size size) {
    const std::string ext = extension(video_);
    const int fourcc = ext == "mp4" ? cv::VideoWriter::fourcc('m', 'p', '4', 'v')
                                    : cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
    // OpenCV picks the container from the name, so the temporary name keeps the extension.
    tmp_ = fmt::format("{}.tmp.{}.{}", video_, static_cast<long>(::getpid()), ext);
    writer_.open(tmp_, fourcc, fps_, size);
    if (!writer_.isOpened()) {
      writer_failed_ = true;
      std::remove(tmp_.c_str());
    }
  }
  std::string video_, tmp_;
  double fps_;
  size_t keep_, count_ = 0, stride_ = 1;
  bool writer_failed_ = false;
  cv::VideoWriter writer_;
  std::vector<cv::Mat> kept_;
};

struct Options {
  std::string env;
  std::string policy = "zero";
  int episodes = 1;
  uint64_t seed = 0;
  int frame_skip = 1;
  std::string csv;
  std::string video;
  std::string strip;
  int strip_frames = 8;
  int record_episodes = 1;
  int width = 480;
  int height = 360;
  std::string demos;        // record every episode as demonstrations (.hltd)
  int max_steps = 0;        // cut episodes after this many steps (0: the environment's limit)
  bool perception = false;  // report the camera-observed task's estimator error and step timings
  std::string models;       // a checkpoint whose dynamics and reward models predict every step
  std::string predictions;  // where their predictions go (CSV)
  std::string controller;   // act with this controller of the checkpoint's run instead of its policy's mean
  // The stochastic planners' model with --controller: the run's learned models or the simulator.
  std::string plan_on = "learned";
  std::vector<std::string> overrides;  // key=value changes to the run's config with --controller
  int plan_check = 0;   // replay the planner's samples on the simulator at every N-th step (0: never)
  std::string compare;  // a reference policy asked at every step, on the visited states, without acting
};

// How far the acting policy's actions are from a reference policy's on the states the acting policy visits:
// imitation's error where it matters (behaviour cloning is fitted on the expert's states; its test runs on
// its own, and the difference between the two errors is the covariate shift).
class ActionComparison {
 public:
  ActionComparison(std::unique_ptr<PolicySource> reference, int action_dim)
      : reference_(std::move(reference)), abs_sum_(Eigen::VectorXd::Zero(action_dim)) {}
  void add(const Transition& t) {
    const Eigen::VectorXd ref = reference_->act(t.observation);
    check(ref.size() == t.action.size(), "--compare: the reference gives {} action components, not {}",
          ref.size(), t.action.size());
    const Eigen::VectorXd diff = t.action - ref;
    abs_sum_ += diff.cwiseAbs();
    square_sum_ += diff.squaredNorm();
    for (Eigen::Index i = 0; i < diff.size(); ++i)
      if (t.action[i] * ref[i] < 0.0) ++opposite_;
    ++steps_;
  }
  void print() const {
    if (steps_ == 0) return;
    const double n = static_cast<double>(steps_) * abs_sum_.size();
    fmt::print(
        "actions against {} over {} steps: mean |a - a_ref| {:.4f}, rms {:.4f}, opposite sign in {:.1f} % of "
        "components\n  mean |a - a_ref| per component {:.3f}\n",
        reference_->describe(), steps_, abs_sum_.sum() / n, std::sqrt(square_sum_ / n), 100.0 * opposite_ / n,
        fmt::join(per_component(), " "));
  }

 private:
  std::vector<double> per_component() const {
    std::vector<double> out(abs_sum_.size());
    for (Eigen::Index i = 0; i < abs_sum_.size(); ++i)
      out[i] = abs_sum_[i] / static_cast<double>(steps_);
    return out;
  }
  std::unique_ptr<PolicySource> reference_;
  Eigen::VectorXd abs_sum_;
  double square_sum_ = 0.0;
  int64_t opposite_ = 0, steps_ = 0;
};

// The acting policy, and after every `every`-th of its planning calls (before the environment steps) the
// planner's samples compared with their replay on the simulator.
class PlanCheckingPolicy : public PolicySource {
 public:
  PlanCheckingPolicy(std::unique_ptr<PolicySource> inner, const StochasticHybrid& planner, PlanCheck& check,
                     int every)
      : inner_(std::move(inner)), planner_(planner), check_(check), every_(every) {}
  std::string describe() const override { return inner_->describe(); }
  Eigen::VectorXd act(const Eigen::VectorXd& observation) override {
    Eigen::VectorXd action = inner_->act(observation);
    if (calls_++ % every_ == 0) check_.add(planner_);
    return action;
  }

 private:
  std::unique_ptr<PolicySource> inner_;
  const StochasticHybrid& planner_;
  PlanCheck& check_;
  int every_;
  int64_t calls_ = 0;
};

// The learned models' one-step predictions next to what the environment did: per step the observation's
// next value and the reward, predicted from the step's observation and action (a reward model of the next
// state reads the predicted one, as the planner does).
class PredictionCsv {
 public:
  PredictionCsv(SavedModels models, int observation_dim) : models_(std::move(models)) {
    text_ = "episode,step";
    for (int i = 0; i < observation_dim; ++i)
      text_ += fmt::format(",pred_obs_{}", i);
    text_ += ",pred_reward\n";
  }
  void add(int episode, const Transition& t) {
    torch::InferenceMode guard;
    const at::Tensor s = observation_tensor(t.observation).unsqueeze(0);
    const at::Tensor a = observation_tensor(t.action).unsqueeze(0);
    const at::Tensor predicted = models_.dynamics->forward(s, a);
    const Eigen::VectorXd next = action_vector(predicted);
    const double r = models_.reward->predict(s, a, predicted).item<double>();
    text_ += fmt::format("{},{}", episode, t.step);
    for (Eigen::Index i = 0; i < next.size(); ++i)
      text_ += fmt::format(",{:.17g}", next[i]);
    text_ += fmt::format(",{:.17g}\n", r);
    if (t.result.failure.empty()) check_.add(t.observation, t.action, t.result.observation);
  }
  const std::string& text() const { return text_; }
  // The dynamics model's one-step errors over the rollout against predicting "no change".
  void print_check(const Env& env) {
    if (check_.size() == 0) return;
    const ModelScore m = check_.score(*models_.dynamics, env);
    fmt::print(
        "dynamics model over {} steps: error / 'no change' {:.3f} (pooled, each component in its unit), "
        "better than 'no change' in {} of {} components\n  rms error  {:.4g}\n  rms change {:.4g}\n",
        m.transitions, m.error_ratio, m.better, m.error_rms.size(), fmt::join(m.error_rms, " "),
        fmt::join(m.change_rms, " "));
  }

 private:
  SavedModels models_;
  std::string text_;
  ModelCheck check_;
};

int run(Options o, bool frame_skip_given) {
  std::optional<SavedPolicy> saved;
  if (is_checkpoint(o.policy)) {
    saved = load_saved_policy(o.policy.substr(std::string(kCheckpointPrefix).size()));
    // Act at the rate the policy was trained at unless told otherwise.
    if (!frame_skip_given) o.frame_skip = saved->frame_skip;
  }
  std::optional<SavedModels> models;
  check(o.models.empty() == o.predictions.empty(), "--models and --predictions go together");
  if (!o.models.empty()) {
    models = load_saved_models(o.models);
    check(models->env == o.env, "--models {}: its models were trained on {}, not {}", o.models, models->env,
          o.env);
    // The models predict one step of their run's frame skip.
    check(!frame_skip_given || o.frame_skip == models->frame_skip,
          "--models {} predicts steps of frame skip {}, not {}", o.models, models->frame_skip, o.frame_skip);
    check(!saved || saved->frame_skip == models->frame_skip,
          "--policy and --models were trained with frame skips {} and {}", saved->frame_skip,
          models->frame_skip);
    o.frame_skip = models->frame_skip;
  }
  std::unique_ptr<Env> env = make_env(o.env);
  if (o.frame_skip != 1) env = std::make_unique<FrameSkip>(std::move(env), o.frame_skip);
  check(o.episodes >= 1, "--episodes must be at least 1, got {}", o.episodes);
  check(o.width >= 16 && o.height >= 16, "--width and --height must be at least 16");
  // The policy's randomness is its own stream, so changing the policy never changes the environment's starts.
  std::unique_ptr<PolicySource> policy =
      make_policy(o.policy, saved, *env, derive_seed(o.seed, 1), "--policy");
  check(o.plan_on == "learned" || o.plan_on == "simulator" || o.plan_on == "simulator-dynamics",
        "--plan-on: 'learned', 'simulator' or 'simulator-dynamics', not '{}'", o.plan_on);
  check(o.controller.empty() || saved,
        "--controller acts with a trained run's networks: give --policy checkpoint:PATH");
  check(
      o.overrides.empty() || !o.controller.empty(),
      "key=value overrides change the run's config for --controller; without it there is nothing to change");
  check(o.plan_on == "learned" || o.controller == "stochastic_hybrid" || o.controller == "mppi",
        "--plan-on {}: only the stochastic planners (--controller stochastic_hybrid or mppi) plan on the "
        "simulator",
        o.plan_on);
  check(o.plan_check >= 0, "--plan-check must be >= 0, got {}", o.plan_check);
  check(o.plan_check == 0 || o.controller == "stochastic_hybrid" || o.controller == "mppi",
        "--plan-check compares a stochastic planner's samples with the simulator: give --controller "
        "stochastic_hybrid or mppi");
  std::unique_ptr<Controller> controller;
  std::optional<PlanCheck> plan_check;
  if (!o.controller.empty()) {
    std::shared_ptr<RolloutModel> plan_on;
    const std::string path = o.policy.substr(std::string(kCheckpointPrefix).size());
    // The run's own reward model, read once: it scores the simulator's transitions for simulator-dynamics
    // and the replayed samples for the plan check.
    RewardModel run_reward = nullptr;
    if (o.plan_on == "simulator-dynamics" || o.plan_check > 0) run_reward = load_saved_models(path).reward;
    if (o.plan_on == "simulator") plan_on = std::make_shared<SimulatorRolloutModel>(*env, at::kFloat);
    if (o.plan_on == "simulator-dynamics")
      plan_on = std::make_shared<SimulatorRolloutModel>(*env, at::kFloat, run_reward);
    SavedController c = load_saved_controller(path, o.controller, plan_on, o.overrides);
    controller = std::move(c.controller);
    // The planner's samples come from LibTorch's generator: its own stream, as the policy's.
    torch::manual_seed(derive_seed(o.seed, 2));
    policy = std::make_unique<ControllerPolicy>(*controller);
    if (o.plan_check > 0) {
      const auto* planner = dynamic_cast<const StochasticHybrid*>(controller.get());
      check(planner != nullptr, "--plan-check: the run's {} controller is not a stochastic planner",
            o.controller);
      plan_check.emplace(*env, run_reward);
      policy = std::make_unique<PlanCheckingPolicy>(std::move(policy), *planner, *plan_check, o.plan_check);
    }
    const char* model = o.plan_on == "simulator" ? "a copy of the simulator (a perfect model)"
                        : o.plan_on == "simulator-dynamics"
                            ? "a copy of the simulator scored by its learned reward"
                            : "its learned models";
    fmt::print("acting with the run's {} controller, planning on {}\n", o.controller, model);
  }
  // Output names are checked before any work is done.
  if (!o.video.empty()) {
    const std::string ext = extension(o.video);
    check(ext == "mp4" || ext == "avi", "--video {}: use a .mp4 or .avi file name (or --strip for a PNG)",
          o.video);
  }
  check(o.strip.empty() || extension(o.strip) == "png", "--strip {}: use a .png file name", o.strip);
  check(o.strip_frames >= 1 && o.record_episodes >= 0,
        "--strip-frames must be >= 1 and --record-episodes >= 0");
  std::optional<PredictionCsv> predictions;
  if (models) predictions.emplace(std::move(*models), env->observation_dim());
  std::optional<ActionComparison> comparison;
  if (!o.compare.empty()) {
    std::optional<SavedPolicy> reference;
    comparison.emplace(make_policy(o.compare, reference, *env, derive_seed(o.seed, 3), "--compare"),
                       env->action_dim());
  }
  for (const std::string* out : {&o.csv, &o.video, &o.strip, &o.demos, &o.predictions}) {
    const auto slash = out->find_last_of('/');
    if (!out->empty() && slash != std::string::npos && slash > 0)
      ensure_writable_directory(out->substr(0, slash));
  }
  const bool recording = (!o.video.empty() || !o.strip.empty()) && o.record_episodes > 0;
  std::optional<PerceptionReport> perception;
  if (o.perception) {
    const robot::CameraObserved* camera = camera_task(*env);
    check(camera != nullptr,
          "--perception needs a camera-observed environment (block_push_camera, "
          "block_stack_camera), not {}",
          o.env);
    perception.emplace(*camera);
  }
  fmt::print("env {} (observation {}, action {}, limit {} steps{}), policy {}, seed {}\n", o.env,
             env->observation_dim(), env->action_dim(), env->max_episode_steps(),
             o.frame_skip != 1 ? fmt::format(", frame skip {}", o.frame_skip) : "", policy->describe(),
             o.seed);

  TrajectoryCsv csv(env->observation_dim(), env->action_dim());
  check(o.max_steps >= 0, "--max-steps must be >= 0, got {}", o.max_steps);
  std::optional<Demonstrations> demos;
  if (!o.demos.empty())
    demos.emplace(o.env, env->observation_dim(), env->action_dim(), o.frame_skip, policy->describe());
  const double fps = std::max(1.0, std::round(1.0 / env->dt()));
  FrameRecorder recorder(o.video, fps, o.strip_frames);
  std::vector<EpisodeStats> episodes;
  for (int ep = 0; ep < o.episodes; ++ep) {
    const bool record = recording && ep < o.record_episodes;
    std::vector<DemoStep> demo_steps;
    auto on_reset = [&]() {
      if (controller) controller->reset();  // each episode starts from an empty plan, as in training
      if (record) recorder.add(env->render(o.width, o.height));
      if (perception) perception->after_reset();
    };
    auto on_step = [&](const Transition& t) {
      // The step's timing is taken before this tool's own work on it (CSV, frames, demonstrations).
      if (perception) perception->after_step();
      if (!o.csv.empty()) csv.add(ep, t);
      if (predictions) predictions->add(ep, t);
      if (comparison) comparison->add(t);
      if (record) recorder.add(env->render(o.width, o.height));
      if (demos)
        demo_steps.push_back({t.observation, t.action, t.result.observation, t.result.reward,
                              t.result.terminated, t.result.truncated});
      if (perception) perception->restart_clock();
    };
    // The first episode starts from the seed; later ones continue the environment's generator.
    const EpisodeStats s =
        run_episode(*env, *policy, ep == 0 ? std::optional<uint64_t>(o.seed) : std::nullopt, on_step,
                    on_reset, o.max_steps);
    if (demos) demos->add_episode(std::move(demo_steps));
    std::string note = s.terminated ? " (terminated)" : "";
    if (!s.failure.empty()) note = " (simulation failed: " + s.failure + ")";
    if (s.success) note += *s.success ? " success" : " no success";
    fmt::print("episode {}: return {:.1f} length {}{}\n", ep, s.episode_return, s.length, note);
    episodes.push_back(s);
  }
  const ReturnSummary sum = summarize(episodes);
  fmt::print("mean return {:.1f} std {:.1f} mean length {:.1f} over {} episodes\n", sum.mean_return,
             sum.std_return, sum.mean_length, episodes.size());
  if (sum.success_rate) {
    const auto succeeded = std::count_if(episodes.begin(), episodes.end(),
                                         [](const EpisodeStats& e) { return e.success.value_or(false); });
    fmt::print("success {} of {} episodes ({:.0f} %)\n", succeeded, episodes.size(), 100 * *sum.success_rate);
  }
  if (perception) perception->print();
  if (predictions) predictions->print_check(*env);
  if (plan_check) fmt::print("{}", plan_check->summary());
  if (comparison) comparison->print();

  if (demos) {
    demos->save(o.demos);
    fmt::print("wrote {} ({} episodes, {} transitions)\n", o.demos, demos->episodes().size(),
               demos->transitions());
  }
  if (!o.csv.empty()) {
    write_file_atomic(o.csv, csv.text());
    fmt::print("wrote {}\n", o.csv);
  }
  if (predictions) {
    write_file_atomic(o.predictions, predictions->text());
    fmt::print("wrote {}\n", o.predictions);
  }
  if (!o.video.empty() && recorder.frames() > 0) {
    if (recorder.finish_video()) {
      fmt::print("wrote {} ({} frames at {} fps)\n", o.video, recorder.frames(), fps);
    } else {
      const std::string fallback = replace_extension(o.video, "png");
      write_png(fallback, image_strip(recorder.strip_frames(), o.strip_frames));
      fmt::print(
          stderr,
          "warning: OpenCV has no encoder for {} here; wrote an image strip of {} frames to {} instead\n",
          o.video, std::min<size_t>(o.strip_frames, recorder.frames()), fallback);
    }
  }
  if (!o.strip.empty() && recorder.frames() > 0) {
    write_png(o.strip, image_strip(recorder.strip_frames(), o.strip_frames));
    fmt::print("wrote {}\n", o.strip);
  }
  return 0;
}

}  // namespace
}  // namespace hlt

int run_tool(int argc, char** argv) {
  hlt::Options o;
  CLI::App app{"Runs a registered environment with a given policy and reports episode returns."};
  bool list = false;
  app.add_flag("--list", list, "List the registered environments and exit");
  app.add_option("--env", o.env, "Environment name (see --list)");
  app.add_option("--policy", o.policy,
                 "zero | random | constant:V[,V2,...] | checkpoint:PATH | expert:PATH | scripted:NAME | "
                 "oracle:H,K[,LAMBDA[,NOISE]] (MPPI on the simulator itself)")
      ->capture_default_str();
  app.add_option("--episodes", o.episodes, "Number of episodes")->capture_default_str();
  app.add_option("--seed", o.seed, "Seed of the first reset (and of the random policy)")
      ->capture_default_str();
  app.add_option("--frame-skip", o.frame_skip, "Repeat each action K simulator steps")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--csv", o.csv,
                 "Write every step (observation, action, reward, done, truncated) to this CSV");
  app.add_option("--video", o.video, "Write the recorded episodes as a video (.mp4 or .avi)");
  app.add_option("--strip", o.strip, "Write evenly spaced frames of the recorded episodes as one PNG");
  app.add_option("--strip-frames", o.strip_frames, "Frames in the image strip")->capture_default_str();
  app.add_option("--record-episodes", o.record_episodes, "How many episodes, from the first, to record")
      ->capture_default_str();
  app.add_option("--demos", o.demos, "Record every episode as demonstrations to this file (.hltd)");
  app.add_option("--max-steps", o.max_steps, "Cut each episode after this many steps (0: the env's limit)")
      ->capture_default_str();
  app.add_option("--width", o.width, "Frame width in pixels")->capture_default_str();
  app.add_flag("--perception", o.perception,
               "Camera-observed tasks: report the estimator's error against the simulator (mean, 95th "
               "percentile, misses) and the time per control step (render, perceive, rest)");
  app.add_option("--height", o.height, "Frame height in pixels")->capture_default_str();
  app.add_option("--models", o.models,
                 "An hlt_train checkpoint whose dynamics and reward models predict every step (with "
                 "--predictions)");
  app.add_option(
      "--predictions", o.predictions,
      "Write the models' one-step predictions (next observation, reward) of every step to this CSV, "
      "row for row with --csv");
  app.add_option(
      "--controller", o.controller,
      "With --policy checkpoint:PATH: act with this controller of the run (e.g. stochastic_hybrid, "
      "built from the run's config and networks) instead of the policy's mean");
  app.add_option("--plan-on", o.plan_on,
                 "With --controller stochastic_hybrid or mppi: plan on the run's 'learned' models, on a "
                 "copy of the 'simulator' (a perfect model and the true reward: what the planner can do "
                 "with better models), or on 'simulator-dynamics' (the simulator's transitions scored by "
                 "the run's learned reward model)")
      ->capture_default_str();
  app.add_option("--plan-check", o.plan_check,
                 "With --controller stochastic_hybrid or mppi: at every N-th step replay the planner's "
                 "samples on a copy of the simulator and report how well its models ranked them (rank "
                 "correlation of predicted and simulated returns, where its choice lands among them)")
      ->capture_default_str();
  app.add_option("--compare", o.compare,
                 "A reference policy (the forms of --policy) asked at every step on the states the acting "
                 "policy visits, without acting: reports how far the actions are from it (e.g. a cloned "
                 "policy against its expert on its own states)");
  app.add_option("overrides", o.overrides,
                 "With --controller: key=value changes to the run's config before the controller is built, "
                 "e.g. planner.lambda=0.1");
  if (const std::optional<int> code = hlt::parse_command_line(app, argc, argv)) return *code;
  hlt::check_finite_flags(app);
  if (list) {
    for (const auto& n : hlt::env_names())
      std::cout << n << "\n";
    return 0;
  }
  hlt::check(!o.env.empty(), "--env is required; known environments: {}", fmt::join(hlt::env_names(), ", "));
  return hlt::run(o, app.count("--frame-skip") > 0);
}

int main(int argc, char** argv) {
  return hlt::guarded_main("hlt_rollout", [&] { return run_tool(argc, argv); });
}
