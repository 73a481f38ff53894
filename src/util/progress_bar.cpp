#include "hlt/util/progress_bar.h"

#include <unistd.h>

#include <cstdio>

#include <fmt/format.h>

namespace hlt {

ProgressBar::ProgressBar(int64_t start, int64_t total, bool enabled)
    : start_(start), total_(total), step_(start), enabled_(enabled) {
  t0_ = last_draw_ = std::chrono::steady_clock::now();
}

bool ProgressBar::stderr_is_terminal() {
  return ::isatty(STDERR_FILENO) == 1;
}

void ProgressBar::set(const std::string& name, double value) {
  for (auto& kv : values_) {
    if (kv.first == name) {
      kv.second = value;
      return;
    }
  }
  values_.emplace_back(name, value);
}

void ProgressBar::update(int64_t step) {
  step_ = step;
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_draw_ < std::chrono::milliseconds(200) && step_ < total_) return;
  last_draw_ = now;
  draw();
}

void ProgressBar::draw() {
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  const double rate = elapsed > 0 ? (step_ - start_) / elapsed : 0.0;
  const double eta = rate > 0 ? (total_ - step_) / rate : 0.0;
  const double frac = total_ > 0 ? static_cast<double>(step_) / total_ : 1.0;
  const int width = 24;
  const int filled = static_cast<int>(frac * width);
  std::string bar = std::string(filled, '#') + std::string(width - filled, '-');
  std::string extra;
  for (const auto& [name, value] : values_)
    extra += fmt::format(" {} {:.4g}", name, value);
  fmt::print(stderr, "\r[{}] {}/{}{} | {:.1f} steps/s | ETA {:02d}:{:02d}\033[K", bar, step_, total_, extra,
             rate, static_cast<int>(eta) / 60, static_cast<int>(eta) % 60);
  std::fflush(stderr);
}

void ProgressBar::finish() {
  if (!enabled_) return;
  draw();
  fmt::print(stderr, "\n");
}

}  // namespace hlt
