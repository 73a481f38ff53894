// hlt::CheckerboardCalibrator: intrinsic calibration from views of a printed checkerboard, with OpenCV's
// chessboard detector and calibrateCamera. Add images one by one (views where the board is not found are
// recorded as rejected), then calibrate to get a CameraModel, the RMS reprojection error and per-view errors.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "envs/perception/camera_model.h"

namespace hlt {

struct CalibrationResult {
  CameraModel camera;
  double rms = 0.0;                  // RMS reprojection error over all corners (pixels)
  std::vector<double> per_view_rms;  // in the order of `used`
  std::vector<std::string> used, rejected;
};

class CheckerboardCalibrator {
 public:
  // `inner_corners`: corners where four squares meet (columns x rows, e.g. 9x6 for a 10x7-square board);
  // `square_size`: edge of one square in metres.
  CheckerboardCalibrator(cv::Size inner_corners, double square_size);

  // Returns whether the board was found. The first image fixes the image size; others must match.
  bool add_image(const cv::Mat& image, const std::string& name);
  size_t views() const { return image_points_.size(); }
  const std::vector<std::string>& rejected() const { return rejected_; }

  // OpenCV calibration flags (e.g. cv::CALIB_FIX_K3). Needs at least 3 views.
  CalibrationResult calibrate(int flags) const;

 private:
  cv::Size pattern_;
  double square_;
  cv::Size image_size_;
  std::vector<std::vector<cv::Point2f>> image_points_;
  std::vector<std::string> used_, rejected_;
};

}  // namespace hlt
