#include "envs/rollout.h"

#include <cmath>
#include <cstdlib>
#include <sstream>

#include <fmt/format.h>

#include "envs/scripted.h"
#include "hlt/util/error.h"

namespace hlt {

namespace {

const char* const kPolicyForms = "zero, random, constant:V or constant:V1,V2,...";

class ConstantPolicy : public PolicySource {
 public:
  ConstantPolicy(Eigen::VectorXd action, std::string label)
      : action_(std::move(action)), label_(std::move(label)) {}
  std::string describe() const override { return label_; }
  Eigen::VectorXd act(const Eigen::VectorXd&) override { return action_; }

 private:
  Eigen::VectorXd action_;
  std::string label_;
};

class UniformPolicy : public PolicySource {
 public:
  UniformPolicy(int dim, uint64_t seed) : dim_(dim), rng_(seed) {}
  std::string describe() const override { return "uniform random in [-1, 1]"; }
  Eigen::VectorXd act(const Eigen::VectorXd&) override {
    Eigen::VectorXd a(dim_);
    for (int i = 0; i < dim_; ++i)
      a[i] = dist_(rng_);
    return a;
  }

 private:
  int dim_;
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> dist_{-1.0, 1.0};
};

double parse_number(const std::string& text, const std::string& spec) {
  const char* begin = text.c_str();
  char* end = nullptr;
  const double v = std::strtod(begin, &end);
  check(!text.empty() && end == begin + text.size() && std::isfinite(v),
        "policy '{}': '{}' is not a finite number (forms: {})", spec, text, kPolicyForms);
  return v;
}

}  // namespace

std::unique_ptr<PolicySource> make_simple_policy(const std::string& spec, int action_dim, uint64_t seed) {
  check(action_dim > 0, "policy '{}': action size must be positive", spec);
  if (spec == "zero") return std::make_unique<ConstantPolicy>(Eigen::VectorXd::Zero(action_dim), "zero");
  if (spec == "random") return std::make_unique<UniformPolicy>(action_dim, seed);
  const std::string prefix = "constant:";
  if (spec.rfind(prefix, 0) == 0) {
    std::vector<double> values;
    std::stringstream ss(spec.substr(prefix.size()));
    std::string item;
    while (std::getline(ss, item, ','))
      values.push_back(parse_number(item, spec));
    check(!values.empty(), "policy '{}': no value given (forms: {})", spec, kPolicyForms);
    Eigen::VectorXd a(action_dim);
    if (values.size() == 1) {
      a.setConstant(values[0]);
    } else {
      check(static_cast<int>(values.size()) == action_dim, "policy '{}': {} values given, the action has {}",
            spec, values.size(), action_dim);
      for (int i = 0; i < action_dim; ++i)
        a[i] = values[i];
    }
    return std::make_unique<ConstantPolicy>(a, spec);
  }
  throw Error(fmt::format("unknown policy '{}'; accepted: {}", spec, kPolicyForms));
}

std::unique_ptr<PolicySource> make_policy_for(const std::string& spec, const Env& env, uint64_t seed) {
  if (spec.rfind(kScriptedPrefix, 0) == 0)
    return make_scripted_policy(spec.substr(std::string(kScriptedPrefix).size()), env.name(), seed);
  if (spec == "zero" || spec == "random" || spec.rfind("constant:", 0) == 0)
    return make_simple_policy(spec, env.action_dim(), seed);
  throw Error(fmt::format("unknown policy '{}'; accepted: {}, scripted:NAME (known: {})", spec, kPolicyForms,
                          fmt::join(scripted_policy_names(), ", ")));
}

EpisodeStats run_episode(Env& env, PolicySource& policy, std::optional<uint64_t> seed,
                         const std::function<void(const Transition&)>& on_step,
                         const std::function<void()>& on_reset, int max_steps) {
  Eigen::VectorXd obs = env.reset(seed);
  if (on_reset) on_reset();
  EpisodeStats stats;
  for (;;) {
    const Eigen::VectorXd action = policy.act(obs);
    StepResult r = env.step(action);
    if (max_steps > 0 && stats.length + 1 >= max_steps && !r.terminated) r.truncated = true;
    if (on_step) on_step(Transition{stats.length, obs, action, r});
    stats.episode_return += r.reward;
    ++stats.length;
    if (r.done()) {
      stats.terminated = r.terminated;
      stats.truncated = r.truncated;
      stats.failure = r.failure;
      stats.success = env.episode_success();
      return stats;
    }
    obs = r.observation;
  }
}

TrajectoryCsv::TrajectoryCsv(int observation_dim, int action_dim) {
  text_ = "episode,step";
  for (int i = 0; i < observation_dim; ++i)
    text_ += fmt::format(",obs_{}", i);
  for (int i = 0; i < action_dim; ++i)
    text_ += fmt::format(",action_{}", i);
  text_ += ",reward,done,truncated\n";
}

void TrajectoryCsv::add(int episode, const Transition& t) {
  text_ += fmt::format("{},{}", episode, t.step);
  for (Eigen::Index i = 0; i < t.observation.size(); ++i)
    text_ += fmt::format(",{:.17g}", t.observation[i]);
  for (Eigen::Index i = 0; i < t.action.size(); ++i)
    text_ += fmt::format(",{:.17g}", t.action[i]);
  text_ +=
      fmt::format(",{:.17g},{},{}\n", t.result.reward, t.result.done() ? 1 : 0, t.result.truncated ? 1 : 0);
}

ReturnSummary summarize(const std::vector<EpisodeStats>& episodes) {
  ReturnSummary s;
  if (episodes.empty()) return s;
  const double n = static_cast<double>(episodes.size());
  for (const auto& e : episodes) {
    s.mean_return += e.episode_return / n;
    s.mean_length += e.length / n;
  }
  double var = 0;
  for (const auto& e : episodes)
    var += (e.episode_return - s.mean_return) * (e.episode_return - s.mean_return) / n;
  s.std_return = std::sqrt(var);
  int judged = 0, succeeded = 0;
  for (const auto& e : episodes) {
    if (!e.success) continue;
    ++judged;
    succeeded += *e.success ? 1 : 0;
  }
  if (judged > 0) s.success_rate = static_cast<double>(succeeded) / judged;
  return s;
}

}  // namespace hlt
