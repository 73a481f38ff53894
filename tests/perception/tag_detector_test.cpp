#include "envs/perception/tag_detector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "envs/perception/pose_math.h"
#include "perception_test_support.h"

namespace hlt {
namespace {

using test::error_of;

const char* kTwoTags =
    "family: tag36h11\ntags:\n  - {id: 1, name: block, size: 0.033}\n"
    "  - {id: 2, name: target, size: 0.048}\n";

struct PoseError {
  double position = 0;  // metres
  double rotation = 0;  // degrees
};

struct Sweep {
  int cases = 0, detected = 0;
  double worst_relative_position = 0;  // position error / distance
  double worst_rotation_deg = 0;
  double worst_rotation_frontal_deg = 0;  // tags facing the camera: the ill-conditioned case for rotation
  double worst_rotation_tilted_deg = 0;   // tilted by 20 or 40 degrees
};

// Renders each tag of the two sizes at 0.3, 0.5 and 0.8 m, frontal and tilted by 20 and 40 degrees, at two
// in-plane angles, and detects it.
Sweep sweep(const CameraModel& camera, const ImageEffects& effects, const TagDetectorOptions& options = {}) {
  const TagConfig config = TagConfig::parse(kTwoTags, "test");
  const SyntheticCamera renderer(camera);
  const TagFamily family("tag36h11");
  TagDetector detector(camera, config, options);
  Sweep s;
  uint64_t seed = 1;
  for (double size : {0.033, 0.048})
    for (double distance : {0.3, 0.5, 0.8})
      for (double tilt : {0.0, 20.0, 40.0})
        for (double yaw : {0.0, 0.7}) {
          const int id = size < 0.04 ? 1 : 2;
          const Eigen::Isometry3d truth = test::tag_in_front(distance, tilt, yaw);
          ImageEffects e = effects;
          e.seed = seed++;
          const TagDetectionResult r =
              detector.detect(test::render_tag(renderer, family, id, size, truth, e));
          ++s.cases;
          if (r.tags.size() != 1 || r.tags[0].id != id) continue;
          ++s.detected;
          const TagDetection& d = r.tags[0];
          const double dp = (d.camera_from_tag.translation() - truth.translation()).norm();
          const double dr = rotation_angle_between(d.camera_from_tag.linear(), truth.linear()) * 180.0 / M_PI;
          s.worst_relative_position = std::max(s.worst_relative_position, dp / distance);
          s.worst_rotation_deg = std::max(s.worst_rotation_deg, dr);
          double& worst = tilt == 0.0 ? s.worst_rotation_frontal_deg : s.worst_rotation_tilted_deg;
          worst = std::max(worst, dr);
        }
  return s;
}

TEST(TagDetector, CleanImagesGivePosesWithinOnePercentAndTwoDegrees) {
  const Sweep s = sweep(CameraModel(), {});
  EXPECT_EQ(s.detected, s.cases);
  EXPECT_LT(s.worst_relative_position, 0.01);
  EXPECT_LT(s.worst_rotation_deg, 2.0);
  RecordProperty("worst_relative_position", std::to_string(s.worst_relative_position));
  RecordProperty("worst_rotation_deg", std::to_string(s.worst_rotation_deg));
}

// The bounds below are the ones docs/PERCEPTION.md states for degraded images (measured by
// hlt_perception_eval over the same sweep with more seeds), with some room. Rotation is weakest for small
// tags facing the camera from afar (0.033 m at 0.8 m: 25 pixels), where a tilt of a degree barely changes
// the image; tilted tags, as the robot's camera sees them, stay within 2 degrees.
TEST(TagDetector, NoisyImagesStayWithinTheDocumentedBounds) {
  ImageEffects e;
  e.noise_sigma = 3.0;
  const Sweep s = sweep(CameraModel(), e);
  EXPECT_EQ(s.detected, s.cases);
  EXPECT_LT(s.worst_relative_position, 0.005);
  EXPECT_LT(s.worst_rotation_tilted_deg, 2.0);
  EXPECT_LT(s.worst_rotation_frontal_deg, 4.0);
}

TEST(TagDetector, BlurredImagesStayWithinTheDocumentedBounds) {
  ImageEffects e;
  e.blur_sigma = 1.0;
  const Sweep s = sweep(CameraModel(), e);
  EXPECT_EQ(s.detected, s.cases);
  EXPECT_LT(s.worst_relative_position, 0.01);
  EXPECT_LT(s.worst_rotation_tilted_deg, 2.0);
  EXPECT_LT(s.worst_rotation_frontal_deg, 15.0);
  e.blur_sigma = 0.6;
  e.noise_sigma = 2.0;
  const Sweep t = sweep(CameraModel(), e);
  EXPECT_EQ(t.detected, t.cases);
  EXPECT_LT(t.worst_relative_position, 0.005);
  EXPECT_LT(t.worst_rotation_tilted_deg, 2.0);
  EXPECT_LT(t.worst_rotation_frontal_deg, 15.0);
}

TEST(TagDetector, DarkAndLensDistortedImagesStillGiveAccuratePoses) {
  const CameraModel distorted(640, 480, 600, 600, 319.5, 239.5, {-0.2, 0.05, 0.0005, -0.0005, 0.0});
  ImageEffects dark;
  dark.gain = 0.45;
  const Sweep s = sweep(distorted, dark);
  EXPECT_EQ(s.detected, s.cases);
  EXPECT_LT(s.worst_relative_position, 0.01);
  EXPECT_LT(s.worst_rotation_deg, 2.0);

  // The same images read with a camera model that ignores the distortion are measurably worse, so the
  // detector does use the model.
  const TagConfig config = TagConfig::parse(kTwoTags, "test");
  const SyntheticCamera renderer(distorted);
  const TagFamily family("tag36h11");
  const Eigen::Isometry3d truth = test::tag_in_front(0.5, 20, 0.3, 0.15, 0.1);
  const cv::Mat img = test::render_tag(renderer, family, 2, 0.048, truth);
  TagDetector with(distorted, config), without(CameraModel(), config);
  const double good =
      (with.detect(img).tags.at(0).camera_from_tag.translation() - truth.translation()).norm();
  const double bad =
      (without.detect(img).tags.at(0).camera_from_tag.translation() - truth.translation()).norm();
  EXPECT_LT(good, 0.001);
  EXPECT_GT(bad, 5 * good);
}

TEST(TagDetector, ReportsDetectionQuality) {
  const TagConfig config = TagConfig::parse(kTwoTags, "test");
  const CameraModel camera;
  const SyntheticCamera renderer(camera);
  const TagFamily family("tag36h11");
  TagDetector detector(camera, config);
  const Eigen::Isometry3d truth = test::tag_in_front(0.5, 30, 0.4);
  const TagDetectionResult clean = detector.detect(test::render_tag(renderer, family, 1, 0.033, truth));
  ASSERT_EQ(clean.tags.size(), 1u);
  const TagDetection& d = clean.tags[0];
  EXPECT_EQ(d.name, "block");
  EXPECT_DOUBLE_EQ(d.size, 0.033);
  EXPECT_EQ(d.hamming, 0);
  EXPECT_TRUE(d.refined);
  EXPECT_GT(d.decision_margin, 100.0);
  EXPECT_LT(d.reprojection_error, 0.05);
  EXPECT_LT(d.pose_error, 1e-7);
  // Corners are reported where the tag's corners project, in the documented order.
  const double h = 0.033 / 2;
  const Eigen::Vector3d corners[4] = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}};
  for (int k = 0; k < 4; ++k)
    EXPECT_LT(cv::norm(d.corners[k] - camera.project(truth * corners[k])), 0.05) << k;
  EXPECT_LT(cv::norm(d.centre - camera.project(truth.translation())), 0.05);

