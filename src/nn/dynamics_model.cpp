#include "hlt/nn/dynamics_model.h"

#include <cmath>
#include <limits>

#include <torch/torch.h>

#include "hlt/nn/batched_forward.h"
#include "hlt/nn/dense_layers.h"
#include "hlt/util/error.h"

namespace hlt {

DynamicsModelImpl::DynamicsModelImpl(const DynamicsModelOptions& o) : options_(o) {
  check(o.state_dim > 0 && o.action_dim > 0 && o.hidden > 0,
        "DynamicsModel needs positive sizes, got n={} m={} h={}", o.state_dim, o.action_dim, o.hidden);
  normaliser_ =
      InputNormaliser(o.state_dim, o.input_offset, o.input_scale, o.input_reference, "DynamicsModel");
  fc1 = register_module("fc1", torch::nn::Linear(o.state_dim + o.action_dim, o.hidden));
  fc2 = register_module("fc2", torch::nn::Linear(o.hidden, o.state_dim));
  log_std_param = register_parameter("log_std", torch::zeros({1, o.state_dim}));
}

torch::Tensor DynamicsModelImpl::forward(const torch::Tensor& state, const torch::Tensor& action) {
  torch::Tensor h = fc1(torch::cat({normaliser_.apply(state), action}, -1));
  return state + fc2(activate(h, options_.activation));
}

DenseChain DynamicsModelImpl::chain() const {
  // The residual adds the chain's raw state input; the normalisation is folded into a copy of the first
  // layer.
  return DenseChain{{normaliser_.enabled() ? normaliser_.fold_into(fc1) : fc1, fc2},
                    options_.activation,
                    /*tanh_output=*/false,
                    /*residual=*/true};
}

void DynamicsModelImpl::extend_domain(const torch::Tensor& states) {
  const int64_t n = options_.state_dim;
  check(states.dim() == 2 && states.size(1) == n,
        "DynamicsModel::extend_domain: states must be [B, {}], got {}", n, fmt::join(states.sizes(), "x"));
  if (states.size(0) == 0) return;
  // Called on every model update: Eigen over the raw rows, not a dozen dispatched tensor ops.
  const torch::Tensor s = states.to(fc1->weight.scalar_type()).contiguous();
  dispatch_floating(s, [&](auto tag) {
    using T = decltype(tag);
    Eigen::Map<const RowMatrix<T>> rows(s.data_ptr<T>(), s.size(0), n);
    check(rows.allFinite(), "DynamicsModel::extend_domain: states are not finite");
    if (!has_domain()) {
      domain_low_ = torch::full({n}, std::numeric_limits<T>::infinity(), s.options().requires_grad(false));
      domain_high_ = torch::full({n}, -std::numeric_limits<T>::infinity(), s.options().requires_grad(false));
    }
    Eigen::Map<Eigen::Matrix<T, 1, Eigen::Dynamic>> low(domain_low_.data_ptr<T>(), n),
        high(domain_high_.data_ptr<T>(), n);
    low = low.cwiseMin(rows.colwise().minCoeff());
    high = high.cwiseMax(rows.colwise().maxCoeff());
  });
}

void DynamicsModelImpl::set_domain(const torch::Tensor& low, const torch::Tensor& high) {
  const int64_t n = options_.state_dim;
  check(low.dim() == 1 && high.dim() == 1 && low.size(0) == n && high.size(0) == n,
        "DynamicsModel::set_domain: bounds must be [{}], got {} and {}", n, fmt::join(low.sizes(), "x"),
        fmt::join(high.sizes(), "x"));
  check((low <= high).all().item<bool>(), "DynamicsModel::set_domain: a lower bound exceeds its upper bound");
  domain_low_ = low.to(fc1->weight.scalar_type()).clone().contiguous();
  domain_high_ = high.to(fc1->weight.scalar_type()).clone().contiguous();
}

torch::Tensor DynamicsModelImpl::log_std() const {
  return log_std_param.clamp(options_.log_std_min, options_.log_std_max);
}

namespace {

// -mean log N(x; mean, exp(ls)^2), with log N(x; mu, sigma) = -(x - mu)^2 / (2 sigma^2) - log sigma -
// log(2 pi) / 2.
torch::Tensor gaussian_nll(const torch::Tensor& x, const torch::Tensor& mean, const torch::Tensor& ls) {
  const torch::Tensor z = (x - mean) * torch::exp(-ls);
  const torch::Tensor log_density = -0.5 * z.square() - ls - 0.5 * std::log(2.0 * M_PI);
  return -log_density.mean();
}

}  // namespace

torch::Tensor DynamicsModelImpl::loss(const torch::Tensor& state, const torch::Tensor& action,
                                      const torch::Tensor& next_state) {
  return gaussian_nll(next_state, forward(state, action), log_std());
}

torch::Tensor DynamicsModelImpl::rollout_loss(const torch::Tensor& state, const torch::Tensor& actions,
                                              const torch::Tensor& next_states) {
  const int64_t batch = state.size(0);
  check(state.dim() == 2 && batch > 0 && actions.dim() == 2 && next_states.dim() == 2 &&
            actions.size(0) % batch == 0 && next_states.size(0) == actions.size(0),
        "DynamicsModel::rollout_loss: needs states [B, n], actions [K B, m] and next states [K B, n], got "
        "{}, {} and {}",
        fmt::join(state.sizes(), "x"), fmt::join(actions.sizes(), "x"), fmt::join(next_states.sizes(), "x"));
  const int64_t steps = actions.size(0) / batch;
  const torch::Tensor ls = log_std();
  torch::Tensor predicted = state, total;
  for (int64_t k = 0; k < steps; ++k) {
    predicted = forward(predicted, actions.narrow(0, k * batch, batch));
    const torch::Tensor step = gaussian_nll(next_states.narrow(0, k * batch, batch), predicted, ls);
    total = k == 0 ? step : total + step;
  }
  return total / static_cast<double>(steps);
}

double DynamicsModelImpl::rollout_loss_with_gradient(const torch::Tensor& state, const torch::Tensor& actions,
                                                     const torch::Tensor& next_states, double scale) {
  check(!c10::InferenceMode::is_enabled(),
        "DynamicsModel::rollout_loss_with_gradient needs autograd: call it outside inference mode");
  const torch::Tensor value = rollout_loss(state, actions, next_states);
  std::vector<torch::Tensor> params = parameters();
  const std::vector<torch::Tensor> grads = torch::autograd::grad({value}, params);
  torch::NoGradGuard no_grad;
  for (size_t i = 0; i < params.size(); ++i)
    gradient_of(params[i]).copy_(grads[i]).mul_(scale);
  return value.item<double>();
}

double DynamicsModelImpl::loss_with_gradient(const torch::Tensor& state, const torch::Tensor& action,
                                             const torch::Tensor& next_state, double scale) {
  // The products go through BLAS (ATen's out= kernels); everything elementwise but sin and cos runs as
  // Eigen expressions over the same buffers, without dispatched ops.
  c10::InferenceMode guard;  // its buffers are only ever touched in inference mode
  const int64_t batch = state.size(0), n = options_.state_dim, m = options_.action_dim;
  check(state.is_contiguous() && action.is_contiguous() && next_state.is_contiguous() &&
            state.scalar_type() == fc1->weight.scalar_type(),
        "DynamicsModel::loss_with_gradient needs contiguous inputs of the model's dtype");
  match_buffers({&x_, &h_, &act_, &mean_, &z_, &g_mean_, &g_act_, &cos_}, fc1->weight);
  sized(x_, {batch, n + m});
  sized(g_mean_, {batch, n});
  const double count = static_cast<double>(batch * n);
  double loss = 0;
  dispatch_floating(x_, [&](auto tag) {
    using T = decltype(tag);
    auto x = row_map<T>(x_);
    x.leftCols(n) = row_map<T>(state);
    x.rightCols(m) = row_map<T>(action);
  });
  normaliser_.apply_in_place(x_);
  dense_forward(h_, x_, fc1->weight, fc1->bias);
  activate_out(act_, h_, options_.activation);
  at::mm_out(mean_, act_, fc2->weight.t());
  dispatch_floating(x_, [&](auto tag) {
    using T = decltype(tag);
    using Row = Eigen::Array<T, 1, Eigen::Dynamic>;
    const Eigen::Map<const Row> b2(fc2->bias.data_ptr<T>(), n), raw_ls(log_std_param.data_ptr<T>(), n);
    const Row ls = raw_ls.max(T(options_.log_std_min)).min(T(options_.log_std_max));
    const Row inv_std = (-ls).exp();
    // z = (s' - (s + W2 h + b2)) / sigma; loss = mean(z^2) / 2 + mean(log sigma) + log(2 pi) / 2.
    const RowMatrix<T> z =
        ((row_map<T>(next_state) - row_map<T>(state) - row_map<T>(mean_)).array().rowwise() - b2).rowwise() *
        inv_std;
    const Row z_sq = z.array().square().colwise().sum();
    loss = 0.5 * static_cast<double>(z_sq.sum()) / count + static_cast<double>(ls.mean()) +
           0.5 * std::log(2.0 * M_PI);
    // d loss / d mean = -z / (sigma B n); d loss / d log_std_j = 1 / n - sum_b z_bj^2 / (B n), zero where
    // the clamp is active (as autograd's clamp backward).
    auto g = row_map<T>(g_mean_);
    g = (z.array().rowwise() * inv_std * T(-scale / count)).matrix();
    Eigen::Map<Row>(gradient_of(fc2->bias).template data_ptr<T>(), n) = g.colwise().sum().array();
    const Row g_ls = T(scale) * (T(1.0 / n) - z_sq / T(count));
    const auto inside = (raw_ls >= T(options_.log_std_min)) && (raw_ls <= T(options_.log_std_max));
    Eigen::Map<Row>(gradient_of(log_std_param).template data_ptr<T>(), n) = inside.select(g_ls, T(0));
  });
  at::mm_out(gradient_of(fc2->weight), g_mean_.t(), act_);
  at::mm_out(g_act_, g_mean_, fc2->weight);
  if (options_.activation == Activation::kSin) cosine_out(cos_, h_);
  dispatch_floating(x_, [&](auto tag) {
    using T = decltype(tag);
    auto g = row_map<T>(g_act_);
    if (options_.activation == Activation::kSin)
      g.array() *= row_map<T>(cos_).array();
    else
      relu_gradient_of(act_, g_act_);
    sum_rows_into(g, Eigen::Map<Eigen::Matrix<T, 1, Eigen::Dynamic>>(
                         gradient_of(fc1->bias).template data_ptr<T>(), options_.hidden));
  });
  at::mm_out(gradient_of(fc1->weight), g_act_.t(), x_);
  return loss;
}

}  // namespace hlt
