#include "envs/perception/checkerboard_calibrator.h"

#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "envs/perception/image_checks.h"
#include "hlt/util/error.h"

namespace hlt {

CheckerboardCalibrator::CheckerboardCalibrator(cv::Size inner_corners, double square_size)
    : pattern_(inner_corners), square_(square_size) {
  check(inner_corners.width >= 2 && inner_corners.height >= 2,
        "checkerboard: need at least 2x2 inner corners, got {}x{}", inner_corners.width,
        inner_corners.height);
  check(
      inner_corners.width != inner_corners.height,
      "checkerboard: use a board with different numbers of inner corners per side ({}x{} is ambiguous under "
      "rotation)",
      inner_corners.width, inner_corners.height);
  check(std::isfinite(square_size) && square_size > 0, "checkerboard: square size must be positive (metres)");
}

bool CheckerboardCalibrator::add_image(const cv::Mat& image, const std::string& name) {
  const cv::Mat grey = to_grey(image, "CheckerboardCalibrator");
  if (image_size_.empty()) image_size_ = grey.size();
  check(grey.size() == image_size_, "checkerboard image {} is {}x{}, but the first image was {}x{}", name,
        grey.cols, grey.rows, image_size_.width, image_size_.height);
  std::vector<cv::Point2f> corners;
  bool found = cv::findChessboardCornersSB(grey, pattern_, corners,
                                           cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_ACCURACY);
  if (!found) {
    found = cv::findChessboardCorners(grey, pattern_, corners,
                                      cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
    if (found)
      cv::cornerSubPix(grey, corners, cv::Size(5, 5), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 50, 1e-3));
  }
  if (!found) {
    rejected_.push_back(name);
    return false;
  }
  image_points_.push_back(corners);
  used_.push_back(name);
  return true;
}

CalibrationResult CheckerboardCalibrator::calibrate(int flags) const {
  check(image_points_.size() >= 3,
        "calibration needs the board in at least 3 images; found it in {} ({} rejected)",
        image_points_.size(), rejected_.size());
  std::vector<cv::Point3f> board;
  for (int r = 0; r < pattern_.height; ++r)
    for (int c = 0; c < pattern_.width; ++c)
      board.emplace_back(static_cast<float>(c * square_), static_cast<float>(r * square_), 0.0f);
  const std::vector<std::vector<cv::Point3f>> object_points(image_points_.size(), board);
  cv::Mat K, D;
  std::vector<cv::Mat> rvecs, tvecs;
  const double rms =
      cv::calibrateCamera(object_points, image_points_, image_size_, K, D, rvecs, tvecs, flags);
  check(std::isfinite(rms) && cv::checkRange(K) && cv::checkRange(D),
        "calibration failed (non-finite result)");
  std::vector<double> dist(D.begin<double>(), D.end<double>());
  CalibrationResult result{CameraModel(image_size_.width, image_size_.height, K.at<double>(0, 0),
                                       K.at<double>(1, 1), K.at<double>(0, 2), K.at<double>(1, 2), dist),
                           rms,
                           {},
                           used_,
                           rejected_};
  for (size_t i = 0; i < image_points_.size(); ++i) {
    std::vector<cv::Point2f> projected;
    cv::projectPoints(board, rvecs[i], tvecs[i], K, D, projected);
    double sq = 0;
    for (size_t k = 0; k < board.size(); ++k) {
      const cv::Point2f d = projected[k] - image_points_[i][k];
      sq += d.dot(d);
    }
    result.per_view_rms.push_back(std::sqrt(sq / board.size()));
  }
  return result;
}

}  // namespace hlt
