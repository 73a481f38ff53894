#include "hlt/nn/batched_forward.h"

#include <algorithm>
#include <optional>
#include <tuple>
#include <type_traits>

#include <torch/torch.h>

#include "hlt/simd/vector_math.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

torch::nn::LinearImpl* linear_at(torch::nn::ModuleList list, size_t i) {
  return list[i]->as<torch::nn::Linear>();
}

// x = act(x + bias) for a sample-major block x [batch, width] (rows may be strided: a column block of a
// fused layer's output) and a bias parameter [width]: for float one pass of hlt's vector kernels (SLEEF's
// sin, no dispatched op); double (tests) through Eigen and ATen.
void bias_activate(const at::Tensor& x, const at::Tensor& bias, std::optional<Activation> a) {
  if (x.scalar_type() == at::kFloat) {
    const BiasThen then = !a ? BiasThen::kNothing : *a == Activation::kSin ? BiasThen::kSin : BiasThen::kRelu;
    bias_cols(x.data_ptr<float>(), x.size(0), x.size(1), x.stride(0), bias.data_ptr<float>(), then);
    return;
  }
  dispatch_floating(x, [&](auto tag) {
    using T = decltype(tag);
    auto m = row_map<T>(x);
    Eigen::Map<const Eigen::Matrix<T, 1, Eigen::Dynamic>> b(bias.data_ptr<T>(), bias.numel());
    if (a == Activation::kRelu) {
      m = (m.rowwise() + b).cwiseMax(T(0));
    } else {
      m.rowwise() += b;
    }
  });
  if (a == Activation::kSin) at::sin_(const_cast<at::Tensor&>(x));
}

// Copies the transpose of a weight [out, in] into the block at (row, col) of a row-major matrix with `stride`
// columns: the [in, out] layout that makes a sample-major layer x W^T one plain product.
template <typename T>
void copy_transposed(const at::Tensor& w, T* dst, int64_t row, int64_t col, int64_t stride) {
  const int64_t out = w.size(0), in = w.size(1);
  if constexpr (std::is_same_v<T, float>) {
    transpose_copy(w.data_ptr<float>(), out, in, in, dst + row * stride + col, stride);
  } else {
    Eigen::Map<RowMatrix<T>, 0, Eigen::OuterStride<>> block(dst + row * stride + col, in, out,
                                                            Eigen::OuterStride<>(stride));
    block = Eigen::Map<const RowMatrix<T>>(w.data_ptr<T>(), out, in).transpose();
  }
}

}  // namespace

void dispatch_floating_error(const at::Tensor& t) {
  throw Error(
      fmt::format("batched forward needs float or double tensors, got {}", std::string(t.dtype().name())));
}

PolicyForward::PolicyForward(GaussianPolicy policy) : policy_(std::move(policy)) {
  check(!policy_.is_empty(), "PolicyForward needs a policy");
}

