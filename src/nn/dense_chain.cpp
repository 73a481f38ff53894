#include "hlt/nn/dense_chain.h"

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {
namespace {

using torch::autograd::AutogradContext;
using torch::autograd::variable_list;

// The autograd node. Its variables are the inputs, then W_1, b_1, ..., W_L, b_L; edge i of the node is
// variable i, which is what needs_input_grad(i) asks about.
struct DenseChainNode : torch::autograd::Function<DenseChainNode> {
  static at::Tensor forward(AutogradContext* ctx, at::TensorList all, int64_t num_inputs, int64_t hidden,
                            bool tanh_output, bool residual) {
    const auto act = static_cast<Activation>(hidden);
    const int64_t layers = (static_cast<int64_t>(all.size()) - num_inputs) / 2;
    const at::Tensor x = num_inputs == 1 ? all[0] : at::cat(all.slice(0, num_inputs), 1);
    std::vector<at::Tensor> pre, post;  // each hidden layer's values before and after the activation
    at::Tensor a = x;
    for (int64_t l = 0; l < layers; ++l) {
      at::Tensor z = at::addmm(all[num_inputs + 2 * l + 1], a, all[num_inputs + 2 * l].t());
      if (l + 1 == layers) {
        a = z;
        break;
      }
      at::Tensor h = at::empty_like(z);
      activate_out(h, z, act);
      pre.push_back(z);
      post.push_back(h);
      a = h;
    }
    const at::Tensor y = tanh_output ? at::tanh(a) : a;
    // The inputs and weights go through save_for_backward, so that changing one in place between the two
    // passes is an error, as for any autograd op; the intermediates are this node's own.
    ctx->save_for_backward(all.vec());
    ctx->saved_data["x"] = x;
    ctx->saved_data["pre"] = pre;
    ctx->saved_data["post"] = post;
    ctx->saved_data["y"] = y;
    ctx->saved_data["num_inputs"] = num_inputs;
    ctx->saved_data["hidden"] = hidden;
    ctx->saved_data["tanh_output"] = tanh_output;
    ctx->saved_data["residual"] = residual;
    return residual ? y + all[0] : y;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    const variable_list saved = ctx->get_saved_variables();
    const int64_t num_inputs = ctx->saved_data["num_inputs"].toInt();
    const auto act = static_cast<Activation>(ctx->saved_data["hidden"].toInt());
    const at::Tensor x = ctx->saved_data["x"].toTensor();
    const std::vector<at::Tensor> pre = ctx->saved_data["pre"].toTensorVector();
    const std::vector<at::Tensor> post = ctx->saved_data["post"].toTensorVector();
    const int64_t layers = (static_cast<int64_t>(saved.size()) - num_inputs) / 2;
    bool inputs_need = false;
    for (int64_t i = 0; i < num_inputs; ++i)
      inputs_need = inputs_need || ctx->needs_input_grad(i);

    // One slot per forward argument: the variables, then the four settings (no gradient).
    variable_list out(saved.size() + 4);
    const at::Tensor& grad_out = grads[0];
    at::Tensor g = ctx->saved_data["tanh_output"].toBool()
                       ? at::tanh_backward(grad_out, ctx->saved_data["y"].toTensor())
                       : grad_out;
    for (int64_t l = layers - 1; l >= 0; --l) {
      const size_t w = static_cast<size_t>(num_inputs + 2 * l);
      const at::Tensor& below = l == 0 ? x : post[l - 1];
      if (ctx->needs_input_grad(w)) out[w] = g.t().mm(below);
      if (ctx->needs_input_grad(w + 1)) out[w + 1] = g.sum(0);
      if (l == 0 && !inputs_need) break;
      bool lower_weights_need = inputs_need;
      for (int64_t k = 0; k < 2 * l && !lower_weights_need; ++k)
        lower_weights_need = ctx->needs_input_grad(num_inputs + k);
      if (!lower_weights_need) break;
      g = g.mm(saved[w]);  // a new tensor: the in-place activation backward below cannot touch grad_out
      if (l > 0) {
        at::Tensor scratch = at::empty_like(pre[l - 1]);
        activation_backward_(g, pre[l - 1], post[l - 1], act, scratch);
      }
    }
    if (inputs_need) {
      int64_t offset = 0;
      for (int64_t i = 0; i < num_inputs; ++i) {
        const int64_t width = saved[i].size(1);
        if (ctx->needs_input_grad(i)) {
          at::Tensor gi = num_inputs == 1 ? g : g.narrow(1, offset, width);
          out[i] = (i == 0 && ctx->saved_data["residual"].toBool()) ? gi + grad_out : gi;
        }
        offset += width;
      }
    }
    return out;
  }
};

}  // namespace

at::Tensor dense_chain(const DenseChain& chain, at::TensorList inputs) {
  check(!chain.layers.empty(), "dense_chain: the chain has no layers");
  check(!inputs.empty(), "dense_chain: no inputs");
  int64_t width = 0;
  for (const at::Tensor& x : inputs) {
    check(x.dim() == 2 && x.size(0) == inputs[0].size(0), "dense_chain: inputs must be [B, in_i] with one B");
    width += x.size(1);
  }
  const int64_t in = chain.layers.front()->weight.size(1), out = chain.layers.back()->weight.size(0);
  check(width == in, "dense_chain: the inputs have {} columns, the first layer takes {}", width, in);
  check(!chain.residual || inputs[0].size(1) == out,
        "dense_chain: a residual needs the first input as wide as the output ({} against {})",
        inputs[0].size(1), out);
  std::vector<at::Tensor> all(inputs.begin(), inputs.end());
  for (const torch::nn::Linear& layer : chain.layers) {
    check(layer->bias.defined(), "dense_chain: every layer needs a bias");
    all.push_back(layer->weight);
    all.push_back(layer->bias);
  }
  return DenseChainNode::apply(at::TensorList(all), static_cast<int64_t>(inputs.size()),
                               static_cast<int64_t>(chain.hidden), chain.tanh_output, chain.residual);
}

}  // namespace hlt
