// Input checks shared by the image consumers: every image that enters perception passes through one of
// these, so an empty frame or an unexpected pixel format is a clear hlt::Error, never a crash.
#pragma once

#include <opencv2/core.hpp>

namespace hlt {

// 8-bit grey from CV_8UC1, CV_8UC3 (BGR) or CV_8UC4 (BGRA); `who` names the caller in the error message.
cv::Mat to_grey(const cv::Mat& image, const char* who);
// 8-bit BGR from CV_8UC3 (as is) or CV_8UC4 (alpha dropped); grey and other types throw, since colour is
// needed.
cv::Mat to_bgr(const cv::Mat& image, const char* who);
// Throws unless the image has the expected size.
void require_size(const cv::Mat& image, cv::Size expected, const char* who);

}  // namespace hlt
