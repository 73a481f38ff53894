// hlt_bench's main: Google Benchmark's, plus the facts a timing means nothing without (the CPU model and
// the OpenBLAS kernel in use) in the report's context, and the checks Google Benchmark 1.7 leaves out.
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

#include <benchmark/benchmark.h>

#include "hlt/simd/vector_math.h"
#include "hlt/util/blas_kernel.h"
#include "hlt/util/error.h"
#include "hlt/util/main_guard.h"

namespace {

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line, name, family, model;
  while (std::getline(in, line)) {
    auto value = [&] { return line.substr(line.find(':') + 2); };
    if (name.empty() && line.rfind("model name", 0) == 0) name = value();
    if (family.empty() && line.rfind("cpu family", 0) == 0) family = value();
    if (model.empty() && line.rfind("model\t", 0) == 0) model = value();
  }
  return name + " (family " + family + ", model " + model + ")";
}

// The value of --NAME=VALUE in argv, or nullptr.
const char* flag_value(int argc, char** argv, const char* name) {
  const size_t n = std::strlen(name);
  const char* value = nullptr;  // the last one counts, as in Google Benchmark
  for (int i = 1; i < argc; ++i)
    if (std::strncmp(argv[i], "--", 2) == 0 && std::strncmp(argv[i] + 2, name, n) == 0 &&
        argv[i][2 + n] == '=')
      value = argv[i] + 3 + n;
  return value;
}

// Google Benchmark 1.7 takes a NaN or negative minimum time (and then times one iteration, or none) and a
// negative repetition count (std::length_error: an abort). Values it cannot parse it reports itself.
void check_flags(int argc, char** argv) {
  for (const char* name : {"benchmark_min_time", "benchmark_min_warmup_time"}) {
    const char* v = flag_value(argc, argv, name);
    if (v == nullptr) continue;
    char* end = nullptr;
    const double x = std::strtod(v, &end);
    if (end == v || *end != '\0') continue;
    const bool warmup = std::strcmp(name, "benchmark_min_warmup_time") == 0;
    hlt::check(std::isfinite(x) && (warmup ? x >= 0 : x > 0), "--{} must be a finite number {} 0, got '{}'",
               name, warmup ? ">=" : ">", v);
  }
  // Google Benchmark exits 1 from inside on an unwritable --benchmark_out: refused here as bad input.
  if (const char* out = flag_value(argc, argv, "benchmark_out")) {
    std::ofstream probe(out, std::ios::app);
    hlt::check(probe.is_open(), "--benchmark_out: cannot write {}: {}", out, std::strerror(errno));
  }
  if (const char* v = flag_value(argc, argv, "benchmark_repetitions")) {
    char* end = nullptr;
    errno = 0;
    const long n = std::strtol(v, &end, 10);
    if (end != v && *end == '\0')
      hlt::check(errno == 0 && n >= 1, "--benchmark_repetitions must be at least 1, got '{}'", v);
  }
}

}  // namespace

int main(int argc, char** argv) {
  return hlt::guarded_main("hlt_bench", [&] {
    check_flags(argc, argv);
    const char* filter_flag = flag_value(argc, argv, "benchmark_filter");  // Initialize removes it from argv
    const std::string filter = filter_flag != nullptr ? filter_flag : "";
    benchmark::AddCustomContext("cpu", cpu_model());
    benchmark::AddCustomContext("blas", hlt::blas_kernel().summary());
    benchmark::AddCustomContext("vector kernels", hlt::vector_isa());
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 2;  // bad input, as in every tool
    // A filter that matches nothing (or does not compile) runs nothing: that is an error, not a report.
    const size_t ran = benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    hlt::check(ran > 0, "no benchmark matches --benchmark_filter='{}' (--benchmark_list_tests lists them)",
               filter);
    return 0;
  });
}
