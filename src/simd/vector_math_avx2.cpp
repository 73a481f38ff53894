// The kernels for AVX2 + FMA (this file is compiled with -mavx2 -mfma; it runs only where the CPU has them).
#include <immintrin.h>
#include <sleef.h>

#include "kernels.h"
#include "table.h"
#include "transpose_avx.h"

namespace hlt {
namespace {

struct Avx2 {
  using Reg = __m256;
  static constexpr int kWidth = 8;
  static Reg load(const float* p) { return _mm256_loadu_ps(p); }
  static void store(float* p, Reg v) { _mm256_storeu_ps(p, v); }
  // The first n < 8 lanes; the others are zero on load and untouched on store.
  static __m256i first(int64_t n) {
    static const int32_t ones_then_zeros[16] = {-1, -1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, 0};
    return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(ones_then_zeros + 8 - n));
  }
  static Reg load_partial(const float* p, int64_t n) { return _mm256_maskload_ps(p, first(n)); }
  static void store_partial(float* p, Reg v, int64_t n) { _mm256_maskstore_ps(p, first(n), v); }
  // 8 x 8 tiles in 256-bit registers (transpose_avx.h).
  static constexpr int64_t kTile = 8;
  static void transpose_tile(const float* src, int64_t lds, float* dst, int64_t ldd) {
    transpose_tile_8x8(src, lds, dst, ldd);
  }
  static Reg set1(float a) { return _mm256_set1_ps(a); }
  static Reg zero() { return _mm256_setzero_ps(); }
  static Reg add(Reg a, Reg b) { return _mm256_add_ps(a, b); }
  static Reg sub(Reg a, Reg b) { return _mm256_sub_ps(a, b); }
  static Reg mul(Reg a, Reg b) { return _mm256_mul_ps(a, b); }
  // a b + c and c - a b, each rounded once.
  static Reg fmadd(Reg a, Reg b, Reg c) { return _mm256_fmadd_ps(a, b, c); }
  static Reg fnmadd(Reg a, Reg b, Reg c) { return _mm256_fnmadd_ps(a, b, c); }
  static Reg div(Reg a, Reg b) { return _mm256_div_ps(a, b); }
  static Reg sqrt(Reg a) { return _mm256_sqrt_ps(a); }
  // g where y > 0, else +0.
  static Reg keep_where_positive(Reg y, Reg g) {
    return _mm256_and_ps(_mm256_cmp_ps(y, zero(), _CMP_GT_OQ), g);
  }
  static Reg max(Reg a, Reg b) { return _mm256_max_ps(a, b); }
  static Reg sin(Reg a) { return Sleef_sinf8_u35avx2(a); }
  static Reg cos(Reg a) { return Sleef_cosf8_u35avx2(a); }
};

}  // namespace

const VectorKernelTable& avx2_kernels() {
  static const VectorKernelTable table = make_table<Kernels<Avx2>>("avx2");
  return table;
}

}  // namespace hlt
