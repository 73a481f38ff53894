#include "envs/perception/colour_tracker.h"

#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "envs/perception/image_checks.h"
#include "hlt/util/error.h"

namespace hlt {

ColourTracker::ColourTracker(CameraModel camera, ColourTrackerOptions options)
    : camera_(std::move(camera)), options_(options) {
  for (int i = 0; i < 3; ++i) {
    const double hi = i == 0 ? 180.0 : 255.0;
    check(options_.hsv_low[i] >= 0 && options_.hsv_low[i] <= hi && options_.hsv_high[i] >= 0 &&
              options_.hsv_high[i] <= hi,
          "ColourTracker: HSV channel {} bounds must be in [0, {}]", i, hi);
    if (i > 0)
      check(options_.hsv_low[i] <= options_.hsv_high[i], "ColourTracker: HSV channel {} has low > high", i);
  }
  check(options_.min_area >= 1, "ColourTracker: min_area must be >= 1 pixel");
  check(options_.open_radius >= 0 && options_.open_radius <= 10,
        "ColourTracker: open_radius must be in [0, 10]");
  check(std::isfinite(options_.plane_height), "ColourTracker: plane_height must be finite");
  check(std::isfinite(options_.block_size) && options_.block_size >= 0,
        "ColourTracker: block_size must be >= 0");
  check(options_.min_visible_fraction >= 0 && options_.min_visible_fraction <= 1,
        "ColourTracker: min_visible_fraction must be in [0, 1]");
}

cv::Mat ColourTracker::mask(const cv::Mat& image) const {
  const cv::Mat bgr = to_bgr(image, "ColourTracker");
  require_size(bgr, camera_.size(), "ColourTracker");
  cv::Mat hsv, m;
  cv::cvtColor(bgr, hsv, cv::COLOR_BGR2HSV);
  const cv::Scalar& lo = options_.hsv_low;
  const cv::Scalar& hi = options_.hsv_high;
  if (lo[0] <= hi[0]) {
    cv::inRange(hsv, lo, hi, m);
  } else {  // hue range wraps through 0 (reds)
    cv::Mat a, b;
    cv::inRange(hsv, cv::Scalar(lo[0], lo[1], lo[2]), cv::Scalar(180, hi[1], hi[2]), a);
    cv::inRange(hsv, cv::Scalar(0, lo[1], lo[2]), cv::Scalar(hi[0], hi[1], hi[2]), b);
    m = a | b;
  }
  if (options_.open_radius > 0) {
    const int k = 2 * options_.open_radius + 1;
    cv::morphologyEx(m, m, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(k, k)));
  }
  return m;
}

ColourBlob ColourTracker::detect(const cv::Mat& image) const {
  const cv::Mat m = mask(image);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(m, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  ColourBlob blob;
  double best = 0;
  for (const auto& c : contours) {
    // A box's silhouette is convex: the hull restores what the block's own tag, glare or the thin coloured
    // rim around the tag take out of the mask, which would otherwise pull the centroid off the block.
    std::vector<cv::Point> hull;
    cv::convexHull(c, hull);
    const cv::Moments mo = cv::moments(hull);
    if (mo.m00 < options_.min_area || mo.m00 <= best) continue;
    best = mo.m00;
    blob.found = true;
    blob.area = mo.m00;
    blob.centroid = cv::Point2d(mo.m10 / mo.m00, mo.m01 / mo.m00);
  }
  if (blob.found) blob.ray_camera = camera_.pixel_ray(blob.centroid);
  return blob;
}

std::optional<Eigen::Vector3d> ColourTracker::locate(const ColourBlob& blob,
                                                     const Eigen::Isometry3d& table_from_camera) const {
  check(table_from_camera.matrix().allFinite(), "ColourTracker::locate: table_from_camera is not finite");
  if (!blob.found || !blob.ray_camera.allFinite()) return std::nullopt;
  const Eigen::Vector3d origin = table_from_camera.translation();
  const Eigen::Vector3d dir = table_from_camera.linear() * blob.ray_camera;
  if (std::abs(dir.z()) < 1e-9) return std::nullopt;  // ray parallel to the table
  const double lambda = (options_.plane_height - origin.z()) / dir.z();
  if (!(lambda > 0)) return std::nullopt;  // plane behind the camera
  const Eigen::Vector3d p = origin + lambda * dir;
  if (!p.allFinite()) return std::nullopt;
  if (options_.block_size > 0 &&
      blob.area < options_.min_visible_fraction * expected_area(p, table_from_camera))
    return std::nullopt;
  return p;
}

double ColourTracker::expected_area(const Eigen::Vector3d& p_table,
                                    const Eigen::Isometry3d& table_from_camera) const {
  const Eigen::Isometry3d camera_from_table = table_from_camera.inverse();
  const double h = options_.block_size / 2;
  std::vector<cv::Point2f> corners;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d c =
        camera_from_table * (p_table + Eigen::Vector3d(i & 1 ? h : -h, i & 2 ? h : -h, i & 4 ? h : -h));
    if (c.z() <= 1e-6) return 0.0;
    const cv::Point2d px = camera_.project_ideal(c);
    corners.emplace_back(static_cast<float>(px.x), static_cast<float>(px.y));
  }
  std::vector<cv::Point2f> hull;
  cv::convexHull(corners, hull);
  return cv::contourArea(hull);
}

}  // namespace hlt
