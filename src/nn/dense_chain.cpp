#include "hlt/nn/dense_chain.h"

#include <dlfcn.h>

#include <cmath>
#include <type_traits>

#include <torch/torch.h>

#include "hlt/nn/activation.h"
#include "hlt/nn/batched_forward.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

using torch::autograd::AutogradContext;
using torch::autograd::variable_list;

// The Fortran BLAS gemm the process already has (LibTorch's own products go through it), looked up at run
// time rather than linked: calling it directly skips ATen's dispatcher, whose cost per op is several times a
// product's at these sizes. Null if the process has none (then the products go through ATen).
template <typename T>
using GemmFn = void (*)(const char*, const char*, const int*, const int*, const int*, const T*, const T*,
                        const int*, const T*, const int*, const T*, T*, const int*);
template <typename T>
GemmFn<T> blas_gemm() {
  static const GemmFn<T> fn =
      reinterpret_cast<GemmFn<T>>(dlsym(RTLD_DEFAULT, std::is_same_v<T, float> ? "sgemm_" : "dgemm_"));
  return fn;
}

// Row-major C [M, N] = alpha op(A) op(B) + beta C, where op(A) is [M, K] and op(B) is [K, N]; lda, ldb and
// ldc are row strides. A row-major matrix is its transpose in column-major order, so this is BLAS's
// C^T = op(B)^T op(A)^T.
template <typename T>
void gemm(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, const T* A, int64_t lda, const T* B,
          int64_t ldb, T beta, T* C, int64_t ldc) {
  if (M == 0 || N == 0) return;
  const T alpha = 1;
  if (GemmFn<T> fn = blas_gemm<T>()) {
    const char ta = trans_b ? 'T' : 'N', tb = trans_a ? 'T' : 'N';
    const int m = static_cast<int>(N), n = static_cast<int>(M), k = static_cast<int>(K);
    const int la = static_cast<int>(ldb), lb = static_cast<int>(lda), lc = static_cast<int>(ldc);
    fn(&ta, &tb, &m, &n, &k, &alpha, B, &la, A, &lb, &beta, C, &lc);
    return;
  }
  const auto dtype = std::is_same_v<T, float> ? at::kFloat : at::kDouble;
  auto view = [&](const T* p, int64_t rows, int64_t cols, int64_t ld, bool trans) {
    at::Tensor t = at::from_blob(const_cast<T*>(p), {rows, cols}, {ld, 1}, at::TensorOptions().dtype(dtype));
    return trans ? t.t() : t;
  };
  at::Tensor c = view(C, M, N, ldc, false);
  at::addmm_out(c, c, view(A, trans_a ? K : M, trans_a ? M : K, lda, trans_a),
                view(B, trans_b ? N : K, trans_b ? K : N, ldb, trans_b), beta, alpha);
}

// The settings that travel from the forward to the backward pass, packed into one saved integer.
constexpr int64_t kTanh = 1, kResidual = 2, kSin = 4;

