// The vector kernels (hlt/simd/vector_math.h), every instruction set this CPU runs: sin and cos within
// SLEEF's 3.5-ulp bound of the double-precision value, bias passes equal to the scalar formula on every row
// length (so every tail path runs), NaN propagated by ReLU, padding left alone.
#include <gtest/gtest.h>
#include <unistd.h>

#include <climits>
#include <cstdio>
#include <cstdlib>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <torch/torch.h>

#include "hlt/simd/vector_math.h"
#include "hlt/util/error.h"
#include "support/subprocess.h"

namespace hlt {
namespace {

// Restores the default instruction set after each test.
class VectorMath : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override { use_vector_isa(GetParam()); }
  void TearDown() override { use_vector_isa(supported_vector_isas().front()); }
};

// The distance between |y| and the next float up: one unit in the last place at y.
double ulp(double y) {
  const float a = std::fabs(static_cast<float>(y));
  return std::nextafter(a, std::numeric_limits<float>::infinity()) - a;
}

std::vector<float> test_points(int64_t n) {
  std::vector<float> x(n);
  for (int64_t i = 0; i < n; ++i)
    x[i] = static_cast<float>(std::sin(0.7 * i) * 40.0 + 0.01 * i);
  return x;
}

TEST_P(VectorMath, SinAndCosAreWithinSleefsBoundOnEveryLength) {
  EXPECT_EQ(std::string(vector_isa()), GetParam());
  double worst = 0;
  for (int64_t n : {0, 1, 3, 4, 5, 7, 8, 9, 15, 16, 17, 31, 33, 1000}) {
    const std::vector<float> x = test_points(n);
    std::vector<float> s(n + 1, 7.0f), c(n + 1, 7.0f);
    vector_sin(x.data(), s.data(), n);
    vector_cos(x.data(), c.data(), n);
    for (int64_t i = 0; i < n; ++i) {
      const double rs = std::sin(static_cast<double>(x[i])), rc = std::cos(static_cast<double>(x[i]));
      EXPECT_LE(std::fabs(s[i] - rs), 3.5 * ulp(rs)) << "sin(" << x[i] << "), n = " << n;
      EXPECT_LE(std::fabs(c[i] - rc), 3.5 * ulp(rc)) << "cos(" << x[i] << "), n = " << n;
      worst = std::max(worst, std::fabs(s[i] - rs) / ulp(rs));
    }
    EXPECT_EQ(s[n], 7.0f) << "wrote past the end, n = " << n;
    EXPECT_EQ(c[n], 7.0f) << "wrote past the end, n = " << n;
  }
  EXPECT_GT(worst, 0.0) << "the test points should not all be exact";
}

TEST_P(VectorMath, SinInPlaceEqualsSinIntoAnotherBuffer) {
  std::vector<float> x = test_points(37), y(37);
  vector_sin(x.data(), y.data(), 37);
  vector_sin(x.data(), x.data(), 37);
  EXPECT_EQ(x, y);
}

float reference(float v, BiasThen f) {
  if (f == BiasThen::kRelu) return v > 0 ? v : 0.0f;
  if (f == BiasThen::kSin) return static_cast<float>(std::sin(static_cast<double>(v)));
  return v;
}

TEST_P(VectorMath, BiasPassesMatchTheScalarFormulaOnEveryShape) {
  for (BiasThen f : {BiasThen::kNothing, BiasThen::kRelu, BiasThen::kSin}) {
    for (int64_t cols = 0; cols <= 37; ++cols) {
      for (int64_t pad : {0, 3}) {
        const int64_t rows = 3, ld = cols + pad;
        const std::vector<float> x0 = test_points(rows * ld);
        const std::vector<float> row_bias = {0.5f, -1.25f, 3.0f};
        std::vector<float> col_bias = test_points(cols + 1);
        std::vector<float> by_row = x0, by_col = x0;
        bias_rows(by_row.data(), rows, cols, ld, row_bias.data(), f);
        bias_cols(by_col.data(), rows, cols, ld, col_bias.data(), f);
        for (int64_t r = 0; r < rows; ++r) {
          for (int64_t c = 0; c < ld; ++c) {
            const float x = x0[r * ld + c];
            const std::string where = "row " + std::to_string(r) + " col " + std::to_string(c) + " of " +
                                      std::to_string(cols) + " (ld " + std::to_string(ld) + ")";
            if (c >= cols) {
              EXPECT_EQ(by_row[r * ld + c], x) << "padding changed at " << where;
              EXPECT_EQ(by_col[r * ld + c], x) << "padding changed at " << where;
              continue;
            }
            const float er = reference(x + row_bias[r], f), ec = reference(x + col_bias[c], f);
            const double tol = f == BiasThen::kSin ? 3.5 * ulp(er) : 0.0;
            EXPECT_LE(std::fabs(by_row[r * ld + c] - er), tol) << "bias_rows at " << where;
            EXPECT_LE(std::fabs(by_col[r * ld + c] - ec), f == BiasThen::kSin ? 3.5 * ulp(ec) : 0.0)
                << "bias_cols at " << where;
          }
        }
      }
    }
  }
}

TEST_P(VectorMath, ReluPropagatesNanAndClampsInfinities) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  // Long enough for whole registers, 4-lane chunks and scalars on every instruction set.
  std::vector<float> x(23, -1.0f);
  for (int64_t i = 0; i < 23; i += 3)
    x[i] = nan;
  x[1] = inf;
  x[2] = -inf;
  std::vector<float> by_row = x, by_col = x, zero(23, 0.0f);
  bias_rows(by_row.data(), 1, 23, 23, zero.data(), BiasThen::kRelu);
  bias_cols(by_col.data(), 1, 23, 23, zero.data(), BiasThen::kRelu);
  for (int64_t i = 0; i < 23; ++i) {
    for (const std::vector<float>* y : {&by_row, &by_col}) {
      if (i % 3 == 0) {
        EXPECT_TRUE(std::isnan((*y)[i])) << "NaN at " << i << " was hidden";
      } else {
        EXPECT_EQ((*y)[i], i == 1 ? inf : 0.0f) << "at " << i;
      }
    }
  }
}

