// hlt::guarded_main: the one way an executable's main() ends. Whatever the body throws becomes a one-line
// message on stderr naming the tool and what failed, and a non-zero exit: a user never sees an abort with a
// LibTorch or OpenCV stack trace.
#pragma once

#include <functional>

namespace hlt {

// Exit codes: the body's own on return; 2 for hlt::Error (bad input, failed I/O: the message says which);
// 3 when memory ran out; 1 for anything else (a dependency's exception, reported by its first line).
int guarded_main(const char* tool, const std::function<int()>& body);

}  // namespace hlt
