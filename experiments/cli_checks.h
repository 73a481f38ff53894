// Checks every tool applies to its parsed command line beyond what CLI11 validates.
#pragma once

#include <cmath>
#include <cstdlib>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "hlt/util/error.h"

namespace hlt {

// CLI11's range validators let NaN through (every comparison with it is false) and accept "inf": a numeric
// flag given a non-finite value is an error naming the flag. Throws hlt::Error.
inline void check_finite_flags(const CLI::App& app) {
  for (const CLI::Option* opt : app.get_options()) {
    if (opt->count() == 0 || opt->get_type_name().find("FLOAT") == std::string::npos) continue;
    for (const std::string& v : opt->results()) {
      const double x = std::strtod(v.c_str(), nullptr);
      check(std::isfinite(x), "{} must be a finite number, got '{}'", opt->get_name(), v);
    }
  }
}

// Parses the command line; returns the exit code when the tool must stop now. CLI11 exits with codes of its
// own (100 and up, one per kind of error), which would break the contract every tool documents (2: bad
// input); --help still exits 0.
inline std::optional<int> parse_command_line(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  return std::nullopt;
}

}  // namespace hlt
