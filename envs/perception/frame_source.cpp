#include "envs/perception/frame_source.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "hlt/util/error.h"

namespace hlt {
namespace fs = std::filesystem;

std::vector<std::string> FrameSource::image_files(const std::string& folder) {
  check(fs::exists(folder), "image folder {} does not exist", folder);
  check(fs::is_directory(folder), "{} is not a folder", folder);
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (!entry.is_regular_file()) continue;
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" || ext == ".tif" || ext == ".tiff")
      files.push_back(entry.path().string());
  }
  std::sort(files.begin(), files.end());
  check(!files.empty(), "no images (png, jpg, jpeg, bmp, tif, tiff) in folder {}", folder);
  return files;
}

FrameSource::FrameSource(const std::string& spec, double folder_fps, cv::Size camera_size)
    : fps_(folder_fps) {
  check(std::isfinite(folder_fps) && folder_fps > 0, "frame rate for image folders must be positive, got {}",
        folder_fps);
  check(!spec.empty(), "no input given (expected a video file, an image folder or camera:N)");
  start_ = std::chrono::steady_clock::now();
  if (spec.rfind("camera:", 0) == 0) {
    const std::string index_text = spec.substr(7);
    int index = -1;
    try {
      size_t used = 0;
      index = std::stoi(index_text, &used);
      if (used != index_text.size()) index = -1;
    } catch (const std::exception&) {
      index = -1;
    }
    check(index >= 0, "bad camera input '{}': expected camera:N with N a camera index (0, 1, ...)", spec);
    capture_ = std::make_unique<cv::VideoCapture>(index);
    check(capture_->isOpened(), "cannot open camera {} (is it connected, and is /dev/video{} readable?)",
          index, index);
    capture_->set(cv::CAP_PROP_FRAME_WIDTH, camera_size.width);
    capture_->set(cv::CAP_PROP_FRAME_HEIGHT, camera_size.height);
    live_ = true;
    description_ = fmt::format("camera {}", index);
    return;
  }
  check(fs::exists(spec), "input '{}' does not exist (expected a video file, an image folder or camera:N)",
        spec);
  if (fs::is_directory(spec)) {
    files_ = image_files(spec);
    description_ = fmt::format("{} images in {}", files_.size(), spec);
    return;
  }
  capture_ = std::make_unique<cv::VideoCapture>(spec);
  check(capture_->isOpened(), "cannot open video file {} (unsupported format or codec?)", spec);
  const double fps = capture_->get(cv::CAP_PROP_FPS);
  if (std::isfinite(fps) && fps > 0) fps_ = fps;
  description_ = fmt::format("video {}", spec);
}

FrameSource::~FrameSource() = default;

bool FrameSource::read(cv::Mat& frame, double& time) {
  if (!capture_) {
    if (count_ >= static_cast<int64_t>(files_.size())) return false;
    const std::string& path = files_[count_];
    frame = cv::imread(path, cv::IMREAD_COLOR);
    check(!frame.empty(), "cannot read image {} (corrupt or not an image)", path);
    time = static_cast<double>(count_) / fps_;
    ++count_;
    return true;
  }
  if (!capture_->read(frame) || frame.empty()) return false;
  if (live_) {
    time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  } else {
    const double ms = capture_->get(cv::CAP_PROP_POS_MSEC);
    // Some containers report no timestamps; fall back to the nominal rate.
    time = std::isfinite(ms) && ms / 1000.0 > last_time_ ? ms / 1000.0 : static_cast<double>(count_) / fps_;
    if (time <= last_time_) time = last_time_ + 1.0 / fps_;
  }
  last_time_ = time;
  ++count_;
  return true;
}

}  // namespace hlt
