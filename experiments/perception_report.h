// The camera-observed robot tasks' measurement (hlt_rollout --perception, hlt_camera_loop): the
// estimator's error against the simulator over whole episodes, per tracked object, and the time per control
// step split into rendering, perception and the rest (simulation and policy), as CPU time of the thread so
// that a shared core does not inflate it.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "envs/env.h"
#include "envs/robot/camera_observed.h"

namespace hlt {

// The camera-observed task inside `env` (itself, or under a frame skip), or nullptr.
inline const robot::CameraObserved* camera_task(Env& env) {
  if (auto* c = dynamic_cast<const robot::CameraObserved*>(&env)) return c;
  if (auto* f = dynamic_cast<FrameSkip*>(&env)) return camera_task(f->inner());
  return nullptr;
}

inline double thread_cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(pos));
  const size_t j = std::min(i + 1, v.size() - 1);
  return v[i] + (pos - static_cast<double>(i)) * (v[j] - v[i]);
}

inline double mean_of(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v)
    s += x;
  return v.empty() ? 0.0 : s / static_cast<double>(v.size());
}

// --perception: every control step's estimator error (per object) and timings, summarised at the end.
class PerceptionReport {
 public:
  explicit PerceptionReport(const robot::CameraObserved& env)
      : env_(env),
        position_(env.objects().size()),
        yaw_(env.objects().size()),
        misses_(env.objects().size(), 0),
        colour_(env.objects().size(), 0) {}

  // Call as the last thing after each reset and after each step (an episode loop's callbacks): takes the
  // camera's latest frame and, after a step, the control step's CPU and wall time since the previous call
  // (policy, then simulation, rendering, perception), so work a tool does between steps is not counted.
  void after_reset() {
    add(-1.0, -1.0);
    restart_clock();
  }
  void after_step() {
    add(thread_cpu_ms() - cpu_start_,
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall_start_).count());
    restart_clock();
  }

  // Starts the next step's timing again: after work of the tool's own that follows after_step().
  void restart_clock() {
    wall_start_ = std::chrono::steady_clock::now();
    cpu_start_ = thread_cpu_ms();
  }

  // The camera's latest frame; `step_ms` and `wall_ms` are negative after a reset.
  void add(double step_ms, double wall_ms) {
    const robot::PerceptionRecord& r = env_.last_perception();
    for (size_t i = 0; i < position_.size(); ++i) {
      position_[i].push_back(r.position_error[i]);
      yaw_[i].push_back(r.yaw_error[i]);
      if (r.source[i] == EstimateSource::kHeld || r.source[i] == EstimateSource::kNone) ++misses_[i];
      if (r.source[i] == EstimateSource::kColour) ++colour_[i];
    }
    ++frames_;
    if (step_ms >= 0) {
      render_.push_back(r.render_ms);
      perceive_.push_back(r.perceive_ms);
      total_.push_back(step_ms);
      rest_.push_back(std::max(0.0, step_ms - r.render_ms - r.perceive_ms));
      wall_.push_back(wall_ms);
    }
  }

  void print() const {
    fmt::print("perception over {} frames ({} timed control steps), estimate against the simulator:\n",
               frames_, total_.size());
    std::vector<double> all;
    int misses = 0;
    for (size_t i = 0; i < position_.size(); ++i) {
      const TrackedObject& o = env_.objects()[i];
      std::string yaw;
      if (o.planar_height)
        yaw = fmt::format(", yaw mean {:.2f} p95 {:.2f} deg", mean_of(yaw_[i]) * 180 / M_PI,
                          percentile(yaw_[i], 0.95) * 180 / M_PI);
      fmt::print("  {:<13} position mean {:.2f} p95 {:.2f} max {:.2f} mm{}, misses {} ({:.1f}%), colour {}\n",
                 o.name, 1e3 * mean_of(position_[i]), 1e3 * percentile(position_[i], 0.95),
                 1e3 * *std::max_element(position_[i].begin(), position_[i].end()), yaw, misses_[i],
                 100.0 * misses_[i] / frames_, colour_[i]);
      all.insert(all.end(), position_[i].begin(), position_[i].end());
      misses += misses_[i];
    }
    fmt::print("  {:<13} position mean {:.2f} p95 {:.2f} mm, misses {} of {} object-frames ({:.1f}%)\n",
               "all", 1e3 * mean_of(all), 1e3 * percentile(all, 0.95), misses, all.size(),
               100.0 * misses / std::max<size_t>(1, all.size()));
    auto line = [](const char* what, const std::vector<double>& v) {
      fmt::print("  {:<28} median {:6.2f}  p95 {:6.2f}  mean {:6.2f}\n", what, percentile(v, 0.5),
                 percentile(v, 0.95), mean_of(v));
    };
    fmt::print("time per control step (ms of CPU time on this thread; wall time: the last line):\n");
    line("render", render_);
    line("perceive", perceive_);
    line("rest (simulation + policy)", rest_);
    line("total", total_);
    line("total, wall clock", wall_);
  }

 private:
  std::chrono::steady_clock::time_point wall_start_ = std::chrono::steady_clock::now();
  double cpu_start_ = thread_cpu_ms();
  const robot::CameraObserved& env_;
  std::vector<std::vector<double>> position_, yaw_;
  std::vector<int> misses_, colour_;
  int frames_ = 0;
  std::vector<double> render_, perceive_, rest_, total_, wall_;
};

}  // namespace hlt
