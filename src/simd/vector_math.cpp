// The SSE2 kernels (every x86-64 CPU has SSE2) and the choice of the kernel table.
#include <emmintrin.h>
#include <xmmintrin.h>

#include <sleef.h>
#include <cstdlib>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "hlt/util/error.h"
#include "kernels.h"
#include "table.h"

namespace hlt {
namespace {

struct Sse2 {
  using Reg = __m128;
  static constexpr int kWidth = 4;
  static Reg load(const float* p) { return _mm_loadu_ps(p); }
  static void store(float* p, Reg v) { _mm_storeu_ps(p, v); }
  // The first n < 4 lanes (SSE2 has no masked moves; the others are zero on load and untouched on store).
  static Reg load_partial(const float* p, int64_t n) {
    alignas(16) float lanes[4] = {0, 0, 0, 0};
    for (int64_t i = 0; i < n; ++i)
      lanes[i] = p[i];
    return _mm_load_ps(lanes);
  }
  static void store_partial(float* p, Reg v, int64_t n) {
    alignas(16) float lanes[4];
    _mm_store_ps(lanes, v);
    for (int64_t i = 0; i < n; ++i)
      p[i] = lanes[i];
  }
  static constexpr int64_t kTile = 4;
  static void transpose_tile(const float* src, int64_t lds, float* dst, int64_t ldd) {
    __m128 r0 = _mm_loadu_ps(src), r1 = _mm_loadu_ps(src + lds), r2 = _mm_loadu_ps(src + 2 * lds),
           r3 = _mm_loadu_ps(src + 3 * lds);
    _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
    _mm_storeu_ps(dst, r0);
    _mm_storeu_ps(dst + ldd, r1);
    _mm_storeu_ps(dst + 2 * ldd, r2);
    _mm_storeu_ps(dst + 3 * ldd, r3);
  }
  static Reg set1(float a) { return _mm_set1_ps(a); }
  static Reg zero() { return _mm_setzero_ps(); }
  static Reg add(Reg a, Reg b) { return _mm_add_ps(a, b); }
  static Reg sub(Reg a, Reg b) { return _mm_sub_ps(a, b); }
  static Reg mul(Reg a, Reg b) { return _mm_mul_ps(a, b); }
  // a b + c and c - a b; SSE2 has no fused multiply-add, so the product is rounded first.
  static Reg fmadd(Reg a, Reg b, Reg c) { return _mm_add_ps(_mm_mul_ps(a, b), c); }
  static Reg fnmadd(Reg a, Reg b, Reg c) { return _mm_sub_ps(c, _mm_mul_ps(a, b)); }
  static Reg div(Reg a, Reg b) { return _mm_div_ps(a, b); }
  static Reg sqrt(Reg a) { return _mm_sqrt_ps(a); }
  // g where y > 0, else +0.
  static Reg keep_where_positive(Reg y, Reg g) { return _mm_and_ps(_mm_cmpgt_ps(y, zero()), g); }
  static Reg max(Reg a, Reg b) { return _mm_max_ps(a, b); }
  static Reg sin(Reg a) { return Sleef_sinf4_u35sse2(a); }
  static Reg cos(Reg a) { return Sleef_cosf4_u35sse2(a); }
};

// The widest instruction set the CPU has, first.
std::vector<const VectorKernelTable*> supported() {
  __builtin_cpu_init();
  std::vector<const VectorKernelTable*> tables;
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("fma")) tables.push_back(&avx512_kernels());
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) tables.push_back(&avx2_kernels());
  tables.push_back(&sse2_kernels());
  return tables;
}

const VectorKernelTable* by_name(const std::string& isa) {
  for (const VectorKernelTable* t : supported())
    if (isa == t->isa) return t;
  throw Error(fmt::format("vector instruction set '{}' is not one this CPU runs; it runs: {}", isa,
                          fmt::join(supported_vector_isas(), ", ")));
}

// HLT_VECTOR_ISA, where set, overrides the choice (to reproduce on this CPU the numbers of a narrower one).
const VectorKernelTable*& current() {
  static const VectorKernelTable* table = [] {
    const char* forced = std::getenv("HLT_VECTOR_ISA");
    if (forced == nullptr || *forced == '\0') return supported().front();
    try {
      return by_name(forced);
    } catch (const Error& e) {
      throw Error(fmt::format("HLT_VECTOR_ISA: {}", e.what()));
    }
  }();
  return table;
}

const VectorKernelTable& chosen() {
  return *current();
}

}  // namespace

const VectorKernelTable& sse2_kernels() {
  static const VectorKernelTable table = make_table<Kernels<Sse2>>("sse2");
  return table;
}

void bias_rows(float* x, int64_t rows, int64_t cols, int64_t ld, const float* bias, BiasThen f) {
  chosen().bias_rows(x, rows, cols, ld, bias, f);
}
void bias_cols(float* x, int64_t rows, int64_t cols, int64_t ld, const float* bias, BiasThen f) {
  chosen().bias_cols(x, rows, cols, ld, bias, f);
}
void vector_sin(const float* x, float* out, int64_t n) {
  chosen().sin(x, out, n);
}
void vector_cos(const float* x, float* out, int64_t n) {
  chosen().cos(x, out, n);
}
void relu_gradient(const float* y, float* g, int64_t n) {
  chosen().relu_gradient(y, g, n);
}
void transpose_copy(const float* src, int64_t rows, int64_t cols, int64_t lds, float* dst, int64_t ldd) {
  chosen().transpose(src, rows, cols, lds, dst, ldd);
}
void adam_step(float* p, const float* g, float* m, float* v, int64_t n, const AdamCoefficients& c) {
  chosen().adam_step(p, g, m, v, n, c);
}
void lerp(float* self, const float* end, float weight, int64_t n) {
  chosen().lerp(self, end, weight, n);
}
const char* vector_isa() {
  return chosen().isa;
}

void use_vector_isa(const std::string& isa) {
  current() = by_name(isa);
}

std::vector<std::string> supported_vector_isas() {
  std::vector<std::string> names;
  for (const VectorKernelTable* t : supported())
    names.emplace_back(t->isa);
  return names;
}

}  // namespace hlt