// The autograd node. Its variables are the inputs, then W_1, b_1, ..., W_L, b_L; edge i of the node is
// variable i, which is what needs_input_grad(i) asks about.
struct DenseChainNode : torch::autograd::Function<DenseChainNode> {
  static at::Tensor forward(AutogradContext* ctx, at::TensorList all, int64_t num_inputs, int64_t flags) {
    const auto act = (flags & kSin) ? Activation::kSin : Activation::kRelu;
    const int64_t layers = (static_cast<int64_t>(all.size()) - num_inputs) / 2;
    const int64_t B = all[0].size(0);
    const auto opts = all[0].options().requires_grad(false);
    // The network's values, each [B, width] and contiguous: the input, then each hidden layer's value
    // before and after its activation, then the output layer's.
    std::vector<at::Tensor> values;
    values.reserve(2 * layers);
    at::Tensor out;
    dispatch_floating(all[0], [&](auto tag) {
      using T = decltype(tag);
      at::Tensor x;
      if (num_inputs == 1 && all[0].is_contiguous()) {
        x = all[0];
      } else {
        int64_t width = 0;
        for (int64_t i = 0; i < num_inputs; ++i)
          width += all[i].size(1);
        x = at::empty({B, width}, opts);
        auto xm = row_map<T>(x);
        int64_t offset = 0;
        for (int64_t i = 0; i < num_inputs; ++i) {
          const at::Tensor xi = all[i].stride(1) == 1 ? all[i] : all[i].contiguous();
          xm.middleCols(offset, xi.size(1)) = row_map<T>(xi);
          offset += xi.size(1);
        }
      }
      values.push_back(x);
      for (int64_t l = 0; l < layers; ++l) {
        const at::Tensor& w = all[num_inputs + 2 * l];
        const at::Tensor& b = all[num_inputs + 2 * l + 1];
        const at::Tensor& below = values.back();
        const int64_t fan_out = w.size(0), fan_in = w.size(1);
        at::Tensor z = at::empty({B, fan_out}, opts);
        row_map<T>(z).rowwise() =
            Eigen::Map<const Eigen::Matrix<T, 1, Eigen::Dynamic>>(b.data_ptr<T>(), fan_out);
        gemm<T>(false, true, B, fan_out, fan_in, below.data_ptr<T>(), fan_in, w.data_ptr<T>(), fan_in, T(1),
                z.data_ptr<T>(), fan_out);
        values.push_back(z);
        if (l + 1 < layers) {
          at::Tensor h = at::empty({B, fan_out}, opts);
          activate_values(z.data_ptr<T>(), h.data_ptr<T>(), z.numel(), act);
          values.push_back(h);
        }
      }
      at::Tensor& last = values.back();
      if (flags & kTanh) {
        at::Tensor y = at::empty_like(last);
        row_map<T>(y) = row_map<T>(last).array().tanh().matrix();
        values.push_back(y);
      }
      if (flags & kResidual) {
        const at::Tensor x0 = all[0].stride(1) == 1 ? all[0] : all[0].contiguous();
        out = at::empty_like(values.back());
        row_map<T>(out) = row_map<T>(values.back()) + row_map<T>(x0);
      } else if (flags & kTanh) {
        out = values.back().clone();
      } else {
        out = values.back();
        values.pop_back();
      }
    });
    // The inputs and weights go through save_for_backward, so that changing one in place between the two
    // passes is an error, as for any autograd op; the values are this node's own.
    ctx->save_for_backward(all.vec());
    ctx->saved_data["values"] = values;
    ctx->saved_data["setup"] = num_inputs * 8 + flags;
    // The node must not hold its own output: output -> grad_fn -> saved values -> output is a reference cycle
    // that leaks the whole graph. So tanh's y, which the backward pass reads, was cloned, and the last
    // layer's z, which it does not read, was dropped.
    return out;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    const variable_list saved = ctx->get_saved_variables();
    const int64_t setup = ctx->saved_data["setup"].toInt();
    const int64_t num_inputs = setup / 8, flags = setup % 8;
    const auto act = (flags & kSin) ? Activation::kSin : Activation::kRelu;
    const std::vector<at::Tensor> values = ctx->saved_data["values"].toTensorVector();
    const int64_t layers = (static_cast<int64_t>(saved.size()) - num_inputs) / 2;
    bool inputs_need = false;
    for (int64_t i = 0; i < num_inputs; ++i)
      inputs_need = inputs_need || ctx->needs_input_grad(i);

    // One slot per forward argument: the variables, then the two settings (no gradient).
    variable_list result(saved.size() + 2);
    const at::Tensor grad_out = grads[0].contiguous();
    const int64_t B = grad_out.size(0);
    const auto opts = grad_out.options();
    dispatch_floating(grad_out, [&](auto tag) {
      using T = decltype(tag);
      // g: the gradient of the current layer's pre-activation value z_l, [B, width of layer l].
      at::Tensor g;
      if (flags & kTanh) {
        const at::Tensor& y = values.back();
        g = at::empty_like(grad_out);
        row_map<T>(g) = (row_map<T>(grad_out).array() * (T(1) - row_map<T>(y).array().square())).matrix();
      } else {
        g = grad_out;
      }
      for (int64_t l = layers - 1; l >= 0; --l) {
        const size_t wi = static_cast<size_t>(num_inputs + 2 * l);
        const at::Tensor& w = saved[wi];
        const int64_t fan_out = w.size(0), fan_in = w.size(1);
        const at::Tensor& below = values[2 * l];  // the input of layer l (after the activation below it)
        if (ctx->needs_input_grad(wi)) {
          at::Tensor gw = at::empty({fan_out, fan_in}, opts);
          gemm<T>(true, false, fan_out, fan_in, B, g.data_ptr<T>(), fan_out, below.data_ptr<T>(), fan_in,
                  T(0), gw.data_ptr<T>(), fan_in);
          result[wi] = gw;
        }
        if (ctx->needs_input_grad(wi + 1)) {
          at::Tensor gb = at::empty({fan_out}, opts);
          sum_rows_into(row_map<T>(g),
                        Eigen::Map<Eigen::Matrix<T, 1, Eigen::Dynamic>>(gb.data_ptr<T>(), fan_out));
          result[wi + 1] = gb;
        }
        bool lower_need = inputs_need;
        for (int64_t k = 0; k < 2 * l && !lower_need; ++k)
          lower_need = ctx->needs_input_grad(num_inputs + k);
        if (!lower_need) break;
        at::Tensor g_below = at::empty({B, fan_in}, opts);
        gemm<T>(false, false, B, fan_in, fan_out, g.data_ptr<T>(), fan_out, w.data_ptr<T>(), fan_in, T(0),
                g_below.data_ptr<T>(), fan_in);
        if (l > 0) {
          // Through layer l - 1's activation: values[2l - 1] is its z, values[2l] its h.
          at::Tensor scratch = act == Activation::kSin ? at::empty({B, fan_in}, opts) : at::Tensor();
          activation_gradient(g_below.data_ptr<T>(), values[2 * l - 1].data_ptr<T>(),
                              values[2 * l].data_ptr<T>(),
                              scratch.defined() ? scratch.data_ptr<T>() : nullptr, g_below.numel(), act);
        }
        g = g_below;
      }
      if (!inputs_need) return;
      int64_t offset = 0;
      for (int64_t i = 0; i < num_inputs; ++i) {
        const int64_t width = saved[i].size(1);
        if (ctx->needs_input_grad(i)) {
          at::Tensor gi = num_inputs == 1 ? g : g.narrow(1, offset, width);
          if (i == 0 && (flags & kResidual)) {
            at::Tensor sum = at::empty({B, width}, opts);
            row_map<T>(sum) = row_map<T>(gi) + row_map<T>(grad_out);
            gi = sum;
          }
          result[i] = gi;
        }
        offset += width;
      }
    });
    return result;
  }
};

}  // namespace

