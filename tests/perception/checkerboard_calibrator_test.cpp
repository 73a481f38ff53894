#include "envs/perception/checkerboard_calibrator.h"

#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/calib3d.hpp>

#include "envs/perception/pose_math.h"
#include "envs/perception/synthetic_camera.h"
#include "envs/perception/tabletop_scene.h"
#include "perception_test_support.h"

namespace hlt {
namespace {

using test::error_of;

TEST(CheckerboardCalibrator, RecoversKnownIntrinsicsWithinOnePercent) {
  const CameraModel truth(640, 480, 612.0, 604.0, 326.0, 236.0, {-0.12, 0.04, 0.0, 0.0, 0.0});
  const SyntheticCamera renderer(truth);
  const cv::Size inner(8, 6);
  const double square = 0.03;
  CheckerboardCalibrator calibrator(inner, square);
  int i = 0;
  // The board 0.45-0.55 m in front of the camera, tilted, off-centre: varied views constrain the model.
  for (const Eigen::Isometry3d& pose : TabletopScene::checkerboard_calibration_poses()) {
    ImageEffects e;
    e.noise_sigma = 1.0;
    e.seed = static_cast<uint64_t>(i);
    EXPECT_TRUE(calibrator.add_image(renderer.render({TabletopScene::checkerboard_quad(inner, square, pose)},
                                                     Eigen::Isometry3d::Identity(), e),
                                     "view" + std::to_string(i)))
        << i;
    ++i;
  }
  // A view without the board is rejected, not fatal.
  EXPECT_FALSE(calibrator.add_image(cv::Mat(480, 640, CV_8UC3, cv::Scalar(120, 120, 120)), "blank"));
  const CalibrationResult r = calibrator.calibrate(cv::CALIB_FIX_K3);
  EXPECT_EQ(r.used.size(), 12u);
  ASSERT_EQ(r.rejected.size(), 1u);
  EXPECT_EQ(r.rejected[0], "blank");
  EXPECT_NEAR(r.camera.fx(), truth.fx(), 0.01 * truth.fx());
  EXPECT_NEAR(r.camera.fy(), truth.fy(), 0.01 * truth.fy());
  EXPECT_NEAR(r.camera.cx(), truth.cx(), 0.01 * truth.cx());
  EXPECT_NEAR(r.camera.cy(), truth.cy(), 0.01 * truth.cy());
  EXPECT_NEAR(r.camera.distortion()[0], -0.12, 0.02);
  EXPECT_LT(r.rms, 0.2);
  ASSERT_EQ(r.per_view_rms.size(), 12u);
  RecordProperty("fx_error", std::to_string(r.camera.fx() - truth.fx()));
  RecordProperty("rms", std::to_string(r.rms));
  // The result is a loadable calibration file.
  const std::string path = ::testing::TempDir() + "/hlt_calibration_test.yaml";
  r.camera.save(path, r.rms);
  EXPECT_DOUBLE_EQ(CameraModel::load(path).fx(), r.camera.fx());
}

TEST(CheckerboardCalibrator, BadInputsAreClearErrors) {
  EXPECT_NE(error_of([] { CheckerboardCalibrator(cv::Size(6, 6), 0.03); }).find("ambiguous"),
            std::string::npos);
  EXPECT_NE(
      error_of([] { CheckerboardCalibrator(cv::Size(8, 6), 0.0); }).find("square size must be positive"),
      std::string::npos);
  CheckerboardCalibrator c(cv::Size(8, 6), 0.03);
  c.add_image(cv::Mat(480, 640, CV_8UC1, cv::Scalar(0)), "a.png");
  EXPECT_NE(error_of([&] {
              c.add_image(cv::Mat(240, 320, CV_8UC1, cv::Scalar(0)), "b.png");
            }).find("checkerboard image b.png is 320x240, but the first image was 640x480"),
            std::string::npos);
  EXPECT_NE(error_of([&] { c.calibrate(0); }).find("at least 3 images; found it in 0 (1 rejected)"),
            std::string::npos);
}

}  // namespace
}  // namespace hlt
