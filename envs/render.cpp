#include "envs/render.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "hlt/util/error.h"

namespace hlt {

namespace {
// Sub-pixel coordinates for anti-aliased drawing.
constexpr int kShift = 4;
constexpr double kSubPixel = 1 << kShift;

// Far outside any image, so OpenCV clips it away; also where non-finite coordinates go.
constexpr double kFar = 1e6;

int fixed(double v) {
  if (!(v > -kFar)) v = -kFar;  // also catches NaN
  if (v > kFar) v = kFar;
  return static_cast<int>(std::lround(v * kSubPixel));
}

cv::Point fixed_point(const cv::Point2d& p) {
  return {fixed(p.x), fixed(p.y)};
}
}  // namespace

SideView::SideView(int width, int height, double cx, double cz, double metres_across)
    : cx_(cx), cz_(cz), scale_(width / metres_across) {
  check(width > 0 && height > 0, "render size must be positive, got {}x{}", width, height);
  check(metres_across > 0, "the view must be wider than 0 m");
  image_ = cv::Mat(height, width, CV_8UC3, colours::kBackground);
}

cv::Point2d SideView::to_pixel(double x, double z) const {
  return {image_.cols / 2.0 + (x - cx_) * scale_, image_.rows / 2.0 - (z - cz_) * scale_};
}

void SideView::capsule(double x0, double z0, double x1, double z1, double radius, const cv::Scalar& colour) {
  // OpenCV draws thick lines with round caps, which is exactly a capsule's silhouette.
  const int thickness = std::max(1, static_cast<int>(std::lround(2 * radius * scale_)));
  cv::line(image_, fixed_point(to_pixel(x0, z0)), fixed_point(to_pixel(x1, z1)), colour, thickness,
           cv::LINE_AA, kShift);
}

void SideView::line(double x0, double z0, double x1, double z1, const cv::Scalar& colour, int thickness_px) {
  cv::line(image_, fixed_point(to_pixel(x0, z0)), fixed_point(to_pixel(x1, z1)), colour, thickness_px,
           cv::LINE_AA, kShift);
}

void SideView::disc(double x, double z, double radius, const cv::Scalar& colour) {
  const int r = std::max(1, static_cast<int>(std::lround(radius * scale_ * kSubPixel)));
  cv::circle(image_, fixed_point(to_pixel(x, z)), r, colour, cv::FILLED, cv::LINE_AA, kShift);
}

void SideView::rectangle(double x0, double z0, double x1, double z1, const cv::Scalar& colour) {
  cv::rectangle(image_, fixed_point(to_pixel(x0, z0)), fixed_point(to_pixel(x1, z1)), colour, cv::FILLED,
                cv::LINE_AA, kShift);
}

void SideView::polygon(const std::vector<cv::Point2d>& corners, const cv::Scalar& colour) {
  std::vector<cv::Point> pts;
  for (const cv::Point2d& c : corners)
    pts.push_back(fixed_point(to_pixel(c.x, c.y)));
  if (pts.size() >= 3) cv::fillConvexPoly(image_, pts, colour, cv::LINE_AA, kShift);
}

void SideView::caption(const std::string& text) {
  ++caption_lines_;
  // Readable from thumbnails (image strips) up to full-size frames.
  const double font = std::clamp(image_.cols / 960.0, 0.3, 0.6);
  const int line = static_cast<int>(std::lround(36 * font));
  cv::putText(image_, text, cv::Point(6, 4 + line * caption_lines_), cv::FONT_HERSHEY_SIMPLEX, font,
              colours::kText, 1, cv::LINE_AA);
}

}  // namespace hlt