void PolicyForward::prepare(int64_t batch) {
  const auto& o = policy_->options();
  const size_t layers = policy_->mean_layers->size();
  const auto& w0 = linear_at(policy_->mean_layers, 0)->weight;
  if (buffers_.empty() || buffers_.front().size(0) != batch ||
      w0.scalar_type() != buffers_.front().scalar_type()) {
    // Allocated once per batch size; the off-diagonal blocks of the fused layers stay zero.
    weights_.clear();
    buffers_.clear();
    widths_.assign(o.hidden.begin(), o.hidden.end());
    const auto opts = w0.options().requires_grad(false);
    for (size_t l = 0; l < layers; ++l) {
      const auto& mw = linear_at(policy_->mean_layers, l)->weight;
      const int64_t in = l == 0 ? mw.size(1) : 2 * mw.size(1);
      weights_.push_back(torch::zeros({in, 2 * mw.size(0)}, opts));
      buffers_.push_back(torch::empty({batch, 2 * mw.size(0)}, opts));
    }
    if (policy_->normalizes_inputs()) {
      const InputNormalisation n = policy_->input_normalisation(opts);
      input_offset_ = n.offset;
      input_inv_scale_ = n.inv_scale;
      input_map_t_ = n.map_t;
      normalized_ = torch::empty({batch, o.state_dim}, opts);
    }
    mean_ = buffers_.back().narrow(1, 0, o.action_dim);
    log_std_ = buffers_.back().narrow(1, o.action_dim, o.action_dim);
    mean_cols_.clear();
    std_cols_.clear();
    for (size_t l = 0; l < layers; ++l) {
      const int64_t width = l + 1 < layers ? widths_[l] : o.action_dim;
      mean_cols_.push_back(buffers_[l].narrow(1, 0, width));
      std_cols_.push_back(buffers_[l].narrow(1, width, width));
    }
  }
  // The current weights, transposed and fused: the first layers side by side (both heads read the state),
  // later layers block-diagonal.
  dispatch_floating(w0, [&](auto tag) {
    using T = decltype(tag);
    for (size_t l = 0; l < layers; ++l) {
      const auto* mean = linear_at(policy_->mean_layers, l);
      const auto* std = linear_at(policy_->log_std_layers, l);
      const int64_t out = mean->weight.size(0), in = mean->weight.size(1);
      const int64_t stride = weights_[l].size(1);
      T* w = weights_[l].data_ptr<T>();
      copy_transposed<T>(mean->weight, w, 0, 0, stride);
      copy_transposed<T>(std->weight, w, l == 0 ? 0 : in, out, stride);
    }
  });
}

void PolicyForward::forward(const at::Tensor& states) {
  torch::NoGradGuard no_grad;  // out= products do not record gradients
  const auto& o = policy_->options();
  const at::Tensor* x = &states;
  if (normalized_.defined()) {
    // Normalised inputs (the robot tasks): elementwise passes into the buffer (after one product for
    // references), nothing allocated.
    if (input_map_t_.defined()) {
      at::mm_out(normalized_, states, input_map_t_);
      normalized_.sub_(input_offset_);
    } else {
      at::sub_out(normalized_, states, input_offset_);
    }
    normalized_.mul_(input_inv_scale_);
    x = &normalized_;
  }
  const size_t layers = buffers_.size();
  for (size_t l = 0; l < layers; ++l) {
    at::mm_out(buffers_[l], *x, weights_[l]);
    x = &buffers_[l];
    const bool hidden = l + 1 < layers;
    bias_activate(mean_cols_[l], linear_at(policy_->mean_layers, l)->bias,
                  hidden ? std::optional<Activation>(o.mean_activation) : std::nullopt);
    bias_activate(std_cols_[l], linear_at(policy_->log_std_layers, l)->bias,
                  hidden ? std::optional<Activation>(Activation::kRelu) : std::nullopt);
  }
  dispatch_floating(log_std_, [&](auto tag) {
    using T = decltype(tag);
    auto ls = row_map<T>(log_std_);
    ls = ls.array().max(T(o.log_std_min)).min(T(o.log_std_max)).matrix();
  });
}

ModelForward::ModelForward(DynamicsModel dynamics, RewardModel reward)
    : dynamics_(std::move(dynamics)), reward_(std::move(reward)) {
  check(!dynamics_.is_empty() && !reward_.is_empty(), "ModelForward needs both models");
  n_ = dynamics_->options().state_dim;
  m_ = dynamics_->options().action_dim;
  hd_ = dynamics_->options().hidden;
  hr_ = reward_->options().hidden;
  check(reward_->options().state_dim == n_ && reward_->options().action_dim == m_,
        "dynamics and reward models disagree on sizes");
  // Their first layers read one input buffer.
  check(dynamics_->normaliser().same_as(reward_->normaliser()),
        "dynamics and reward models disagree on their input normalisation");
}

