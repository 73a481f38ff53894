// hlt::FrameSource: frames from a video file, a folder of images (sorted by name) or a live camera
// (cv::VideoCapture), with a timestamp for each. Folders have no clock of their own: frame i is at
// i / folder_fps seconds. Videos use the container's timestamps; live cameras the time since opening.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace cv {
class VideoCapture;
}

namespace hlt {

class FrameSource {
 public:
  // `spec`: "camera:N" for camera index N, a folder, or a video file. Live cameras are asked for
  // `camera_size` (the camera may refuse; frames come as delivered).
  explicit FrameSource(const std::string& spec, double folder_fps = 10.0, cv::Size camera_size = {640, 480});
  ~FrameSource();
  FrameSource(const FrameSource&) = delete;
  FrameSource& operator=(const FrameSource&) = delete;

  // The next frame (BGR as decoded) and its time in seconds; false at the end of the input.
  bool read(cv::Mat& frame, double& time);
  const std::string& description() const { return description_; }
  bool live() const { return live_; }
  int64_t frames_read() const { return count_; }

  // Image files (png, jpg, jpeg, bmp, tif, tiff) in a folder, sorted by name; throws if there are none.
  static std::vector<std::string> image_files(const std::string& folder);

 private:
  std::string description_;
  bool live_ = false;
  double fps_ = 10.0;
  int64_t count_ = 0;
  double last_time_ = -1.0;
  std::vector<std::string> files_;
  std::unique_ptr<cv::VideoCapture> capture_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace hlt
