// The kernels for AVX-512 (this file is compiled with -mavx512f -mfma; it runs only where the CPU has them).
#include <immintrin.h>
#include <sleef.h>

#include "kernels.h"
#include "table.h"
#include "transpose_avx.h"

namespace hlt {
namespace {

struct Avx512 {
  using Reg = __m512;
  static constexpr int kWidth = 16;
  static Reg load(const float* p) { return _mm512_loadu_ps(p); }
  static void store(float* p, Reg v) { _mm512_storeu_ps(p, v); }
  // The first n < 16 lanes; the others are zero on load and untouched on store.
  static __mmask16 first(int64_t n) { return static_cast<__mmask16>((1u << n) - 1); }
  static Reg load_partial(const float* p, int64_t n) { return _mm512_maskz_loadu_ps(first(n), p); }
  static void store_partial(float* p, Reg v, int64_t n) { _mm512_mask_storeu_ps(p, first(n), v); }
  // 8 x 8 tiles in 256-bit registers (transpose_avx.h).
  static constexpr int64_t kTile = 8;
  static void transpose_tile(const float* src, int64_t lds, float* dst, int64_t ldd) {
    transpose_tile_8x8(src, lds, dst, ldd);
  }
  static Reg set1(float a) { return _mm512_set1_ps(a); }
  static Reg zero() { return _mm512_setzero_ps(); }
  static Reg add(Reg a, Reg b) { return _mm512_add_ps(a, b); }
  static Reg sub(Reg a, Reg b) { return _mm512_sub_ps(a, b); }
  static Reg mul(Reg a, Reg b) { return _mm512_mul_ps(a, b); }
  // a b + c and c - a b, each rounded once.
  static Reg fmadd(Reg a, Reg b, Reg c) { return _mm512_fmadd_ps(a, b, c); }
  static Reg fnmadd(Reg a, Reg b, Reg c) { return _mm512_fnmadd_ps(a, b, c); }
  static Reg div(Reg a, Reg b) { return _mm512_div_ps(a, b); }
  static Reg sqrt(Reg a) { return _mm512_maskz_sqrt_ps(0xFFFF, a); }  // see max()
  // g where y > 0, else +0.
  static Reg keep_where_positive(Reg y, Reg g) {
    return _mm512_maskz_mov_ps(_mm512_cmp_ps_mask(y, zero(), _CMP_GT_OQ), g);
  }
  // The masked form: _mm512_max_ps trips GCC 12's -Wmaybe-uninitialized (its _mm512_undefined_ps).
  static Reg max(Reg a, Reg b) { return _mm512_maskz_max_ps(0xFFFF, a, b); }
  static Reg sin(Reg a) { return Sleef_sinf16_u35avx512f(a); }
  static Reg cos(Reg a) { return Sleef_cosf16_u35avx512f(a); }
};

}  // namespace

const VectorKernelTable& avx512_kernels() {
  static const VectorKernelTable table = make_table<Kernels<Avx512>>("avx512");
  return table;
}

}  // namespace hlt
