#include "hlt/nn/gaussian_policy.h"

#include <cmath>

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {
namespace {

// Hidden layers then an output layer; only the output layer gets the small uniform initialisation.
torch::nn::ModuleList make_mlp(int64_t in, const std::vector<int64_t>& hidden, int64_t out,
                               double init_scale) {
  torch::nn::ModuleList layers;
  int64_t width = in;
  for (int64_t h : hidden) {
    layers->push_back(torch::nn::Linear(width, h));
    width = h;
  }
  torch::nn::Linear last(width, out);
  torch::NoGradGuard no_grad;
  last->weight.uniform_(-init_scale, init_scale);
  last->bias.uniform_(-init_scale, init_scale);
  layers->push_back(last);
  return layers;
}

torch::Tensor run_mlp(torch::nn::ModuleList layers, torch::Tensor x, Activation hidden_activation) {
  const size_t n = layers->size();
  for (size_t i = 0; i < n; ++i) {
    x = layers[i]->as<torch::nn::Linear>()->forward(x);
    if (i + 1 < n) x = activate(x, hidden_activation);
  }
  return x;
}

// The two heads on a state: the mean and the log-std head's output before its clamp.
std::pair<torch::Tensor, torch::Tensor> heads(const GaussianPolicyImpl& policy, const torch::Tensor& state) {
  const torch::Tensor x = policy.normalize(state);
  return {run_mlp(policy.mean_layers, x, policy.options().mean_activation),
          run_mlp(policy.log_std_layers, x, Activation::kRelu)};
}

struct InwardClamp : torch::autograd::Function<InwardClamp> {
  static torch::Tensor forward(torch::autograd::AutogradContext* ctx, const torch::Tensor& raw, double lo,
                               double hi) {
    ctx->save_for_backward({raw});
    ctx->saved_data["lo"] = lo;
    ctx->saved_data["hi"] = hi;
    return raw.clamp(lo, hi);
  }
  static torch::autograd::tensor_list backward(torch::autograd::AutogradContext* ctx,
                                               torch::autograd::tensor_list grad) {
    const torch::Tensor raw = ctx->get_saved_variables()[0];
    const double lo = ctx->saved_data["lo"].toDouble(), hi = ctx->saved_data["hi"].toDouble();
    const torch::Tensor& g = grad[0];
    const torch::Tensor pass = ((raw >= lo) & (raw <= hi)) | ((raw > hi) & (g > 0)) | ((raw < lo) & (g < 0));
    return {g * pass, torch::Tensor(), torch::Tensor()};
  }
};

}  // namespace

torch::Tensor clamp_with_inward_gradient(const torch::Tensor& raw, double lo, double hi) {
  check(lo <= hi, "clamp_with_inward_gradient needs lo <= hi, got [{}, {}]", lo, hi);
  return InwardClamp::apply(raw, lo, hi);
}

GaussianPolicyImpl::GaussianPolicyImpl(const GaussianPolicyOptions& o) : options_(o) {
  check(o.state_dim > 0 && o.action_dim > 0, "GaussianPolicy needs positive sizes, got n={} m={}",
        o.state_dim, o.action_dim);
  check(!o.hidden.empty(), "GaussianPolicy needs at least one hidden layer");
  for (int64_t h : o.hidden)
    check(h > 0, "GaussianPolicy hidden sizes must be positive");
  normaliser_ =
      InputNormaliser(o.state_dim, o.input_offset, o.input_scale, o.input_reference, "GaussianPolicy");
  mean_layers = register_module("mean", make_mlp(o.state_dim, o.hidden, o.action_dim, o.init_scale));
  log_std_layers = register_module("log_std", make_mlp(o.state_dim, o.hidden, o.action_dim, o.init_scale));
}

InputNormalisation GaussianPolicyImpl::input_normalisation(const torch::TensorOptions& options) const {
  check(normalizes_inputs(), "GaussianPolicy: input_normalisation() of a policy without normalisation");
  return normaliser_.tensors(options);
}

torch::Tensor GaussianPolicyImpl::normalize(const torch::Tensor& state) const {
  return normaliser_.apply(state);
}

std::pair<torch::Tensor, torch::Tensor> GaussianPolicyImpl::forward(const torch::Tensor& state) {
  auto [mean, raw] = heads(*this, state);
  return {mean, raw.clamp(options_.log_std_min, options_.log_std_max)};
}

std::pair<torch::Tensor, torch::Tensor> GaussianPolicyImpl::forward_for_fit(const torch::Tensor& state) {
  auto [mean, raw] = heads(*this, state);
  return {mean, clamp_with_inward_gradient(raw, options_.log_std_min, options_.log_std_max)};
}

torch::Tensor GaussianPolicyImpl::mean_action(const torch::Tensor& state) {
  return torch::tanh(run_mlp(mean_layers, normalize(state), options_.mean_activation));
}

DenseChain GaussianPolicyImpl::mean_chain() const {
  DenseChain chain{{}, options_.mean_activation, /*tanh_output=*/true};
  for (const auto& layer : *mean_layers)
    chain.layers.push_back(torch::nn::Linear(std::dynamic_pointer_cast<torch::nn::LinearImpl>(layer)));
  // Folded into the first layer, a new one (the chain holds its layers): gradients reach the state, not the
  // policy's own first layer.
  if (normalizes_inputs()) chain.layers.front() = normaliser_.fold_into(chain.layers.front());
  return chain;
}

torch::Tensor GaussianPolicyImpl::squashed_log_prob(const torch::Tensor& u, const torch::Tensor& action,
                                                    const torch::Tensor& mean, const torch::Tensor& log_std) {
  const torch::Tensor z = (u - mean) * torch::exp(-log_std);
  const torch::Tensor gaussian = -0.5 * z.square() - log_std - 0.5 * std::log(2.0 * M_PI);
  const torch::Tensor correction = torch::log(1.0 - action.square() + kTanhEpsilon);
  return (gaussian - correction).sum(-1, /*keepdim=*/true);
}

PolicySample GaussianPolicyImpl::rsample(const torch::Tensor& state, c10::optional<at::Generator> generator) {
  auto [mean, log_std] = forward(state);
  const torch::Tensor u = mean + torch::exp(log_std) * at::randn(mean.sizes(), generator, mean.options());
  const torch::Tensor a = torch::tanh(u);
  return {a, squashed_log_prob(u, a, mean, log_std), u};
}

PolicySample GaussianPolicyImpl::sample(const torch::Tensor& state) {
  torch::NoGradGuard no_grad;
  return rsample(state);
}

torch::Tensor GaussianPolicyImpl::log_prob(const torch::Tensor& state, const torch::Tensor& action) {
  auto [mean, log_std] = forward(state);
  const torch::Tensor a = action.clamp(-1.0 + kTanhEpsilon, 1.0 - kTanhEpsilon);
  return squashed_log_prob(torch::atanh(a), a, mean, log_std);
}

}  // namespace hlt