TEST_P(VectorMath, ReluGradientKeepsTheGradientWhereTheOutputIsPositive) {
  for (int64_t n : {0, 1, 5, 16, 23, 40}) {
    const std::vector<float> y = test_points(n);
    std::vector<float> g = test_points(n + 1);
    const std::vector<float> g0 = g;
    relu_gradient(y.data(), g.data(), n);
    for (int64_t i = 0; i < n; ++i)
      EXPECT_EQ(g[i], y[i] > 0 ? g0[i] : 0.0f) << "at " << i << " of " << n;
    EXPECT_EQ(g[n], g0[n]) << "wrote past the end";
  }
}

TEST_P(VectorMath, TransposeCopiesEveryElementAndNothingElse) {
  for (int64_t rows : {1, 3, 4, 8, 13, 16, 37}) {
    for (int64_t cols : {1, 5, 8, 9, 16, 40}) {
      const int64_t lds = cols + 2, ldd = rows + 3;
      const std::vector<float> src = test_points(rows * lds);
      std::vector<float> dst(cols * ldd, -7.0f);
      transpose_copy(src.data(), rows, cols, lds, dst.data(), ldd);
      for (int64_t c = 0; c < cols; ++c)
        for (int64_t r = 0; r < ldd; ++r)
          EXPECT_EQ(dst[c * ldd + r], r < rows ? src[r * lds + c] : -7.0f)
              << rows << " x " << cols << " at (" << r << ", " << c << ")";
    }
  }
}

// torch.optim.Adam's float arithmetic, one value at a time, in the order the kernel promises.
void adam_reference(float& p, float g, float& m, float& v, const AdamCoefficients& c) {
  m = m * c.b1 + c.c1 * g;
  v = v * c.b2 + (c.c2 * g) * g;
  const float denom = std::sqrt(v) * c.inv_sqrt_bc2 + c.eps;
  p = p - (c.step_size * m) / denom;
}

