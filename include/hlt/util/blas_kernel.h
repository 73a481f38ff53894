// Which OpenBLAS kernel the process runs, and the rule that picks it before OpenBLAS loads.
//
// Debian 12's OpenBLAS 0.3.21 picks its kernels from the CPU model in its load-time constructor; on CPUs it
// does not know (Intel family 6 model 207, for one) it falls back to its SSE3 `Prescott` kernels, 3-6x
// slower than the AVX-512 ones. Every hlt executable links `src/preinit/process_preinit.cpp`, an ELF
// `.preinit_array` entry that runs before any shared library's constructor and, where OPENBLAS_CORETYPE is
// unset, re-executes the process once with it set from the CPU's features (choose_openblas_core). A value
// set by the user or the machine is never changed.
#pragma once

#include <string>

namespace hlt {

// Environment variables: OpenBLAS's own, and the note hlt leaves when it set that one (so that a child
// process, which inherits both, still reports where the value came from).
inline constexpr const char* kOpenBlasCoreVar = "OPENBLAS_CORETYPE";
inline constexpr const char* kHltSetCoreVar = "HLT_SET_OPENBLAS_CORETYPE";

// The OpenBLAS core for the CPU this runs on: "SkylakeX" with AVX-512 F, CD, BW, DQ and VL (all enabled by
// the OS), "Haswell" with AVX2 and FMA, "" otherwise (leave OpenBLAS's own choice). These are the kernel
// families OpenBLAS itself chooses on the CPUs it recognises with those features.
std::string choose_openblas_core();

// OpenBLAS's generic or pre-AVX2 fall-back cores (what it runs when it does not recognise a CPU).
bool is_fallback_openblas_core(const std::string& core);

struct BlasKernel {
  bool openblas = false;  // an OpenBLAS is loaded in this process
  std::string core;       // openblas_get_corename(), e.g. "SkylakeX"
  std::string config;     // openblas_get_config(), e.g. "OpenBLAS 0.3.21 DYNAMIC_ARCH NO_AFFINITY ..."
  std::string origin;     // how the core was chosen: "OpenBLAS's CPU detection", "OPENBLAS_CORETYPE=... set
                          // by hlt (...)", "OPENBLAS_CORETYPE=... set in the environment"
  // One line for logs and benchmark contexts: "OpenBLAS 0.3.21 ..., core SkylakeX (origin)".
  std::string summary() const;
};

// What the running process uses (looked up in the loaded libraries; no link dependency on OpenBLAS).
BlasKernel blas_kernel();

}  // namespace hlt