  ImageEffects poor;
  poor.noise_sigma = 8;
  poor.gain = 0.4;
  poor.seed = 3;
  const TagDetectionResult noisy = detector.detect(test::render_tag(renderer, family, 1, 0.033, truth, poor));
  ASSERT_EQ(noisy.tags.size(), 1u);
  EXPECT_LT(noisy.tags[0].decision_margin, d.decision_margin);
  EXPECT_GT(noisy.tags[0].reprojection_error, d.reprojection_error);
}

TEST(TagDetector, LibapriltagCornersAloneAreLessPrecise) {
  TagDetectorOptions raw;
  raw.refine_corners = false;
  const Sweep plain = sweep(CameraModel(), {}, raw);
  const Sweep refined = sweep(CameraModel(), {});
  EXPECT_EQ(plain.detected, plain.cases);
  EXPECT_LT(plain.worst_relative_position, 0.03);  // libapriltag alone: a few millimetres
  EXPECT_GT(plain.worst_rotation_deg, refined.worst_rotation_deg);
}

TEST(TagDetector, OtherFamiliesWork) {
  const CameraModel camera;
  const SyntheticCamera renderer(camera);
  const Eigen::Isometry3d truth = test::tag_in_front(0.5, 30, 0.4);
  for (const std::string family : {"tag25h9", "tag16h5", "tagStandard41h12"}) {
    const TagConfig config =
        TagConfig::parse("family: " + family + "\ntags:\n  - {id: 3, name: a, size: 0.04}\n", "test");
    TagDetector detector(camera, config);
    const TagDetectionResult r =
        detector.detect(test::render_tag(renderer, TagFamily(family), 3, 0.04, truth));
    ASSERT_EQ(r.tags.size(), 1u) << family;
    EXPECT_LT((r.tags[0].camera_from_tag.translation() - truth.translation()).norm(), 0.002) << family;
    // tagStandard41h12's border is light inside dark: the refiner declines and libapriltag's corners are
    // kept.
    EXPECT_EQ(r.tags[0].refined, family != "tagStandard41h12") << family;
  }
}

