// hlt::CameraModel: a calibrated camera. Pinhole intrinsics (fx, fy, cx, cy) with OpenCV's distortion model
// (0, 4, 5, 8, 12 or 14 coefficients), the image size, and optionally extrinsics: the camera's pose in the
// world (table) frame. Pixel coordinates follow OpenCV: the centre of the top-left pixel is (0, 0). The
// camera frame is OpenCV's optical frame: x right, y down, z forward.
//
// Calibrations are read and written as OpenCV FileStorage YAML with the field names of OpenCV's
// calibration sample (image_width, image_height, camera_matrix, distortion_coefficients); ROS
// camera_calibration files (plain YAML, matrices as {rows, cols, data}) are read too.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

namespace hlt {

class CameraModel {
 public:
  // 640x480, fx = fy = 600, principal point at the image centre, no distortion: the default test camera.
  CameraModel();
  CameraModel(int width, int height, double fx, double fy, double cx, double cy,
              std::vector<double> distortion = {});

  static CameraModel load(const std::string& path);
  // Parses calibration YAML text; `source` names the origin in error messages.
  static CameraModel parse(const std::string& yaml_text, const std::string& source);
  // Writes OpenCV FileStorage YAML atomically; `rms` (if given) is stored as avg_reprojection_error.
  void save(const std::string& path, std::optional<double> rms = std::nullopt) const;

  int width() const { return width_; }
  int height() const { return height_; }
  cv::Size size() const { return {width_, height_}; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  cv::Matx33d camera_matrix() const;
  const std::vector<double>& distortion() const { return distortion_; }
  bool has_distortion() const;

  // Extrinsics: world_from_camera maps camera-frame points into the world (table) frame.
  bool has_extrinsics() const { return world_from_camera_.has_value(); }
  const Eigen::Isometry3d& world_from_camera() const;
  void set_world_from_camera(const Eigen::Isometry3d& world_from_camera);
  void clear_extrinsics() { world_from_camera_.reset(); }

  // Projects a camera-frame point (z > 0) to a pixel, distortion included.
  cv::Point2d project(const Eigen::Vector3d& p_camera) const;
  // The ideal (undistorted) pinhole pixel of a point.
  cv::Point2d project_ideal(const Eigen::Vector3d& p_camera) const;
  // Removes lens distortion from measured pixels: the pixels an ideal pinhole camera with the same K sees.
  std::vector<cv::Point2d> undistort_pixels(const std::vector<cv::Point2d>& pixels) const;
  // The inverse: where ideal pinhole pixels appear in the real (distorted) image.
  std::vector<cv::Point2d> distort_pixels(const std::vector<cv::Point2d>& ideal) const;
  // The viewing ray of a measured pixel in the camera frame, scaled to z = 1.
  Eigen::Vector3d pixel_ray(const cv::Point2d& pixel) const;

 private:
  void validate(const std::string& source) const;

  int width_, height_;
  double fx_, fy_, cx_, cy_;
  std::vector<double> distortion_;
  std::optional<Eigen::Isometry3d> world_from_camera_;
};

}  // namespace hlt
