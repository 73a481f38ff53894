// The OpenBLAS kernel rule (hlt/util/blas_kernel.h): the preinit entry linked into this binary picks a
// non-generic core on AVX2/AVX-512 hardware, and a value preset in the environment is left alone.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cctype>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <torch/torch.h>

#include "hlt/util/blas_kernel.h"
#include "support/subprocess.h"

namespace hlt {
namespace {

std::string lower(std::string s) {
  for (char& c : s)
    c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Runs this test binary's ReportForParent case with `env_prefix` (arguments of env(1)) and returns what it
// printed: "core=<name>" and "origin=<text>" lines.
std::string report_of_child(const std::string& env_prefix) {
  char self[PATH_MAX] = {};
  const ssize_t n = ::readlink("/proc/self/exe", self, sizeof self - 1);
  EXPECT_GT(n, 0);
  const test::Result r =
      test::run("env -u " + std::string(kOpenBlasCoreVar) + " -u " + kHltSetCoreVar + " " + env_prefix +
                " HLT_BLAS_REPORT=1 " + self + " --gtest_filter=BlasKernel.ReportForParent");
  EXPECT_EQ(r.code, 0) << r.output;
  return r.output;
}

TEST(BlasKernel, FallbackCoresAreRecognised) {
  EXPECT_TRUE(is_fallback_openblas_core("Prescott"));
  EXPECT_TRUE(is_fallback_openblas_core("prescott"));
  EXPECT_TRUE(is_fallback_openblas_core("Core2"));
  EXPECT_FALSE(is_fallback_openblas_core("SkylakeX"));
  EXPECT_FALSE(is_fallback_openblas_core("Haswell"));
  EXPECT_FALSE(is_fallback_openblas_core("Zen"));
}

// Not a test of its own: prints this process's kernel for the tests below, which run it as a child.
TEST(BlasKernel, ReportForParent) {
  if (std::getenv("HLT_BLAS_REPORT") == nullptr) GTEST_SKIP() << "runs only as a child of the tests below";
  torch::mm(torch::ones({4, 4}), torch::ones({4, 4}));
  const BlasKernel k = blas_kernel();
  std::printf("core=%s\norigin=%s\n", k.core.c_str(), k.origin.c_str());
}

TEST(BlasKernel, NotAGenericFallbackOnAvx2OrAvx512) {
  const std::string best = choose_openblas_core();
  if (best.empty()) GTEST_SKIP() << "this CPU has neither AVX-512 nor AVX2+FMA: OpenBLAS's choice stands";
  const BlasKernel k = blas_kernel();
  if (!k.openblas) GTEST_SKIP() << "the BLAS LibTorch loaded here is not OpenBLAS";
  if (k.origin.find("set in the environment") != std::string::npos)
    GTEST_SKIP() << "OPENBLAS_CORETYPE is preset on this machine (" << k.origin << "); tested in a child";
  EXPECT_FALSE(is_fallback_openblas_core(k.core)) << k.summary();
}

TEST(BlasKernel, UnsetVariableGetsTheBestCoreInAFreshProcess) {
  const std::string best = choose_openblas_core();
  if (best.empty()) GTEST_SKIP() << "this CPU has neither AVX-512 nor AVX2+FMA: OpenBLAS's choice stands";
  if (!blas_kernel().openblas) GTEST_SKIP() << "the BLAS LibTorch loaded here is not OpenBLAS";
  const std::string out = report_of_child("");
  EXPECT_NE(out.find("core=" + best), std::string::npos) << out;
  EXPECT_NE(out.find("set by hlt"), std::string::npos) << out;
}

TEST(BlasKernel, PresetValueIsRespected) {
  if (!blas_kernel().openblas) GTEST_SKIP() << "the BLAS LibTorch loaded here is not OpenBLAS";
#if !defined(__x86_64__)
  GTEST_SKIP() << "Prescott is an x86-64 core";
#endif
  // Prescott (SSE3) runs on every x86-64 CPU and is never what hlt would choose on AVX2 hardware.
  const std::string out = report_of_child("OPENBLAS_CORETYPE=Prescott");
  EXPECT_NE(lower(out).find("core=prescott"), std::string::npos) << out;
  EXPECT_NE(out.find("OPENBLAS_CORETYPE=Prescott set in the environment"), std::string::npos) << out;
}

}  // namespace
}  // namespace hlt
