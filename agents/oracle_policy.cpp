#include "agents/oracle_policy.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "envs/registry.h"
#include "hlt/util/error.h"

namespace hlt {

OracleOptions OraclePolicy::parse(const std::string& spec) {
  std::vector<std::string> parts(1);
  for (char c : spec) {
    if (c == ',')
      parts.emplace_back();
    else
      parts.back() += c;
  }
  const std::string form = "oracle:H,K[,LAMBDA[,NOISE]] (e.g. oracle:10,10,0.01,0.5)";
  check(parts.size() >= 2 && parts.size() <= 4, "policy '{}{}': expected {}", kPrefix, spec, form);
  OracleOptions o;
  try {
    size_t used = 0;
    auto integer = [&](const std::string& s) {
      const int v = std::stoi(s, &used);
      check(used == s.size() && v > 0, "not a positive integer");
      return v;
    };
    auto real = [&](const std::string& s) {
      const double v = std::stod(s, &used);
      check(used == s.size() && std::isfinite(v) && v > 0, "not a positive number");
      return v;
    };
    o.horizon = integer(parts[0]);
    o.samples = integer(parts[1]);
    if (parts.size() > 2) o.lambda = real(parts[2]);
    if (parts.size() > 3) o.noise = real(parts[3]);
  } catch (const std::exception&) {
    throw Error(fmt::format("policy '{}{}': expected {} with positive values", kPrefix, spec, form));
  }
  return o;
}

OraclePolicy::OraclePolicy(const Env& env, const OracleOptions& options, uint64_t seed)
    : env_(env),
      sim_(make_env_like(env)),
      options_(options),
      rng_(seed),
      plan_(Eigen::MatrixXd::Zero(options.horizon, env.action_dim())) {}

std::string OraclePolicy::describe() const {
  return fmt::format("MPPI on the simulator (H {}, K {}, lambda {}, noise {})", options_.horizon,
                     options_.samples, options_.lambda, options_.noise);
}

Eigen::VectorXd OraclePolicy::act(const Eigen::VectorXd& observation) {
  const int H = options_.horizon, K = options_.samples;
  const auto m = static_cast<int>(plan_.cols());
  check(observation.size() == env_.observation_dim(), "oracle: observation of size {}, {} has {}",
        observation.size(), env_.name(), env_.observation_dim());
  if (env_.elapsed_steps() == 0) plan_.setZero();
  const EnvState start = env_.save_state();
  std::normal_distribution<double> normal(0.0, options_.noise);
  std::vector<Eigen::MatrixXd> actions(K, plan_);
  std::vector<double> returns(K, 0.0);
  for (int k = 0; k < K; ++k) {
    sim_->restore_state(start);
    for (int t = 0; t < H; ++t) {
      for (int j = 0; j < m; ++j)
        actions[k](t, j) = std::clamp(plan_(t, j) + normal(rng_), -1.0, 1.0);
      const StepResult r = sim_->step(actions[k].row(t).transpose());
      returns[k] += r.reward;
      // The rest of the plan is never run: it keeps the sampled actions but earns nothing.
      if (r.done()) break;
    }
  }
  const double best = *std::max_element(returns.begin(), returns.end());
  Eigen::MatrixXd average = Eigen::MatrixXd::Zero(H, m);
  double total = 0;
  for (int k = 0; k < K; ++k) {
    const double w = std::exp((returns[k] - best) / options_.lambda);
    average += w * actions[k];
    total += w;
  }
  average /= total;
  // Warm start: the plan shifted by one step, its last action repeated.
  plan_.topRows(H - 1) = average.bottomRows(H - 1);
  plan_.row(H - 1) = average.row(H - 1);
  return average.row(0).transpose();
}

}  // namespace hlt
