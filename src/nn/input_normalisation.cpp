#include "hlt/nn/input_normalisation.h"

#include <cmath>

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {

InputNormaliser::InputNormaliser(int64_t dim, const std::vector<double>& offset,
                                 const std::vector<double>& scale, const std::vector<int64_t>& reference,
                                 const std::string& owner)
    : dim_(dim) {
  check(offset.size() == scale.size() && (scale.empty() || static_cast<int64_t>(scale.size()) == dim),
        "{} input normalisation needs {} offsets and scales, got {} and {}", owner, dim, offset.size(),
        scale.size());
  if (!scale.empty()) {
    for (size_t i = 0; i < scale.size(); ++i)
      check(scale[i] > 0 && std::isfinite(scale[i]) && std::isfinite(offset[i]),
            "{} input normalisation: component {} has offset {} and scale {} (scales must be finite and > 0)",
            owner, i, offset[i], scale[i]);
    offset_ = torch::tensor(offset, torch::kFloat64);
    inv_scale_ = 1.0 / torch::tensor(scale, torch::kFloat64);
  }
  if (!reference.empty()) {
    check(!scale.empty() && static_cast<int64_t>(reference.size()) == dim,
          "{} input references need the normalisation and {} entries, got {}", owner, dim, reference.size());
    // x = M s with M = I - (1 at (i, r(i))); stored transposed, for row-major batches s M^T.
    map_t_ = torch::eye(dim, torch::kFloat64);
    for (int64_t i = 0; i < dim; ++i) {
      const int64_t r = reference[static_cast<size_t>(i)];
      check(r == -1 || (r >= 0 && r < dim && r != i),
            "{} input reference of component {} is {}: expected -1 or another component", owner, i, r);
      if (r >= 0) map_t_[r][i] = -1.0;
    }
  }
}

InputNormalisation InputNormaliser::tensors(const torch::TensorOptions& options) const {
  check(enabled(), "InputNormaliser::tensors() without a normalisation");
  const auto opts = options.requires_grad(false);
  InputNormalisation n{offset_.to(opts), inv_scale_.to(opts), {}};
  if (map_t_.defined()) n.map_t = map_t_.to(opts);
  return n;
}

torch::Tensor InputNormaliser::apply(const torch::Tensor& state) const {
  if (!enabled()) return state;
  const InputNormalisation n = tensors(state.options());
  const torch::Tensor relative = n.map_t.defined() ? torch::matmul(state, n.map_t) : state;
  return (relative - n.offset) * n.inv_scale;
}

void InputNormaliser::apply_in_place(const torch::Tensor& x) const {
  if (!enabled()) return;
  torch::Tensor s = x.narrow(1, 0, dim_);
  s.copy_(apply(s));
}

torch::nn::Linear InputNormaliser::fold_into(const torch::nn::Linear& first) const {
  check(enabled(), "InputNormaliser::fold_into() without a normalisation");
  check(first->weight.size(1) >= dim_, "InputNormaliser::fold_into: the layer reads {} inputs, fewer than {}",
        first->weight.size(1), dim_);
  torch::NoGradGuard no_grad;
  const InputNormalisation n = tensors(first->weight.options());
  // A Linear draws its initial weights from the default generator: put its state back, so that asking for
  // a fold leaves every later random draw as it was.
  at::Generator generator = at::detail::getDefaultCPUGenerator();
  const at::Tensor generator_state = generator.get_state();
  torch::nn::Linear folded(torch::nn::LinearOptions(first->weight.size(1), first->weight.size(0)));
  generator.set_state(generator_state);
  folded->to(first->weight.scalar_type());
  folded->weight.copy_(first->weight);
  const torch::Tensor w_s = first->weight.narrow(1, 0, dim_);
  const torch::Tensor scaled = w_s * n.inv_scale;
  folded->weight.narrow(1, 0, dim_).copy_(n.map_t.defined() ? torch::matmul(scaled, n.map_t.t()) : scaled);
  folded->bias.copy_(first->bias - torch::mv(w_s, n.offset * n.inv_scale));
  return folded;
}

bool InputNormaliser::same_as(const InputNormaliser& other) const {
  if (enabled() != other.enabled()) return false;
  if (!enabled()) return true;
  if (map_t_.defined() != other.map_t_.defined()) return false;
  return dim_ == other.dim_ && torch::equal(offset_, other.offset_) &&
         torch::equal(inv_scale_, other.inv_scale_) &&
         (!map_t_.defined() || torch::equal(map_t_, other.map_t_));
}

}  // namespace hlt