void ModelForward::prepare(int64_t batch) {
  const auto& w = dynamics_->fc1->weight;
  if (!input_.defined() || input_.size(0) != batch || input_.scalar_type() != w.scalar_type()) {
    const auto opts = w.options().requires_grad(false);
    w1_ = torch::empty({n_ + m_, hd_ + hr_}, opts);
    w2d_ = torch::empty({hd_, n_}, opts);
    w2r_ = torch::empty({hr_, hr_}, opts);
    input_ = torch::empty({batch, n_ + m_}, opts);
    hidden1_ = torch::empty({batch, hd_ + hr_}, opts);
    hidden_d_ = hidden1_.narrow(1, 0, hd_);
    hidden_r_ = hidden1_.narrow(1, hd_, hr_);
    hidden2_ = torch::empty({batch, hr_}, opts);
    if (dynamics_->normaliser().enabled()) {
      normalisation_ = dynamics_->normaliser().tensors(opts);
      if (normalisation_.map_t.defined()) relative_ = torch::empty({batch, n_}, opts);
    }
  }
  dispatch_floating(w, [&](auto tag) {
    using T = decltype(tag);
    // Both models read [s, a]: their first layers, side by side, become one product.
    copy_transposed<T>(dynamics_->fc1->weight, w1_.data_ptr<T>(), 0, 0, hd_ + hr_);
    copy_transposed<T>(reward_->fc1->weight, w1_.data_ptr<T>(), 0, hd_, hd_ + hr_);
    copy_transposed<T>(dynamics_->fc2->weight, w2d_.data_ptr<T>(), 0, 0, n_);
    copy_transposed<T>(reward_->fc2->weight, w2r_.data_ptr<T>(), 0, 0, hr_);
  });
}

void ModelForward::step(const at::Tensor& states, const at::Tensor& actions, at::Tensor& next_states,
                        at::Tensor* rewards) {
  torch::NoGradGuard no_grad;  // out= products do not record gradients
  dispatch_floating(input_, [&](auto tag) {
    using T = decltype(tag);
    auto in = row_map<T>(input_);
    in.rightCols(m_) = row_map<T>(actions);
    if (!normalisation_.offset.defined()) {
      in.leftCols(n_) = row_map<T>(states);
      return;
    }
    // x = (s M^T - offset) / scale: one small product for the references, then one Eigen pass.
    if (relative_.defined()) at::mm_out(relative_, states, normalisation_.map_t);
    using Row = Eigen::Array<T, 1, Eigen::Dynamic>;
    const Eigen::Map<const Row> offset(normalisation_.offset.data_ptr<T>(), n_),
        inv_scale(normalisation_.inv_scale.data_ptr<T>(), n_);
    in.leftCols(n_) =
        ((row_map<T>(relative_.defined() ? relative_ : states).array().rowwise() - offset).rowwise() *
         inv_scale)
            .matrix();
  });
  at::mm_out(hidden1_, input_, w1_);
  bias_activate(hidden_d_, dynamics_->fc1->bias, dynamics_->options().activation);
  bias_activate(hidden_r_, reward_->fc1->bias, Activation::kRelu);
  // s' = s + h W2^T + b2
  at::mm_out(next_states, hidden_d_, w2d_);
  dispatch_floating(next_states, [&](auto tag) {
    using T = decltype(tag);
    Eigen::Map<const Eigen::Matrix<T, 1, Eigen::Dynamic>> b(dynamics_->fc2->bias.data_ptr<T>(), n_);
    row_map<T>(next_states) += row_map<T>(states).rowwise() + b;
  });
  if (!rewards) return;
  at::mm_out(hidden2_, hidden_r_, w2r_);
  bias_activate(hidden2_, reward_->fc2->bias, Activation::kRelu);
  dispatch_floating(hidden2_, [&](auto tag) {
    using T = decltype(tag);
    auto h = row_map<T>(hidden2_);
    // The last layer has one output: a matrix-vector product, cheaper in Eigen than a dispatched op.
    const auto& w3 = reward_->fc3->weight;
    Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, 1>> w(w3.data_ptr<T>(), w3.size(1));
    Eigen::Map<Eigen::Matrix<T, Eigen::Dynamic, 1>> r(rewards->data_ptr<T>(), rewards->numel());
    r.noalias() = h * w;
    r.array() += reward_->fc3->bias.data_ptr<T>()[0];
  });
}

}  // namespace hlt
