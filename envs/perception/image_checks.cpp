#include "envs/perception/image_checks.h"

#include <opencv2/imgproc.hpp>

#include "hlt/util/error.h"

namespace hlt {
namespace {

void require_nonempty_8bit(const cv::Mat& image, const char* who) {
  check(!image.empty(), "{}: the image is empty (no frame?)", who);
  check(image.depth() == CV_8U, "{}: expected an 8-bit image, got depth code {} with {} channels", who,
        image.depth(), image.channels());
}

}  // namespace

cv::Mat to_grey(const cv::Mat& image, const char* who) {
  require_nonempty_8bit(image, who);
  cv::Mat grey;
  switch (image.channels()) {
    case 1:
      return image;
    case 3:
      cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
      return grey;
    case 4:
      cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
      return grey;
    default:
      throw Error(
          fmt::format("{}: expected 1 (grey), 3 (BGR) or 4 (BGRA) channels, got {}", who, image.channels()));
  }
}

cv::Mat to_bgr(const cv::Mat& image, const char* who) {
  require_nonempty_8bit(image, who);
  check(image.channels() == 3 || image.channels() == 4,
        "{}: colour tracking needs a BGR image (3 or 4 channels), got {} channel(s)", who, image.channels());
  if (image.channels() == 3) return image;
  cv::Mat bgr;
  cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
  return bgr;
}

void require_size(const cv::Mat& image, cv::Size expected, const char* who) {
  check(image.size() == expected, "{}: the image is {}x{} but the camera model is {}x{}", who, image.cols,
        image.rows, expected.width, expected.height);
}

}  // namespace hlt
