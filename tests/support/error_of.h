// The message of the hlt::Error a call throws, or "" if it throws none: what tests of error messages assert
// on.
#pragma once

#include <functional>
#include <string>

#include "hlt/util/error.h"

namespace hlt::testing {

inline std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace hlt::testing
