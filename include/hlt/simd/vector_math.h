// Vectorised elementwise kernels for the float hot loops of the planners and learners: SLEEF's sin and cos
// (at most 3.5 ulp of error) and the bias passes that follow a layer's matrix product. Each is compiled for
// AVX-512, AVX2 + FMA and SSE2; the widest set the CPU supports is chosen once, at first use.
//
// Why not ATen's sin: it runs SLEEF's 1-ulp AVX2 kernel behind a dispatched op, which at the planners' sizes
// (a few thousand values per layer) costs about four times the AVX-512 3.5-ulp kernel called directly.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace hlt {

// What a bias pass does after adding the bias.
enum class BiasThen { kNothing, kRelu, kSin };

// x[r * ld + c] = f(x[r * ld + c] + bias[r]) for r < rows, c < cols (a feature-major batch: one row per
// unit). Preconditions: ld >= cols; bias has `rows` values.
void bias_rows(float* x, int64_t rows, int64_t cols, int64_t ld, const float* bias, BiasThen f);
// x[r * ld + c] = f(x[r * ld + c] + bias[c]) (a sample-major batch: one row per sample).
void bias_cols(float* x, int64_t rows, int64_t cols, int64_t ld, const float* bias, BiasThen f);

// out[i] = sin(x[i]) or cos(x[i]) for i < n; out may equal x.
void vector_sin(const float* x, float* out, int64_t n);
void vector_cos(const float* x, float* out, int64_t n);

// dst[c * ldd + r] = src[r * lds + c] for r < rows, c < cols: a transposed copy, in register tiles (a
// planner call transposes every weight; done element by element this was a tenth of a small call).
void transpose_copy(const float* src, int64_t rows, int64_t cols, int64_t lds, float* dst, int64_t ldd);

// g[i] = y[i] > 0 ? g[i] : 0: ReLU's backward pass from its output y (exact on every instruction set).
void relu_gradient(const float* y, float* g, int64_t n);

// One Adam step over flat buffers, torch.optim.Adam's float arithmetic in its order, without fused
// multiply-adds (so every instruction set gives the same bits): m = b1 m + c1 g, v = b2 v + c2 g g,
// p -= step_size m / (sqrt(v) inv_sqrt_bc2 + eps).
struct AdamCoefficients {
  float b1, c1, b2, c2, inv_sqrt_bc2, eps, step_size;
};
void adam_step(float* p, const float* g, float* m, float* v, int64_t n, const AdamCoefficients& c);

// self += weight (end - self) in place, ATen's lerp_ arithmetic: self + weight (end - self) for |weight| <
// 0.5, else end - (end - self) (1 - weight), each as one fused multiply-add on AVX2 and AVX-512 (where
// ATen's own lerp kernel, a scalar loop in LibTorch 1.13, contracts to the same instruction), a rounded
// product and an add on SSE2. The target networks' Polyak average.
void lerp(float* self, const float* end, float weight, int64_t n);

// The instruction set in use: "avx512", "avx2" or "sse2".
const char* vector_isa();
// Uses the named instruction set's kernels from now on (tests and benchmarks compare them); throws
// hlt::Error for an unknown name or one the CPU lacks. Not to be called while other threads run kernels.
void use_vector_isa(const std::string& isa);
// The instruction sets this CPU can run, widest first.
std::vector<std::string> supported_vector_isas();

}  // namespace hlt