TEST(TagDetector, UnknownIdsAreReportedWithoutPose) {
  const TagConfig config = TagConfig::parse(kTwoTags, "test");
  const CameraModel camera;
  const SyntheticCamera renderer(camera);
  const TagFamily family("tag36h11");
  TagDetector detector(camera, config);
  const TagDetectionResult r =
      detector.detect(test::render_tag(renderer, family, 7, 0.04, test::tag_in_front(0.4, 10, 0.2)));
  EXPECT_TRUE(r.tags.empty());
  ASSERT_EQ(r.unknown_ids.size(), 1u);
  EXPECT_EQ(r.unknown_ids[0], 7);
}

TEST(TagDetector, BadImagesAreClearErrors) {
  const TagConfig config = TagConfig::parse(kTwoTags, "test");
  TagDetector detector(CameraModel(), config);
  EXPECT_NE(error_of([&] { detector.detect(cv::Mat()); }).find("TagDetector::detect: the image is empty"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              detector.detect(cv::Mat(480, 640, CV_8UC2, cv::Scalar(0)));
            }).find("expected 1 (grey), 3 (BGR) or 4 (BGRA) channels, got 2"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              detector.detect(cv::Mat(480, 640, CV_16UC1, cv::Scalar(0)));
            }).find("expected an 8-bit image"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              detector.detect(cv::Mat(240, 320, CV_8UC3, cv::Scalar(0)));
            }).find("the image is 320x240 but the camera model is 640x480"),
            std::string::npos);
  // Grey and BGRA images are fine.
  EXPECT_TRUE(detector.detect(cv::Mat(480, 640, CV_8UC1, cv::Scalar(128))).tags.empty());
  EXPECT_TRUE(detector.detect(cv::Mat(480, 640, CV_8UC4, cv::Scalar(128))).tags.empty());
  TagDetectorOptions o;
  o.quad_decimate = 0.5;
  EXPECT_NE(error_of([&] { TagDetector(CameraModel(), config, o); }).find("quad_decimate must be in [1, 8]"),
            std::string::npos);
}

}  // namespace
}  // namespace hlt
