#include "envs/perception/synthetic_camera.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "envs/perception/pose_math.h"
#include "envs/perception/tabletop_scene.h"
#include "envs/perception/tag_detector.h"
#include "perception_test_support.h"

namespace hlt {
namespace {

using test::error_of;

// A flat, unlit square of side `side` centred at `centre` (camera frame, facing the camera).
TexturedQuad square(const Eigen::Vector3d& centre, double side, cv::Vec3b colour) {
  const double h = side / 2;
  TexturedQuad q;
  q.corners = {centre + Eigen::Vector3d(-h, -h, 0), centre + Eigen::Vector3d(h, -h, 0),
               centre + Eigen::Vector3d(h, h, 0), centre + Eigen::Vector3d(-h, h, 0)};
  q.colour = colour;
  q.lit = false;
  return q;
}

SyntheticCameraOptions black_background() {
  SyntheticCameraOptions o;
  o.background = cv::Vec3b(0, 0, 0);
  return o;
}

TEST(SyntheticCamera, DrawsAPatchWithTheProjectedAreaAndCentroid) {
  const SyntheticCamera cam(CameraModel(), black_background());
  // A tilted 10 cm square 0.5 m away: its image is a perspective quadrilateral, not a square.
  const Eigen::Isometry3d pose =
      Eigen::Translation3d(0.02, -0.01, 0.5) * Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitY());
  TexturedQuad q = square(Eigen::Vector3d::Zero(), 0.1, cv::Vec3b(255, 255, 255));
  for (Eigen::Vector3d& c : q.corners)
    c = pose * c;
  const cv::Mat img = cam.render({q}, Eigen::Isometry3d::Identity());
  ASSERT_EQ(img.type(), CV_8UC3);
  ASSERT_EQ(img.size(), cv::Size(640, 480));
  cv::Mat grey;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  const cv::Moments m = cv::moments(grey, false);
  std::vector<cv::Point2f> poly;
  for (const Eigen::Vector3d& c : q.corners) {
    const cv::Point2d p = cam.camera().project(c);
    poly.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  }
  const cv::Moments pm = cv::moments(poly);
  // Partial coverage at the edges makes the intensity-weighted area and centroid match the exact polygon.
  EXPECT_NEAR(m.m00 / 255.0, pm.m00, 0.002 * pm.m00);
  EXPECT_NEAR(m.m10 / m.m00, pm.m10 / pm.m00, 0.05);
  EXPECT_NEAR(m.m01 / m.m00, pm.m01 / pm.m00, 0.05);
}

TEST(SyntheticCamera, OcclusionFollowsDepthNotDrawingOrder) {
  const SyntheticCamera cam(CameraModel(), black_background());
  const TexturedQuad near = square(Eigen::Vector3d(0, 0, 0.4), 0.05, cv::Vec3b(0, 0, 255));
  const TexturedQuad far = square(Eigen::Vector3d(0.01, 0, 0.6), 0.2, cv::Vec3b(255, 0, 0));
  for (const auto& order : {std::vector<TexturedQuad>{near, far}, std::vector<TexturedQuad>{far, near}}) {
    const cv::Mat img = cam.render(order, Eigen::Isometry3d::Identity());
    EXPECT_EQ(img.at<cv::Vec3b>(240, 320), cv::Vec3b(0, 0, 255));  // the near square covers the centre
    EXPECT_EQ(img.at<cv::Vec3b>(240, 400), cv::Vec3b(255, 0, 0));  // the far one shows beside it
  }
}

TEST(SyntheticCamera, BackFacesAreNotDrawn) {
  const SyntheticCamera cam(CameraModel(), black_background());
  TexturedQuad q = square(Eigen::Vector3d(0, 0, 0.5), 0.1, cv::Vec3b(255, 255, 255));
  std::swap(q.corners[1], q.corners[3]);  // same square, wound the other way: seen from behind
  EXPECT_EQ(cv::countNonZero(cam.render({q}, Eigen::Isometry3d::Identity()).reshape(1)), 0);
}

TEST(SyntheticCamera, NoiseIsSeededBlurAndBrightnessApply) {
  const SyntheticCamera cam(CameraModel(), black_background());
  const TexturedQuad q = square(Eigen::Vector3d(0, 0, 0.5), 0.5, cv::Vec3b(100, 100, 100));
  ImageEffects e;
  e.noise_sigma = 4.0;
  e.seed = 11;
  const cv::Mat a = cam.render({q}, Eigen::Isometry3d::Identity(), e);
  const cv::Mat b = cam.render({q}, Eigen::Isometry3d::Identity(), e);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  e.seed = 12;
  EXPECT_GT(cv::norm(a, cam.render({q}, Eigen::Isometry3d::Identity(), e), cv::NORM_INF), 0.0);
  cv::Scalar mean, stddev;
  cv::meanStdDev(a(cv::Rect(200, 150, 240, 180)), mean, stddev);
  EXPECT_NEAR(mean[0], 100.0, 0.5);
  EXPECT_NEAR(stddev[0], 4.0, 0.3);

  ImageEffects dim;
  dim.gain = 0.5;
  dim.offset = 10;
  EXPECT_EQ(cam.render({q}, Eigen::Isometry3d::Identity(), dim).at<cv::Vec3b>(240, 320),
            cv::Vec3b(60, 60, 60));
  ImageEffects blur;
  blur.blur_sigma = 2.0;
  const cv::Mat sharp = cam.render({square(Eigen::Vector3d(0, 0, 0.5), 0.1, cv::Vec3b(255, 255, 255))},
                                   Eigen::Isometry3d::Identity());
  const cv::Mat soft = cam.render({square(Eigen::Vector3d(0, 0, 0.5), 0.1, cv::Vec3b(255, 255, 255))},
                                  Eigen::Isometry3d::Identity(), blur);
  // The pixel just outside the edge is black when sharp and lit when blurred.
  const int edge = static_cast<int>(std::ceil(319.5 + 600 * 0.05 / 0.5));
  EXPECT_EQ(sharp.at<cv::Vec3b>(240, edge + 1)[0], 0);
  EXPECT_GT(soft.at<cv::Vec3b>(240, edge + 1)[0], 20);
}

TEST(SyntheticCamera, AppliesTheCameraModelsDistortion) {
  const CameraModel distorted(640, 480, 600, 600, 319.5, 239.5, {-0.25, 0.08, 0.0, 0.0, 0.0});
  const SyntheticCamera cam(distorted, black_background());
  const Eigen::Vector3d centre(0.18, 0.12, 0.5);  // far off-axis, where barrel distortion is strong
  const cv::Mat img =
      cam.render({square(centre, 0.01, cv::Vec3b(255, 255, 255))}, Eigen::Isometry3d::Identity());
  cv::Mat grey;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  const cv::Moments m = cv::moments(grey, false);
  const cv::Point2d seen(m.m10 / m.m00, m.m01 / m.m00);
  EXPECT_LT(cv::norm(seen - distorted.project(centre)), 0.2);
  EXPECT_GT(cv::norm(seen - distorted.project_ideal(centre)), 5.0);
}

TEST(SyntheticCamera, StaticLayerCacheGivesTheSameImage) {
  const TagConfig tags = test::sawyer_tags();
  CameraModel cam;
  cam.set_world_from_camera(TabletopScene::default_camera_pose());
  const TabletopScene scene(tags);
  const TabletopPoses poses = TabletopScene::example_poses();
  const SyntheticCamera plain(cam);
  SyntheticCamera cached(cam);
  cached.set_static_quads(scene.static_quads());
  const cv::Mat a = plain.render(scene.quads(poses));
  const cv::Mat b = cached.render(scene.object_quads(poses));
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  // From another pose the static quads are drawn afresh, not taken from the cache.
  const Eigen::Isometry3d other = look_at(Eigen::Vector3d(0.3, -0.3, 0.5), Eigen::Vector3d(0.2, 0.1, 0));
  EXPECT_EQ(cv::norm(plain.render(scene.quads(poses), other), cached.render(scene.object_quads(poses), other),
                     cv::NORM_INF),
            0.0);
}

TEST(SyntheticCamera, TabletopSceneShowsAllConfiguredTags) {
  const TagConfig tags = test::sawyer_tags();
  CameraModel cam;
  cam.set_world_from_camera(TabletopScene::default_camera_pose());
  const cv::Mat img = SyntheticCamera(cam).render(TabletopScene(tags).quads(TabletopScene::example_poses()));
  TagDetector detector(cam, tags);
  const TagDetectionResult r = detector.detect(img);
  ASSERT_EQ(r.tags.size(), 4u);
  for (int id = 0; id < 4; ++id)
    EXPECT_EQ(r.tags[id].id, id);
  EXPECT_TRUE(r.unknown_ids.empty());
}

TEST(SyntheticCamera, BadInputsAreClearErrors) {
  EXPECT_NE(error_of([] {
              SyntheticCameraOptions o;
              o.supersample = 0;
              SyntheticCamera(CameraModel(), o);
            }).find("supersample must be in [1, 8]"),
            std::string::npos);
  const SyntheticCamera cam{CameraModel()};
  TexturedQuad q = square(Eigen::Vector3d(0, 0, 0.5), 0.1, cv::Vec3b(1, 2, 3));
  q.corners[2] += Eigen::Vector3d(0.05, 0, 0);
  EXPECT_NE(error_of([&] { cam.render({q}, Eigen::Isometry3d::Identity()); }).find("parallelogram"),
            std::string::npos);
  TexturedQuad t = square(Eigen::Vector3d(0, 0, 0.5), 0.1, cv::Vec3b(1, 2, 3));
  t.texture = cv::Mat(4, 4, CV_32F);
  EXPECT_NE(error_of([&] {
              cam.render({t}, Eigen::Isometry3d::Identity());
            }).find("texture must be CV_8UC1 or CV_8UC3"),
            std::string::npos);
  EXPECT_NE(error_of([&] { cam.render({}); }).find("no extrinsics"), std::string::npos);
  ImageEffects e;
  e.noise_sigma = -1;
  EXPECT_NE(
      error_of([&] { cam.render({}, Eigen::Isometry3d::Identity(), e); }).find("noise_sigma must be >= 0"),
      std::string::npos);
  const TagFamily family("tag36h11");
  EXPECT_NE(error_of([&] {
              TabletopScene::tag_quad(family, 587, 0.03, Eigen::Isometry3d::Identity());
            }).find("tag id 587 is not in family tag36h11 (ids 0..586)"),
            std::string::npos);
}

}  // namespace
}  // namespace hlt
