#include "hlt/nn/flat_adam.h"

#include <xmmintrin.h>

#include <cmath>

#include <torch/torch.h>

#include "hlt/core/checkpoint.h"
#include "hlt/simd/vector_math.h"
#include "hlt/util/error.h"

namespace hlt {

std::vector<at::Tensor> weight_matrices(const torch::nn::Module& module) {
  std::vector<at::Tensor> out;
  for (const auto& p : module.named_parameters(/*recurse=*/true)) {
    const std::string& name = p.key();
    if (name.size() >= 6 && name.compare(name.size() - 6, 6, "weight") == 0) out.push_back(p.value());
  }
  return out;
}

void add_weight_decay(const std::vector<at::Tensor>& weights, double decay) {
  torch::NoGradGuard no_grad;
  for (const auto& w : weights)
    w.mutable_grad().add_(w, decay);
}

at::Tensor flatten_parameters(const std::vector<at::Tensor>& params) {
  check(!params.empty(), "flatten_parameters needs at least one parameter");
  int64_t total = 0;
  for (const auto& p : params) {
    check(p.defined() && p.is_leaf() && p.scalar_type() == torch::kFloat32 && p.device().is_cpu(),
          "flat parameter buffers take float32 CPU leaf tensors");
    total += p.numel();
  }
  at::Tensor flat = torch::empty({total});
  torch::NoGradGuard no_grad;
  int64_t offset = 0;
  for (auto p : params) {
    at::Tensor view = flat.narrow(0, offset, p.numel()).view(p.sizes());
    view.copy_(p);
    p.set_data(view);
    offset += p.numel();
  }
  return flat;
}

FlatAdam::FlatAdam(const std::vector<at::Tensor>& params, const FlatAdamOptions& options)
    : options_(options) {
  param_ = flatten_parameters(params);
  const int64_t total = param_.numel();
  grad_ = torch::zeros({total});
  exp_avg_ = torch::zeros({total});
  exp_avg_sq_ = torch::zeros({total});
  int64_t offset = 0;
  for (auto p : params) {
    p.mutable_grad() = grad_.narrow(0, offset, p.numel()).view(p.sizes());
    offset += p.numel();
  }
}

void FlatAdam::zero_grad() {
  grad_.zero_();
}

void FlatAdam::restart() {
  exp_avg_.zero_();
  exp_avg_sq_.zero_();
  step_ = 0;
}

void FlatAdam::step() {
  ++step_;
  const double bc1 = 1.0 - std::pow(options_.beta1, static_cast<double>(step_));
  const double bc2 = 1.0 - std::pow(options_.beta2, static_cast<double>(step_));
  // torch.optim.Adam's arithmetic in float, as one vectorised pass instead of eight tensor ops.
  const float b1 = static_cast<float>(options_.beta1), b2 = static_cast<float>(options_.beta2);
  const float c1 = static_cast<float>(1.0 - options_.beta1), c2 = static_cast<float>(1.0 - options_.beta2);
  const float inv_sqrt_bc2 = static_cast<float>(1.0 / std::sqrt(bc2)), eps = static_cast<float>(options_.eps);
  const float step_size = static_cast<float>(options_.lr / bc1);
  // Flush denormals to zero here: the second moment of a gradient near 1e-19 is denormal, and x86 cores
  // take a microcode assist of ~100 cycles per denormal operand, which made this pass cost more than all of
  // an update's matrix products. Values below 1e-38 change nothing a step could show.
  const unsigned int mxcsr = _mm_getcsr();
  _mm_setcsr(mxcsr | 0x8040);  // FTZ | DAZ
  adam_step(param_.data_ptr<float>(), grad_.data_ptr<float>(), exp_avg_.data_ptr<float>(),
            exp_avg_sq_.data_ptr<float>(), param_.numel(), {b1, c1, b2, c2, inv_sqrt_bc2, eps, step_size});
  _mm_setcsr(mxcsr);
}

void FlatAdam::save(CheckpointWriter& w, const std::string& name) const {
  w.add_tensor("adam." + name + ".exp_avg", exp_avg_);
  w.add_tensor("adam." + name + ".exp_avg_sq", exp_avg_sq_);
  w.add_int("adam." + name + ".step", step_);
}

void FlatAdam::load(CheckpointReader& r, const std::string& name) {
  const at::Tensor m = r.tensor("adam." + name + ".exp_avg");
  const at::Tensor v = r.tensor("adam." + name + ".exp_avg_sq");
  check(m.sizes() == exp_avg_.sizes() && v.sizes() == exp_avg_sq_.sizes() &&
            m.scalar_type() == torch::kFloat32 && v.scalar_type() == torch::kFloat32,
        "checkpoint {}: optimizer '{}' has {} moments, the networks need {}", r.path(), name, m.numel(),
        exp_avg_.numel());
  exp_avg_.copy_(m);
  exp_avg_sq_.copy_(v);
  step_ = r.get_int("adam." + name + ".step");
  check(step_ >= 0, "checkpoint {}: optimizer '{}' has a negative step count", r.path(), name);
}

}  // namespace hlt
