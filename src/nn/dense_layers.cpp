#include "hlt/nn/dense_layers.h"

#include <ATen/ATen.h>
#include <c10/core/InferenceMode.h>

#include "hlt/util/error.h"

namespace hlt {

void dense_forward(at::Tensor& out, const at::Tensor& x, const at::Tensor& weight, const at::Tensor& bias) {
  at::addmm_out(out, bias, x, weight.t());
}

void dense_backward(const at::Tensor& grad_out, const at::Tensor& x, const at::Tensor& weight,
                    at::Tensor& grad_weight, at::Tensor& grad_bias, at::Tensor* grad_x) {
  at::mm_out(grad_weight, grad_out.t(), x);
  at::sum_out(grad_bias, grad_out, {0});
  if (grad_x != nullptr) at::mm_out(*grad_x, grad_out, weight);
}

at::Tensor empty_buffer() {
  return at::empty({0});
}

void match_buffers(std::initializer_list<at::Tensor*> buffers, const at::Tensor& like) {
  for (at::Tensor* b : buffers)
    if (b->scalar_type() != like.scalar_type()) *b = at::empty({0}, like.options());
}

at::Tensor& sized(at::Tensor& buffer, at::IntArrayRef sizes) {
  if (buffer.sizes() != sizes) buffer.resize_(sizes);
  return buffer;
}

at::Tensor& gradient_of(at::Tensor& parameter) {
  if (!parameter.grad().defined()) parameter.mutable_grad() = at::zeros_like(parameter);
  return parameter.mutable_grad();
}

DenseStack::DenseStack(const torch::nn::ModuleList& layers, Activation hidden) : hidden_(hidden) {
  check(layers->size() > 0, "DenseStack needs at least one layer");
  for (size_t i = 0; i < layers->size(); ++i)
    layers_.emplace_back(layers->ptr<torch::nn::LinearImpl>(i));
  const size_t hidden_layers = layers_.size() - 1;
  for (size_t i = 0; i < hidden_layers; ++i) {
    pre_.push_back(empty_buffer());
    post_.push_back(empty_buffer());
    grad_.push_back(empty_buffer());
  }
}

const at::Tensor& DenseStack::forward(const at::Tensor& x) {
  c10::InferenceMode guard;  // no graph is needed, and the buffers stay in one mode
  input_ = x;
  const at::Tensor* in = &input_;
  for (size_t i = 0; i + 1 < layers_.size(); ++i) {
    dense_forward(pre_[i], *in, layers_[i]->weight, layers_[i]->bias);
    activate_out(post_[i], pre_[i], hidden_);
    in = &post_[i];
  }
  dense_forward(output_, *in, layers_.back()->weight, layers_.back()->bias);
  return output_;
}

void DenseStack::backward(at::Tensor& grad_out) {
  c10::InferenceMode guard;
  at::Tensor* g = &grad_out;
  for (size_t i = layers_.size(); i-- > 0;) {
    auto& layer = layers_[i];
    const at::Tensor& in = i == 0 ? input_ : post_[i - 1];
    at::Tensor* grad_in = i == 0 ? nullptr : &grad_[i - 1];
    dense_backward(*g, in, layer->weight, gradient_of(layer->weight), gradient_of(layer->bias), grad_in);
    if (grad_in != nullptr) {
      activation_backward_(*grad_in, pre_[i - 1], post_[i - 1], hidden_, scratch_);
      g = grad_in;
    }
  }
}

}  // namespace hlt
