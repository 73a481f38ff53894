// Linked into every hlt executable (the `hlt_preinit` object library): process settings that must be made
// before anything else runs.
//
// 1. The allocator keeps what it has: LibTorch allocates and frees tensors of 128 KiB and more on every
//    op of a training step, and glibc's defaults hand such blocks back to the kernel (mmap, heap trimming),
//    so every step paid for page faults and page clearing (11 % of an agent step's time in the kernel).
//    A larger mmap threshold and trim threshold keep them in the heap. A value set through GLIBC_TUNABLES
//    or MALLOC_*_ wins (glibc reads those first; mallopt here is skipped when they are set).
//
// 2. OpenBLAS's kernel, chosen before OpenBLAS's load-time constructor reads OPENBLAS_CORETYPE. See
//    hlt/util/blas_kernel.h for the rule.
//
// Why a re-exec: functions in .preinit_array run before every shared library's constructor, but a setenv()
// made there does not survive, because libc's own initialisation (which runs after them) resets `environ` to
// the array the kernel passed in. So where the variable is unset and the CPU allows a better core, the
// process re-executes itself once with the variable added, before any constructor has run: that costs the
// dynamic loader's ~25 ms, not LibTorch's start-up. The new process finds the variable set and goes on.
#include <malloc.h>
#include <unistd.h>

#include <cstring>
#include <string>
#include <vector>

#include "hlt/util/blas_kernel.h"

namespace {

bool defines(const char* entry, const char* name) {
  const size_t len = std::strlen(name);
  return std::strncmp(entry, name, len) == 0 && entry[len] == '=';
}

bool has_variable(char** envp, const char* name) {
  for (char** e = envp; e != nullptr && *e != nullptr; ++e)
    if (defines(*e, name)) return true;
  return false;
}

void configure_allocator(char** envp) {
  if (has_variable(envp, "GLIBC_TUNABLES") || has_variable(envp, "MALLOC_MMAP_THRESHOLD_") ||
      has_variable(envp, "MALLOC_TRIM_THRESHOLD_"))
    return;
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
}

void choose_blas_kernel(char** argv, char** envp) {
  if (has_variable(envp, hlt::kOpenBlasCoreVar)) return;
  const std::string core = hlt::choose_openblas_core();
  if (core.empty()) return;
  const std::string set = std::string(hlt::kOpenBlasCoreVar) + "=" + core;
  const std::string note = std::string(hlt::kHltSetCoreVar) + "=" + core;
  std::vector<char*> env;
  for (char** e = envp; *e != nullptr; ++e)
    if (!defines(*e, hlt::kHltSetCoreVar)) env.push_back(*e);  // a stale note would mislabel the origin
  env.push_back(const_cast<char*>(set.c_str()));
  env.push_back(const_cast<char*>(note.c_str()));
  env.push_back(nullptr);
  ::execve("/proc/self/exe", argv, env.data());
  // Only reached if the exec failed (no /proc, say): OpenBLAS's own choice stands, and blas_kernel() says so.
}

void hlt_preinit(int, char** argv, char** envp) {
  choose_blas_kernel(argv, envp);  // may re-execute the process, which then passes here again
  configure_allocator(envp);
}

__attribute__((section(".preinit_array"), used)) void (*const hlt_preinit_entry)(int, char**,
                                                                                 char**) = &hlt_preinit;

}  // namespace
