// SideView: a minimal 2-D canvas for drawing environments seen from the side (world x to the right, world z
// up, in metres), used by render() of the pendulum, acrobot and the Bullet robots.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace hlt {

class SideView {
 public:
  // A `width` x `height` BGR image showing `metres_across` metres horizontally, centred on (cx, cz).
  SideView(int width, int height, double cx, double cz, double metres_across);

  cv::Point2d to_pixel(double x, double z) const;
  // Pixels per metre.
  double scale() const { return scale_; }

  // A segment `radius` metres thick on each side with round ends (a capsule seen from the side).
  void capsule(double x0, double z0, double x1, double z1, double radius, const cv::Scalar& colour);
  void line(double x0, double z0, double x1, double z1, const cv::Scalar& colour, int thickness_px = 1);
  void disc(double x, double z, double radius, const cv::Scalar& colour);
  void rectangle(double x0, double z0, double x1, double z1, const cv::Scalar& colour);
  // A filled convex polygon through the given (x, z) corners (a turned box seen from above).
  void polygon(const std::vector<cv::Point2d>& corners, const cv::Scalar& colour);
  // Text in the top-left corner, one call per line.
  void caption(const std::string& text);

  const cv::Mat& image() const { return image_; }

 private:
  cv::Mat image_;
  double cx_, cz_, scale_;
  int caption_lines_ = 0;
};

namespace colours {
const cv::Scalar kBackground(245, 245, 245);
const cv::Scalar kGround(90, 90, 90);
const cv::Scalar kGroundFill(215, 215, 215);
const cv::Scalar kBody(60, 110, 200);
const cv::Scalar kLimb(40, 160, 230);
const cv::Scalar kJoint(30, 30, 30);
const cv::Scalar kText(20, 20, 20);
}  // namespace colours

}  // namespace hlt