at::Tensor dense_chain(const DenseChain& chain, at::TensorList inputs) {
  check(!chain.layers.empty(), "dense_chain: the chain has no layers");
  check(!inputs.empty(), "dense_chain: no inputs");
  int64_t width = 0;
  for (const at::Tensor& x : inputs) {
    check(x.dim() == 2 && x.size(0) == inputs[0].size(0), "dense_chain: inputs must be [B, in_i] with one B");
    check(x.scalar_type() == chain.layers.front()->weight.scalar_type(),
          "dense_chain: the inputs' dtype must be the layers' ({})",
          std::string(c10::toString(chain.layers.front()->weight.scalar_type())));
    width += x.size(1);
  }
  const int64_t in = chain.layers.front()->weight.size(1), out = chain.layers.back()->weight.size(0);
  check(width == in, "dense_chain: the inputs have {} columns, the first layer takes {}", width, in);
  check(!chain.residual || inputs[0].size(1) == out,
        "dense_chain: a residual needs the first input as wide as the output ({} against {})",
        inputs[0].size(1), out);
  std::vector<at::Tensor> all(inputs.begin(), inputs.end());
  int64_t below = in;
  for (const torch::nn::Linear& layer : chain.layers) {
    check(layer->bias.defined(), "dense_chain: every layer needs a bias");
    check(layer->weight.size(1) == below && layer->weight.is_contiguous(),
          "dense_chain: layer weights must be contiguous and chain ({} inputs where {} come)",
          layer->weight.size(1), below);
    below = layer->weight.size(0);
    all.push_back(layer->weight);
    all.push_back(layer->bias);
  }
  const int64_t flags = (chain.tanh_output ? kTanh : 0) | (chain.residual ? kResidual : 0) |
                        (chain.hidden == Activation::kSin ? kSin : 0);
  return DenseChainNode::apply(at::TensorList(all), static_cast<int64_t>(inputs.size()), flags);
}

}  // namespace hlt
