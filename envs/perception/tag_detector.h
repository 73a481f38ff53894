// hlt::TagDetector: finds AprilTags with libapriltag and estimates each configured tag's pose with
// libapriltag's estimate_tag_pose, after removing lens distortion from the detected corners. Tags whose
// ids are not in the TagConfig are reported by id only (no size is known, so no pose).
//
// Poses are camera_from_tag in the hlt tag frame (x right, y towards the printed top edge, z out of the
// face); libapriltag's own frame (y down, z into the tag) is converted. Corners and centres are in OpenCV
// pixel coordinates (centre of the top-left pixel at (0, 0)) of the input image, distortion included.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "envs/perception/camera_model.h"
#include "envs/perception/tag_config.h"
#include "envs/perception/tag_corner_refiner.h"
#include "envs/perception/tag_family.h"

struct apriltag_detector;

namespace hlt {

struct TagDetection {
  int id = 0;
  std::string name;
  double size = 0.0;
  // Corners at tag-frame (-s/2, -s/2), (s/2, -s/2), (s/2, s/2), (-s/2, s/2): bottom-left, bottom-right,
  // top-right, top-left of the printed tag.
  std::array<cv::Point2d, 4> corners;
  cv::Point2d centre;
  double decision_margin = 0.0;  // libapriltag's decoding margin (higher is more certain)
  int hamming = 0;               // bits corrected
  Eigen::Isometry3d camera_from_tag = Eigen::Isometry3d::Identity();
  double pose_error = 0.0;          // estimate_tag_pose's object-space error (m^2)
  double reprojection_error = 0.0;  // RMS distance of the reprojected corners from the detected ones (pixels)
  bool refined = false;             // corners came from TagCornerRefiner (else libapriltag's own)
};

struct TagDetectionResult {
  std::vector<TagDetection> tags;  // configured tags, at most one per id (the most certain)
  std::vector<int> unknown_ids;    // detected ids that are not in the config
  int duplicates = 0;              // extra detections of a configured id that were dropped
};

struct TagDetectorOptions {
  // libapriltag quad_decimate: quads are found in an image this many times smaller (corners are refined at
  // full resolution). 1.5 still finds 0.033 m tags at 0.8 m tilted by 40 degrees and halves the time of 1.0;
  // at 2.0 that case is lost.
  double quad_decimate = 1.5;
  double quad_sigma = 0.0;     // Gaussian blur before quad detection (pixels)
  bool refine_edges = true;    // libapriltag's own edge refinement (whole-pixel)
  bool refine_corners = true;  // then TagCornerRefiner's sub-pixel refinement
  int threads = 1;
  int max_hamming = 1;              // detections with more corrected bits are dropped
  double min_decision_margin = 15;  // and with a lower margin
};

class TagDetector {
 public:
  TagDetector(CameraModel camera, TagConfig config, TagDetectorOptions options = {});
  ~TagDetector();
  TagDetector(const TagDetector&) = delete;
  TagDetector& operator=(const TagDetector&) = delete;

  // Accepts CV_8UC1 (grey), CV_8UC3 (BGR) or CV_8UC4 (BGRA) of the camera's size; anything else throws.
  TagDetectionResult detect(const cv::Mat& image);

  const CameraModel& camera() const { return camera_; }
  const TagConfig& config() const { return config_; }
  const TagDetectorOptions& options() const { return options_; }

 private:
  CameraModel camera_;
  TagConfig config_;
  TagDetectorOptions options_;
  std::unique_ptr<TagFamily> family_;
  std::unique_ptr<TagCornerRefiner> refiner_;
  apriltag_detector* detector_ = nullptr;
  cv::Mat grey_;
};

}  // namespace hlt
