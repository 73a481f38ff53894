#include "agents/model_check.h"

#include <cmath>

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {

void ModelCheck::add(const Eigen::VectorXd& o, const Eigen::VectorXd& a, const Eigen::VectorXd& next) {
  if (size_ == 0) {
    n_ = o.size();
    m_ = a.size();
  }
  check(o.size() == n_ && next.size() == n_ && a.size() == m_,
        "ModelCheck: transition of sizes {}, {}, {}; the first had {}, {}, {}", o.size(), a.size(),
        next.size(), n_, m_, n_);
  observations_.insert(observations_.end(), o.data(), o.data() + n_);
  actions_.insert(actions_.end(), a.data(), a.data() + m_);
  next_.insert(next_.end(), next.data(), next.data() + n_);
  ++size_;
}

void ModelCheck::clear() {
  observations_.clear();
  actions_.clear();
  next_.clear();
  size_ = 0;
}

ModelScore ModelCheck::score(DynamicsModelImpl& model, const std::optional<Eigen::VectorXd>& units) const {
  check(size_ > 0, "ModelCheck: no transitions to score");
  check(model.options().state_dim == n_ && model.options().action_dim == m_,
        "ModelCheck: the model maps {} + {} values, the transitions have {} + {}", model.options().state_dim,
        model.options().action_dim, n_, m_);
  check(!units || (units->size() == n_ && (units->array() > 0).all()),
        "ModelCheck: units must be {} positive values", n_);
  c10::InferenceMode guard;
  const auto rows = [&](const std::vector<double>& v, int64_t width) {
    return torch::from_blob(const_cast<double*>(v.data()), {size_, width}, torch::kFloat64)
        .to(model.fc1->weight.scalar_type());
  };
  const torch::Tensor predicted =
      model.forward(rows(observations_, n_), rows(actions_, m_)).to(torch::kFloat64);
  using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const torch::Tensor p = predicted.contiguous();
  const Eigen::Map<const RowMatrix> pred(p.data_ptr<double>(), size_, n_);
  const Eigen::Map<const RowMatrix> obs(observations_.data(), size_, n_), next(next_.data(), size_, n_);

  ModelScore s;
  s.transitions = size_;
  s.error_rms = ((pred - next).array().square().colwise().mean()).sqrt().transpose();
  s.change_rms = ((next - obs).array().square().colwise().mean()).sqrt().transpose();
  s.spread = ((obs.rowwise() - obs.colwise().mean()).array().square().colwise().mean()).sqrt().transpose();
  if (units) {
    s.unit = *units;
  } else {
    // Numerically constant components get no unit (0) and stay out of the ratio.
    const double floor = 1e-6 * s.spread.maxCoeff();
    s.unit = (s.spread.array() > floor).select(s.spread, 0.0);
  }
  double error = 0, change = 0;
  for (int64_t i = 0; i < n_; ++i) {
    if (s.error_rms[i] < s.change_rms[i]) ++s.better;
    if (s.unit[i] > 0) {
      error += std::pow(s.error_rms[i] / s.unit[i], 2);
      change += std::pow(s.change_rms[i] / s.unit[i], 2);
    }
  }
  if (change > 0) s.error_ratio = std::sqrt(error / change);
  return s;
}

ModelScore ModelCheck::score(DynamicsModelImpl& model, const Env& env) const {
  const std::optional<ObservationScale> declared = env.observation_scale();
  return score(model, declared ? std::optional<Eigen::VectorXd>(declared->scale) : std::nullopt);
}

}  // namespace hlt
