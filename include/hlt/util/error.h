// hlt::Error: the one exception type the project throws for bad input and failed I/O. Its message is meant
// for the user: it names the offending key, file or value and, where there is a closed set, the allowed ones.
#pragma once

#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace hlt {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// Throws hlt::Error with a fmt-formatted message when `condition` is false.
template <typename... Args>
void check(bool condition, fmt::format_string<Args...> format, Args&&... args) {
  if (!condition) throw Error(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace hlt
