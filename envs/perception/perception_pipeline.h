// hlt::PerceptionPipeline: one camera frame in, the task state out. Tag detection and pose, then the
// state estimator, which falls back to colour tracking of the block (only computed when the block's tag is
// missing). Also formats its results as CSV rows, for hlt_perceive and for logging in the robot tasks.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "envs/perception/camera_model.h"
#include "envs/perception/colour_tracker.h"
#include "envs/perception/state_estimator.h"
#include "envs/perception/tag_config.h"
#include "envs/perception/tag_detector.h"

namespace hlt {

struct PerceptionOptions {
  TagDetectorOptions detector;
  StateEstimatorOptions estimator;
  bool colour_fallback = true;
  ColourTrackerOptions colour;
};

struct FrameResult {
  double time = 0.0;
  TagDetectionResult detections;
  std::optional<ColourBlob> colour;  // set when colour tracking ran on this frame
  TaskState state;
  double detect_ms = 0.0;  // tag detection and pose estimation
  double total_ms = 0.0;   // everything in process()
};

class PerceptionPipeline {
 public:
  PerceptionPipeline(CameraModel camera, TagConfig config, PerceptionOptions options = {});

  const FrameResult& process(const cv::Mat& image, double time);
  const FrameResult& last() const { return last_; }
  const CameraModel& camera() const { return camera_; }
  const TagConfig& config() const { return config_; }
  void reset() { estimator_.reset(); }
  // The estimator, e.g. to snapshot its filter (StateEstimator::save/restore).
  const StateEstimator& estimator() const { return estimator_; }
  StateEstimator& estimator() { return estimator_; }

  // One row per frame: time, counts, and for each object its table-frame position, yaw and status, then the
  // task vector. The header names the objects tracked (the pushing task's by default).
  static std::string states_csv_header(const std::vector<std::string>& objects = {"block", "target",
                                                                                  "end_effector"});
  static std::string states_csv_row(const FrameResult& r);
  // One row per detected tag per frame: id, name, quality, camera-frame pose, corners.
  static std::string detections_csv_header();
  static std::string detections_csv_rows(const FrameResult& r);

 private:
  CameraModel camera_;
  TagConfig config_;
  PerceptionOptions options_;
  TagDetector detector_;
  ColourTracker colour_;
  StateEstimator estimator_;
  FrameResult last_;
};

}  // namespace hlt
