// The kernels of hlt/simd/vector_math.h written once over an instruction set's traits (register type, loads,
// stores, SLEEF's sin and cos). Each vector_math_<isa>.cpp includes this with its own traits and compiler
// flags; everything here has internal linkage, so no code built for one instruction set is shared with
// another by the linker.
#pragma once

#include <emmintrin.h>

#include <cmath>
#include <cstdint>
#include <type_traits>

#include "hlt/simd/vector_math.h"

namespace hlt {
namespace {

// What a bias pass does after adding the bias, applied to one register.
template <typename V, BiasThen F>
typename V::Reg after_bias(typename V::Reg v) {
  if constexpr (F == BiasThen::kRelu)
    return V::max(V::zero(), v);  // this order propagates NaN (the second operand wins)
  if constexpr (F == BiasThen::kSin) return V::sin(v);
  return v;
}

// Calls g with the bias pass as a std::integral_constant, so that the pass is fixed at compile time (no
// branch per register).
template <typename G>
void with_bias_then(BiasThen f, G&& g) {
  switch (f) {
    case BiasThen::kRelu:
      return g(std::integral_constant<BiasThen, BiasThen::kRelu>{});
    case BiasThen::kSin:
      return g(std::integral_constant<BiasThen, BiasThen::kSin>{});
    default:
      return g(std::integral_constant<BiasThen, BiasThen::kNothing>{});
  }
}

// Applies g (register to register) to in[0, n), into out: whole registers, then the last 0 < r < kWidth
// values through the traits' partial (masked) load and store.
template <typename V, typename G>
void map_span(const float* in, float* out, int64_t n, G&& g) {
  int64_t i = 0;
  for (; i + V::kWidth <= n; i += V::kWidth)
    V::store(out + i, g(V::load(in + i)));
  if (i < n) V::store_partial(out + i, g(V::load_partial(in + i, n - i)), n - i);
}

template <typename V>
struct Kernels {
  static void bias_rows(float* x, int64_t rows, int64_t cols, int64_t ld, const float* bias, BiasThen f) {
    if (f == BiasThen::kSin) {
      bias_rows(x, rows, cols, ld, bias, BiasThen::kNothing);
      // One sin pass over the whole block where it is contiguous: short rows would each end in a partial
      // register.
      if (ld == cols) {
        sin(x, x, rows * cols);
      } else {
        for (int64_t r = 0; r < rows; ++r)
          sin(x + r * ld, x + r * ld, cols);
      }
      return;
    }
    const bool relu = f == BiasThen::kRelu;
    for (int64_t r = 0; r < rows; ++r) {
      float* row = x + r * ld;
      const typename V::Reg b = V::set1(bias[r]), zero = V::zero();
      int64_t c = 0;
      for (; c + V::kWidth <= cols; c += V::kWidth) {
        const typename V::Reg v = V::add(V::load(row + c), b);
        V::store(row + c, relu ? V::max(zero, v) : v);  // this order propagates NaN
      }
      // The rest of a short row in 4-lane registers and scalars: measured at K = 20, a masked wide
      // register per row costs three times this.
      const __m128 b4 = _mm_set1_ps(bias[r]), zero4 = _mm_setzero_ps();
      for (; c + 4 <= cols; c += 4) {
        const __m128 v = _mm_add_ps(_mm_loadu_ps(row + c), b4);
        _mm_storeu_ps(row + c, relu ? _mm_max_ps(zero4, v) : v);
      }
      for (; c < cols; ++c) {
        const float v = row[c] + bias[r];
        row[c] = relu && v < 0.0f ? 0.0f : v;
      }
    }
  }
  static void bias_cols(float* x, int64_t rows, int64_t cols, int64_t ld, const float* bias, BiasThen f) {
    with_bias_then(f, [&](auto then) {
      for (int64_t r = 0; r < rows; ++r) {
        float* row = x + r * ld;
        int64_t c = 0;
        for (; c + V::kWidth <= cols; c += V::kWidth)
          V::store(row + c,
                   after_bias<V, decltype(then)::value>(V::add(V::load(row + c), V::load(bias + c))));
        if (c < cols) {
          const int64_t r = cols - c;
          V::store_partial(row + c,
                           after_bias<V, decltype(then)::value>(
                               V::add(V::load_partial(row + c, r), V::load_partial(bias + c, r))),
                           r);
        }
      }
    });
  }
  static void sin(const float* x, float* out, int64_t n) {
    map_span<V>(x, out, n, [](typename V::Reg v) { return V::sin(v); });
  }
  static void cos(const float* x, float* out, int64_t n) {
    map_span<V>(x, out, n, [](typename V::Reg v) { return V::cos(v); });
  }
  static void transpose(const float* src, int64_t rows, int64_t cols, int64_t lds, float* dst, int64_t ldd) {
    constexpr int64_t T = V::kTile;
    const int64_t full_rows = rows - rows % T, full_cols = cols - cols % T;
    for (int64_t r = 0; r < full_rows; r += T)
      for (int64_t c = 0; c < full_cols; c += T)
        V::transpose_tile(src + r * lds + c, lds, dst + c * ldd + r, ldd);
    // The edges, element by element.
    for (int64_t r = 0; r < rows; ++r)
      for (int64_t c = r < full_rows ? full_cols : 0; c < cols; ++c)
        dst[c * ldd + r] = src[r * lds + c];
  }
  static void relu_gradient(const float* y, float* g, int64_t n) {
    int64_t i = 0;
    for (; i + V::kWidth <= n; i += V::kWidth)
      V::store(g + i, V::keep_where_positive(V::load(y + i), V::load(g + i)));
    if (i < n)
      V::store_partial(
          g + i, V::keep_where_positive(V::load_partial(y + i, n - i), V::load_partial(g + i, n - i)), n - i);
  }
  static void adam_step(float* p, const float* g, float* m, float* v, int64_t n, const AdamCoefficients& c) {
    const typename V::Reg b1 = V::set1(c.b1), c1 = V::set1(c.c1), b2 = V::set1(c.b2), c2 = V::set1(c.c2),
                          inv = V::set1(c.inv_sqrt_bc2), eps = V::set1(c.eps), lr = V::set1(c.step_size);
    const auto one = [&](int64_t i, int64_t width) {
      const bool whole = width == V::kWidth;
      const auto load = [&](const float* q) {
        return whole ? V::load(q + i) : V::load_partial(q + i, width);
      };
      const auto store = [&](float* q, typename V::Reg r) {
        whole ? V::store(q + i, r) : V::store_partial(q + i, r, width);
      };
      const typename V::Reg gi = load(g);
      const typename V::Reg mi = V::add(V::mul(load(m), b1), V::mul(c1, gi));
      const typename V::Reg vi = V::add(V::mul(load(v), b2), V::mul(V::mul(c2, gi), gi));
      store(m, mi);
      store(v, vi);
      store(p, V::sub(load(p), V::div(V::mul(lr, mi), V::add(V::mul(V::sqrt(vi), inv), eps))));
    };
    int64_t i = 0;
    for (; i + V::kWidth <= n; i += V::kWidth)
      one(i, V::kWidth);
    if (i < n) one(i, n - i);
  }
  static void lerp(float* self, const float* end, float w, int64_t n) {
    const bool near_self = std::abs(w) < 0.5f;
    const typename V::Reg wv = V::set1(near_self ? w : 1.0f - w);
    const auto one = [&](typename V::Reg s, typename V::Reg e) {
      const typename V::Reg d = V::sub(e, s);
      return near_self ? V::fmadd(wv, d, s) : V::fnmadd(d, wv, e);
    };
    int64_t i = 0;
    for (; i + V::kWidth <= n; i += V::kWidth)
      V::store(self + i, one(V::load(self + i), V::load(end + i)));
    if (i < n)
      V::store_partial(self + i, one(V::load_partial(self + i, n - i), V::load_partial(end + i, n - i)),
                       n - i);
  }
};

}  // namespace
}  // namespace hlt
