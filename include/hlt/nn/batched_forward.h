// Allocation-free batched forward passes of the policy and the learned models, for the planners' hot loops.
//
// A planning step over K samples is a few tiny matrix products; through the generic module forward it costs
// dozens of dispatched tensor ops (2-3 us each), which dominates. Here every layer of the whole batch is one
// matrix product through ATen (BLAS) into preallocated buffers, the two policy heads and the two models'
// first layers are fused into single products, and the light elementwise work (ReLU, clamps, the dynamics'
// residual add) runs as Eigen expressions over the same buffers, without dispatch.
//
// Batches are sample-major, as the modules' own: a batch of B states is a [B, n] matrix (one row per
// sample). prepare() copies every weight once per planning call, transposed to [in, out] (and fused), so
// that each layer is the plain product x W^T with the batch as BLAS's long dimension: OpenBLAS's small-matrix
// kernels vectorise over that dimension, and with K = 20 samples as the short one (the feature-major layout
// this replaced) the products took about 1.7x as long (docs/BENCHMARKS.md). The results equal the modules'
// forward passes (tests/core/batched_forward_test.cpp). Float and double models are supported.
#pragma once

#include <cstdint>
#include <vector>

#include <ATen/core/Tensor.h>
#include <Eigen/Core>

#include "hlt/nn/dynamics_model.h"
#include "hlt/nn/gaussian_policy.h"
#include "hlt/nn/reward_model.h"

namespace hlt {

template <typename T>
using RowMatrix = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
template <typename T>
using RowMap = Eigen::Map<RowMatrix<T>, 0, Eigen::OuterStride<>>;

// An Eigen view of a 2-D tensor whose rows are contiguous (any row stride).
template <typename T>
RowMap<T> row_map(const at::Tensor& t) {
  return RowMap<T>(t.data_ptr<T>(), t.size(0), t.size(1), Eigen::OuterStride<>(t.stride(0)));
}

// out = the sum of m's rows, accumulated row by row: contiguous, vectorised adds for a row-major m (Eigen's
// colwise().sum() walks each column with a stride there).
template <typename Derived, typename Out>
void sum_rows_into(const Eigen::MatrixBase<Derived>& m, Out&& out) {
  out = m.row(0);
  for (Eigen::Index i = 1; i < m.rows(); ++i)
    out += m.row(i);
}

[[noreturn]] void dispatch_floating_error(const at::Tensor& t);

// Calls f(T{}) with T = float or double after the tensor's dtype; throws for any other dtype.
template <typename F>
void dispatch_floating(const at::Tensor& t, F&& f) {
  if (t.scalar_type() == at::kFloat) {
    f(float{});
  } else if (t.scalar_type() == at::kDouble) {
    f(double{});
  } else {
    dispatch_floating_error(t);
  }
}

// Both heads of a GaussianPolicy in one pass: mean and clamped log-std for a batch of states.
class PolicyForward {
 public:
  explicit PolicyForward(GaussianPolicy policy);
  // Re-reads the policy's current weights (training changes them between planning calls) and sizes the
  // buffers for `batch` rows. Call once per planning call.
  void prepare(int64_t batch);
  // Fills mean() and log_std() for `states` [batch, n] (rows contiguous).
  void forward(const at::Tensor& states);
  // [batch, m] views into the output buffer, rows strided (valid until the batch size changes).
  const at::Tensor& mean() const { return mean_; }
  const at::Tensor& log_std() const { return log_std_; }

 private:
  GaussianPolicy policy_;
  std::vector<at::Tensor> weights_, buffers_;     // per fused layer: [in, out], [batch, out]
  std::vector<at::Tensor> mean_cols_, std_cols_;  // each head's columns of every layer's buffer
  std::vector<int64_t> widths_;                   // hidden width of one head per hidden layer
  at::Tensor mean_, log_std_;
  // With input normalisation: its offset and 1 / scale in the weights' dtype, and the normalised states.
  at::Tensor input_offset_, input_inv_scale_, input_map_t_, normalized_;
};

// The dynamics and reward models on the same batch of (s, a): s' and r(s, a).
class ModelForward {
 public:
  ModelForward(DynamicsModel dynamics, RewardModel reward);
  void prepare(int64_t batch);
  // next_states [batch, n] and, if `rewards` is given, rewards [batch] from states [batch, n] and actions
  // [batch, m] (rows contiguous). The outputs are caller-owned contiguous tensors of the models' dtype.
  void step(const at::Tensor& states, const at::Tensor& actions, at::Tensor& next_states,
            at::Tensor* rewards);

 private:
  DynamicsModel dynamics_;
  RewardModel reward_;
  int64_t n_ = 0, m_ = 0, hd_ = 0, hr_ = 0;
  at::Tensor w1_, w2d_, w2r_;  // transposed weights: both first layers side by side, the second layers
  at::Tensor input_, hidden1_, hidden_d_, hidden_r_, hidden2_;  // buffers [batch, width] and column views
  // With input normalisation (both models share it): its tensors in the weights' dtype, and the states
  // relative to their references [batch, n] (with references only).
  InputNormalisation normalisation_;
  at::Tensor relative_;
};

}  // namespace hlt
