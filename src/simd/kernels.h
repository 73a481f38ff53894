// The kernels of hlt/simd/vector_math.h written once over an instruction set's traits (register type, loads,
// stores, SLEEF's sin and cos). Each vector_math_<isa>.cpp includes this with its own traits and compiler
// flags; everything here has internal linkage, so no code built for one instruction set is shared with
// another by the linker.
#pragma once

#include <emmintrin.h>

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

// Calls g.template operator()<F>() with the bias pass F as a compile-time constant (no branch per register).
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
      // One sin pass over the whole block where it is contiguous: a planner's rows (K samples) are often
      // shorter than two registers.
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
};

}  // namespace
}  // namespace hlt
