// hlt::FlatAdam: Adam (Kingma & Ba 2015, as torch.optim.Adam without weight decay or amsgrad) over
// parameters that live in one contiguous buffer, their gradients in another.
//
// Why: LibTorch 1.13's Adam runs eight tensor ops per parameter tensor, so a step over a network's dozen
// small tensors costs more in dispatch than in arithmetic. Here the parameters are rebound (Tensor::set_data)
// to views of one flat buffer and their `.grad()`s to views of one flat gradient buffer, which autograd then
// accumulates into in place; zero_grad() is one fill and step() one fused pass over the buffers.
//
// Preconditions: the parameters are distinct float32 CPU leaf tensors. Nothing else may replace their
// storage or their `.grad()` afterwards (loading a checkpoint copies into them, which keeps the binding).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <ATen/core/Tensor.h>

namespace torch::nn {
class Module;
}  // namespace torch::nn

namespace hlt {

class CheckpointWriter;
class CheckpointReader;

struct FlatAdamOptions {
  double lr = 1e-3;
  double beta1 = 0.9;
  double beta2 = 0.999;
  double eps = 1e-8;
};

// Rebinds `params` (distinct float32 CPU tensors) to consecutive views of one new contiguous buffer, their
// values kept, and returns the buffer.
at::Tensor flatten_parameters(const std::vector<at::Tensor>& params);

// The parameters of `module` whose names end in "weight" (its weight matrices, not its biases): what an L2
// penalty decays. Take them after a FlatAdam has rebound the module's parameters, so they are the live views.
std::vector<at::Tensor> weight_matrices(const torch::nn::Module& module);

// Adds decay * W to the gradient of each W in `weights`: the gradient of the penalty 0.5 * decay * |W|^2.
void add_weight_decay(const std::vector<at::Tensor>& weights, double decay);

class FlatAdam {
 public:
  FlatAdam(const std::vector<at::Tensor>& params, const FlatAdamOptions& options);

  // Zeroes every parameter's gradient (one fill of the flat gradient buffer).
  void zero_grad();
  // One Adam step from the accumulated gradients.
  void step();
  // Forgets the moments and the step count (the parameters stay): the next step() is a fresh optimizer's
  // first. For a fit to data that changed as a whole, where moments of the old data would scale the new
  // steps (ModelLearner::restart_optimizer).
  void restart();

  int64_t steps() const { return step_; }
  int64_t size() const { return param_.numel(); }
  const at::Tensor& flat_parameters() const { return param_; }
  const at::Tensor& flat_gradients() const { return grad_; }

  // The moments and the step count, under `name` (the parameters are saved with their modules).
  void save(CheckpointWriter& writer, const std::string& name) const;
  void load(CheckpointReader& reader, const std::string& name);

 private:
  FlatAdamOptions options_;
  at::Tensor param_, grad_, exp_avg_, exp_avg_sq_;
  int64_t step_ = 0;
};

}  // namespace hlt
