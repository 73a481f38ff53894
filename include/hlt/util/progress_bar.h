// hlt::ProgressBar: one terminal line of progress (steps, a few named values, rate, ETA), redrawn at most a
// few times a second. It prints nothing when stderr is not a terminal (CI, redirected logs).
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace hlt {

class ProgressBar {
 public:
  // `start` is the step the run begins at (non-zero when resuming), `total` the step it ends at.
  ProgressBar(int64_t start, int64_t total, bool enabled);
  static bool stderr_is_terminal();

  void set(const std::string& name, double value);
  void update(int64_t step);  // redraws if enough time has passed
  void finish();

 private:
  void draw();
  int64_t start_, total_, step_;
  bool enabled_;
  std::vector<std::pair<std::string, double>> values_;
  std::chrono::steady_clock::time_point t0_, last_draw_;
};

}  // namespace hlt
