#include "hlt/util/main_guard.h"

#include <exception>
#include <new>
#include <string>

#include <fmt/format.h>

#include "hlt/util/error.h"

namespace hlt {
namespace {

// LibTorch's and OpenCV's messages carry a backtrace or a source location after the first line.
std::string first_line(const char* what) {
  std::string s(what != nullptr ? what : "");
  const size_t eol = s.find('\n');
  if (eol != std::string::npos) s.resize(eol);
  return s.empty() ? "(no message)" : s;
}

}  // namespace

int guarded_main(const char* tool, const std::function<int()>& body) {
  try {
    return body();
  } catch (const Error& e) {
    fmt::print(stderr, "{}: error: {}\n", tool, e.what());
    return 2;
  } catch (const std::bad_alloc&) {
    fmt::print(stderr, "{}: error: out of memory (ask for less: a smaller replay capacity, fewer episodes)\n",
               tool);
    return 3;
  } catch (const std::exception& e) {
    fmt::print(stderr, "{}: error: {}\n", tool, first_line(e.what()));
    return 1;
  } catch (...) {
    fmt::print(stderr, "{}: error: unknown exception\n", tool);
    return 1;
  }
}

}  // namespace hlt
