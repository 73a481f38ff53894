// The table of one instruction set's kernels, and where each set's table comes from.
#pragma once

#include <cstdint>

#include "hlt/simd/vector_math.h"

namespace hlt {

struct VectorKernelTable {
  const char* isa;
  void (*bias_rows)(float*, int64_t, int64_t, int64_t, const float*, BiasThen);
  void (*bias_cols)(float*, int64_t, int64_t, int64_t, const float*, BiasThen);
  void (*sin)(const float*, float*, int64_t);
  void (*cos)(const float*, float*, int64_t);
  void (*relu_gradient)(const float*, float*, int64_t);
  void (*transpose)(const float*, int64_t, int64_t, int64_t, float*, int64_t);
  void (*adam_step)(float*, const float*, float*, float*, int64_t, const AdamCoefficients&);
  void (*lerp)(float*, const float*, float, int64_t);
};

template <typename K>
VectorKernelTable make_table(const char* isa) {
  return {isa,           &K::bias_rows, &K::bias_cols, &K::sin, &K::cos, &K::relu_gradient,
          &K::transpose, &K::adam_step, &K::lerp};
}

// Defined in vector_math_<isa>.cpp; call only where the CPU has the instruction set.
const VectorKernelTable& avx512_kernels();
const VectorKernelTable& avx2_kernels();
const VectorKernelTable& sse2_kernels();

}  // namespace hlt