TEST_P(VectorMath, AdamStepGivesTheScalarArithmeticsBitsOnEveryLength) {
  const AdamCoefficients c{0.9f, 0.1f, 0.999f, 0.001f, 1.3f, 1e-8f, 3e-4f};
  for (int64_t n : {1, 7, 16, 33, 100}) {
    std::vector<float> p = test_points(n), m(n, 0.01f), v(n, 0.02f);
    const std::vector<float> g = test_points(n + 3);
    std::vector<float> rp = p, rm = m, rv = v;
    for (int step = 0; step < 3; ++step) {
      adam_step(p.data(), g.data() + 3, m.data(), v.data(), n, c);
      for (int64_t i = 0; i < n; ++i)
        adam_reference(rp[i], g[i + 3], rm[i], rv[i], c);
    }
    EXPECT_EQ(p, rp) << "n = " << n;
    EXPECT_EQ(m, rm) << "n = " << n;
    EXPECT_EQ(v, rv) << "n = " << n;
  }
}

TEST_P(VectorMath, LerpIsAtensArithmeticInBothBranchesOnEveryLength) {
  const bool fused = GetParam() != "sse2";
  for (float w : {0.005f, -0.3f, 0.7f, 1.0f}) {
    for (int64_t n : {1, 7, 16, 33, 100}) {
      std::vector<float> self = test_points(n);
      const std::vector<float> end = test_points(n + 5);
      std::vector<float> expected(n);
      for (int64_t i = 0; i < n; ++i) {
        const float s = self[i], e = end[i + 5], d = e - s;
        if (std::abs(w) < 0.5f) {
          expected[i] = fused ? std::fma(w, d, s) : s + w * d;
        } else {
          expected[i] = fused ? std::fma(-d, 1.0f - w, e) : e - d * (1.0f - w);
        }
      }
      // ATen's lerp_ on the same values agrees to within one rounding of the product.
      at::Tensor aten = torch::tensor(self);
      aten.lerp_(torch::tensor(std::vector<float>(end.begin() + 5, end.end())), w);
      lerp(self.data(), end.data() + 5, w, n);
      EXPECT_EQ(self, expected) << "w = " << w << ", n = " << n;
      for (int64_t i = 0; i < n; ++i)
        EXPECT_NEAR(self[i], aten[i].item<float>(), 1e-6f * (1.0f + std::abs(self[i])));
    }
  }
}

INSTANTIATE_TEST_SUITE_P(EverySupportedSet, VectorMath, ::testing::ValuesIn(supported_vector_isas()),
                         [](const auto& info) { return info.param; });

TEST(VectorMathChoice, TheWidestSupportedSetIsTheDefaultAndUnknownNamesAreRefused) {
  const std::vector<std::string> isas = supported_vector_isas();
  ASSERT_FALSE(isas.empty());
  EXPECT_EQ(isas.back(), "sse2");  // every x86-64 CPU
  EXPECT_EQ(std::string(vector_isa()), isas.front());
  try {
    use_vector_isa("neon");
    FAIL() << "an unknown instruction set was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'neon'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("sse2"), std::string::npos) << e.what();
  }
}

// Not a test of its own: prints this process's instruction set for the test below, which runs it as a child.
TEST(VectorMathChoice, ReportForParent) {
  if (std::getenv("HLT_VECTOR_REPORT") == nullptr) GTEST_SKIP() << "runs only as a child of the test below";
  std::printf("isa=%s\n", vector_isa());
}

// This binary with HLT_VECTOR_ISA set to `value`: its exit status and what it printed.
test::Result child_with(const std::string& value) {
  char self[PATH_MAX] = {};
  EXPECT_GT(::readlink("/proc/self/exe", self, sizeof self - 1), 0);
  return test::run("env HLT_VECTOR_ISA=" + value + " HLT_VECTOR_REPORT=1 " + self +
                   " --gtest_filter=VectorMathChoice.ReportForParent");
}

TEST(VectorMathChoice, TheEnvironmentVariableOverridesTheChoiceAndIsChecked) {
  const auto [status, out] = child_with("sse2");
  EXPECT_EQ(status, 0) << out;
  EXPECT_NE(out.find("isa=sse2"), std::string::npos) << out;
  const auto [bad_status, bad_out] = child_with("neon");
  EXPECT_NE(bad_status, 0) << bad_out;
  EXPECT_NE(bad_out.find("HLT_VECTOR_ISA: vector instruction set 'neon'"), std::string::npos) << bad_out;
}

}  // namespace
}  // namespace hlt
