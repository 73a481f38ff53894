#include "envs/perception/frame_source.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "perception_test_support.h"

namespace hlt {
namespace {

namespace fs = std::filesystem;
using test::error_of;

std::string fresh_dir(const std::string& name) {
  const fs::path p = fs::path(::testing::TempDir()) / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

TEST(FrameSource, ReadsAnImageFolderInNameOrder) {
  const std::string dir = fresh_dir("hlt_frames");
  for (int i : {2, 0, 1}) {
    cv::Mat img(48, 64, CV_8UC3, cv::Scalar(10 * i, 0, 0));
    cv::imwrite(dir + "/frame_" + std::to_string(i) + ".png", img);
  }
  std::ofstream(dir + "/notes.txt") << "not an image";
  FrameSource src(dir, 20.0);
  EXPECT_FALSE(src.live());
  cv::Mat frame;
  double t = -1;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(src.read(frame, t));
    EXPECT_EQ(frame.at<cv::Vec3b>(0, 0)[0], 10 * i);
    EXPECT_DOUBLE_EQ(t, i / 20.0);
  }
  EXPECT_FALSE(src.read(frame, t));
  EXPECT_EQ(src.frames_read(), 3);
}

TEST(FrameSource, ReadsAVideoFile) {
  const std::string path = fresh_dir("hlt_video") + "/clip.avi";
  {
    cv::VideoWriter w(path, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 25.0, cv::Size(64, 48));
    ASSERT_TRUE(w.isOpened());
    for (int i = 0; i < 5; ++i)
      w.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(40 * i, 40 * i, 40 * i)));
  }
  FrameSource src(path);
  cv::Mat frame;
  double t = 0, last = -1;
  int n = 0;
  while (src.read(frame, t)) {
    EXPECT_EQ(frame.size(), cv::Size(64, 48));
    EXPECT_GT(t, last);
    last = t;
    ++n;
  }
  EXPECT_EQ(n, 5);
  EXPECT_NEAR(last, 4 / 25.0, 1e-6);
}

TEST(FrameSource, BadInputsAreClearErrors) {
  EXPECT_NE(error_of([] { FrameSource("/nonexistent/clip.mp4"); })
                .find("input '/nonexistent/clip.mp4' does not exist (expected a video file, an image folder "
                      "or camera:N)"),
            std::string::npos);
  EXPECT_NE(error_of([] { FrameSource("camera:front"); }).find("bad camera input 'camera:front'"),
            std::string::npos);
  const std::string empty = fresh_dir("hlt_empty_frames");
  EXPECT_NE(error_of([&] { FrameSource{empty}; }).find("no images"), std::string::npos);
  const std::string junk = fresh_dir("hlt_junk") + "/clip.avi";
  std::ofstream(junk) << "this is not a video";
  EXPECT_NE(error_of([&] { FrameSource{junk}; }).find("cannot open video file"), std::string::npos);
  const std::string bad_image_dir = fresh_dir("hlt_bad_image");
  std::ofstream(bad_image_dir + "/a.png") << "not a png";
  FrameSource src(bad_image_dir);
  cv::Mat frame;
  double t;
  EXPECT_NE(error_of([&] { src.read(frame, t); }).find("cannot read image"), std::string::npos);
}

}  // namespace
}  // namespace hlt
