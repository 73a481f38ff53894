#include "agents/plan_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <fmt/format.h>
#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::vector<double> ranks(const std::vector<double>& x) {
  std::vector<size_t> order(x.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return x[a] < x[b]; });
  std::vector<double> r(x.size());
  for (size_t i = 0; i < order.size();) {
    size_t j = i;
    while (j + 1 < order.size() && x[order[j + 1]] == x[order[i]])
      ++j;
    for (size_t k = i; k <= j; ++k)
      r[order[k]] = (static_cast<double>(i) + static_cast<double>(j)) / 2;  // ties: their mean rank
    i = j + 1;
  }
  return r;
}

// Every sample's return over the planner's horizon when its actions are replayed on `sim` from the
// environment's current state; the rows of `actions` [H, K, m] that are not finite are replayed as zeros
// (their samples are left out by the caller).
std::vector<double> replay(SimulatorRolloutModel& sim, const at::Tensor& actions) {
  const int64_t H = actions.size(0), K = actions.size(1), n = sim.state_dim();
  const at::Tensor a = torch::nan_to_num(actions.to(at::kDouble), 0.0, 0.0, 0.0);
  at::Tensor states = torch::zeros({K, n}, torch::kFloat64), next = torch::empty({K, n}, torch::kFloat64);
  at::Tensor r = torch::empty({K}, torch::kFloat64), total = torch::zeros({K}, torch::kFloat64);
  sim.begin(K, torch::zeros({n}, torch::kFloat64));
  for (int64_t t = 0; t < H; ++t) {
    sim.step(states, a[t].contiguous(), next, r);
    total += r;
    std::swap(states, next);
  }
  return std::vector<double>(total.data_ptr<double>(), total.data_ptr<double>() + K);
}

double mean_of(const std::vector<double>& v) {
  return v.empty() ? kNaN : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

double median_of(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return kNaN;
  std::sort(v.begin(), v.end());
  const size_t h = v.size() / 2;
  return v.size() % 2 ? v[h] : (v[h - 1] + v[h]) / 2;
}

}  // namespace

double spearman(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() != y.size() || x.size() < 2) return kNaN;
  const std::vector<double> rx = ranks(x), ry = ranks(y);
  const double mx = mean_of(rx), my = mean_of(ry);
  double sxy = 0, sxx = 0, syy = 0;
  for (size_t i = 0; i < rx.size(); ++i) {
    sxy += (rx[i] - mx) * (ry[i] - my);
    sxx += (rx[i] - mx) * (rx[i] - mx);
    syy += (ry[i] - my) * (ry[i] - my);
  }
  return sxx > 0 && syy > 0 ? sxy / std::sqrt(sxx * syy) : kNaN;
}

PlanCheck::PlanCheck(const Env& env, RewardModel reward)
    : env_(env),
      truth_(env, at::kDouble),
      scored_(reward.is_empty() ? nullptr
                                : std::make_unique<SimulatorRolloutModel>(env, at::kDouble, reward)) {}

PlanCheckCall PlanCheck::add(const StochasticHybrid& planner) {
  torch::InferenceMode guard;
  const at::Tensor& samples = planner.samples();
  // weight_ess is NaN until the planner's first call (and after a call whose weights are not finite).
  check(samples.defined() && samples.dim() == 3 && samples.size(2) == env_.action_dim() &&
            std::isfinite(planner.diagnostics().weight_ess),
        "PlanCheck: the planner has made no planning call with finite weights on {}'s actions", env_.name());
  const int64_t K = samples.size(1);
  const at::Tensor predicted_t = planner.rewards().to(at::kDouble).sum(0).contiguous();
  const at::Tensor w0 = planner.weights()[0].to(at::kDouble).contiguous();
  const at::Tensor finite_actions = torch::isfinite(samples).all(2).all(0).contiguous();

  const std::vector<double> simulated = replay(truth_, samples);
  const std::vector<double> scored = scored_ ? replay(*scored_, samples) : std::vector<double>{};
  // The samples whose actions and predicted return are finite; the others carry no weight in the planner.
  std::vector<double> p, s, l, w;
  for (int64_t k = 0; k < K; ++k) {
    const double pk = predicted_t.data_ptr<double>()[k];
    if (!finite_actions.data_ptr<bool>()[k] || !std::isfinite(pk)) continue;
    p.push_back(pk);
    s.push_back(simulated[static_cast<size_t>(k)]);
    if (!scored.empty()) l.push_back(scored[static_cast<size_t>(k)]);
    w.push_back(w0.data_ptr<double>()[k]);
  }
  PlanCheckCall c;
  c.rank_models = spearman(p, s);
  c.rank_reward = scored.empty() ? kNaN : spearman(l, s);
  const double mean = mean_of(s);
  const double best = s.empty() ? kNaN : *std::max_element(s.begin(), s.end());
  const double total_w = std::accumulate(w.begin(), w.end(), 0.0);
  const double chosen = total_w > 0 ? std::inner_product(w.begin(), w.end(), s.begin(), 0.0) / total_w : kNaN;
  c.spread = best - mean;
  c.selection = c.spread > 0 ? (chosen - mean) / c.spread : kNaN;
  calls_.push_back(c);
  return c;
}

std::string PlanCheck::summary() const {
  auto figure = [&](double PlanCheckCall::*f) {
    std::vector<double> v;
    for (const PlanCheckCall& c : calls_)
      if (std::isfinite(c.*f)) v.push_back(c.*f);
    return fmt::format("mean {:.3f} median {:.3f} over {}", mean_of(v), median_of(v), v.size());
  };
  return fmt::format(
      "plan check over {} planning calls (the planner's samples replayed on the simulator):\n"
      "  rank correlation, predicted return vs simulated:                     {}\n"
      "  rank correlation, simulator scored by the learned reward vs true:    {}\n"
      "  the planner's choice, (chosen - mean) / (best - mean), simulated:    {}\n"
      "  best sample's simulated return over the samples' mean (best - mean): {}\n",
      calls_.size(), figure(&PlanCheckCall::rank_models), figure(&PlanCheckCall::rank_reward),
      figure(&PlanCheckCall::selection), figure(&PlanCheckCall::spread));
}

}  // namespace hlt
