#include "hlt/util/blas_kernel.h"

#include <dlfcn.h>

#include <cctype>
#include <cstdlib>

#include <fmt/format.h>

namespace hlt {

std::string choose_openblas_core() {
#if defined(__x86_64__) || defined(__i386__)
  // May run before any constructor (from .preinit_array), so the CPU table is filled here. libgcc's
  // checks include the OS's XSAVE support for the wider registers.
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
      __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
      __builtin_cpu_supports("avx512vl"))
    return "SkylakeX";
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return "Haswell";
#endif
  return "";
}

bool is_fallback_openblas_core(const std::string& core) {
  // Lower-cased names as openblas_get_corename() reports them (0.3.21: "prescott", "core2", ...).
  std::string c;
  for (char ch : core)
    c += static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  for (const char* generic : {"prescott", "core2", "penryn", "dunnington", "nehalem", "atom", "katmai",
                              "coppermine", "northwood", "banias", "athlon", "opteron", "barcelona",
                              "generic", "unknown", "sandybridge", "bulldozer", "piledriver"})
    if (c == generic) return true;
  return false;
}

BlasKernel blas_kernel() {
  BlasKernel k;
  using NameFn = char* (*)();
  auto corename = reinterpret_cast<NameFn>(dlsym(RTLD_DEFAULT, "openblas_get_corename"));
  auto config = reinterpret_cast<NameFn>(dlsym(RTLD_DEFAULT, "openblas_get_config"));
  const char* set = std::getenv(kOpenBlasCoreVar);
  const char* by_hlt = std::getenv(kHltSetCoreVar);
  if (set == nullptr) {
    k.origin = "OpenBLAS's CPU detection";
  } else if (by_hlt != nullptr && std::string(by_hlt) == set) {
    k.origin = fmt::format("{}={} set by hlt from the CPU's features", kOpenBlasCoreVar, set);
  } else {
    k.origin = fmt::format("{}={} set in the environment", kOpenBlasCoreVar, set);
  }
  if (corename == nullptr) {
    k.origin = "no OpenBLAS loaded";
    return k;
  }
  k.openblas = true;
  k.core = corename();
  if (config != nullptr) k.config = config();
  return k;
}

std::string BlasKernel::summary() const {
  if (!openblas) return origin;
  return fmt::format("{}, core {} ({})", config, core, origin);
}

}  // namespace hlt
