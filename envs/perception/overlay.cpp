#include "envs/perception/overlay.h"

#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

#include "envs/perception/image_checks.h"
#include "envs/perception/pose_math.h"

namespace hlt {
namespace {

cv::Point to_px(const cv::Point2d& p) {
  return {cvRound(p.x * 16), cvRound(p.y * 16)};
}  // 4 fractional bits

void line(cv::Mat& img, const cv::Point2d& a, const cv::Point2d& b, const cv::Scalar& c, int thickness = 1) {
  cv::line(img, to_px(a), to_px(b), c, thickness, cv::LINE_AA, 4);
}

void status_line(cv::Mat& img, int row, const std::string& name, const ObjectEstimate& o) {
  const Eigen::Vector3d p = o.table_from_object.translation();
  const std::string text =
      fmt::format("{:<12} {:+.3f} {:+.3f} yaw {:+5.1f}  {}{}", name, p.x(), p.y(),
                  yaw_of(o.table_from_object.linear()) * 180.0 / M_PI, to_string(o.source),
                  o.stale ? fmt::format(" (stale {} frames)", o.misses) : std::string());
  const cv::Scalar colour = !o.valid  ? cv::Scalar(0, 0, 255)
                            : o.stale ? cv::Scalar(0, 200, 255)
                                      : cv::Scalar(0, 255, 0);
  cv::putText(img, text, cv::Point(8, 18 + 16 * row), cv::FONT_HERSHEY_PLAIN, 1.0, cv::Scalar(0, 0, 0), 3,
              cv::LINE_AA);
  cv::putText(img, text, cv::Point(8, 18 + 16 * row), cv::FONT_HERSHEY_PLAIN, 1.0, colour, 1, cv::LINE_AA);
}

}  // namespace

void draw_overlay(cv::Mat& image, const CameraModel& camera, const FrameResult& result) {
  image = to_bgr(image, "draw_overlay");
  for (const TagDetection& t : result.detections.tags) {
    for (int k = 0; k < 4; ++k)
      line(image, t.corners[k], t.corners[(k + 1) % 4], cv::Scalar(0, 255, 255), 1);
    const double a = t.size / 2;
    const Eigen::Vector3d o = t.camera_from_tag * Eigen::Vector3d(0, 0, 0);
    const Eigen::Vector3d axes[3] = {t.camera_from_tag * Eigen::Vector3d(a, 0, 0),
                                     t.camera_from_tag * Eigen::Vector3d(0, a, 0),
                                     t.camera_from_tag * Eigen::Vector3d(0, 0, a)};
    const cv::Scalar colours[3] = {cv::Scalar(0, 0, 255), cv::Scalar(0, 255, 0), cv::Scalar(255, 0, 0)};
    if (o.z() > 0) {
      for (int i = 0; i < 3; ++i)
        if (axes[i].z() > 0) line(image, camera.project(o), camera.project(axes[i]), colours[i], 2);
    }
    const std::string label = fmt::format("{} {}", t.id, t.name);
    cv::putText(image, label, cv::Point(cvRound(t.centre.x) + 6, cvRound(t.centre.y) - 6),
                cv::FONT_HERSHEY_PLAIN, 1.0, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
    cv::putText(image, label, cv::Point(cvRound(t.centre.x) + 6, cvRound(t.centre.y) - 6),
                cv::FONT_HERSHEY_PLAIN, 1.0, cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
  }
  if (result.colour && result.colour->found) {
    const cv::Point c(cvRound(result.colour->centroid.x), cvRound(result.colour->centroid.y));
    cv::drawMarker(image, c, cv::Scalar(255, 0, 255), cv::MARKER_CROSS, 14, 2, cv::LINE_AA);
  }
  const TaskState& s = result.state;
  for (size_t i = 0; i < s.objects.size(); ++i)
    status_line(image, static_cast<int>(i), s.names[i], s.objects[i]);
  const std::string info = fmt::format(
      "frame {}  t {:.2f}s  tags {}  {:.1f} ms{}", s.frame, result.time, result.detections.tags.size(),
      result.total_ms, s.table_known ? (s.table_stale ? "  table held" : "") : "  TABLE UNKNOWN");
  cv::putText(image, info, cv::Point(8, image.rows - 10), cv::FONT_HERSHEY_PLAIN, 1.0, cv::Scalar(0, 0, 0), 3,
              cv::LINE_AA);
  cv::putText(image, info, cv::Point(8, image.rows - 10), cv::FONT_HERSHEY_PLAIN, 1.0,
              cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
}

}  // namespace hlt
