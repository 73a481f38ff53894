#include "envs/perception/camera_model.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "envs/perception/pose_math.h"
#include "hlt/util/files.h"
#include "perception_test_support.h"

namespace hlt {
namespace {

using test::error_of;

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? text : text.replace(at, from.size(), to);
}

const char* kOpenCvYaml = R"(%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 610., 0., 321.5, 0., 605., 238.25, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -0.12, 0.05, 0.001, -0.0005, 0. ]
)";

// What ROS's camera_calibration writes (no %YAML directive, matrices as plain maps).
const char* kRosYaml = R"(image_width: 640
image_height: 480
camera_name: usb_cam
camera_matrix:
  rows: 3
  cols: 3
  data: [600.5, 0.0, 318.0, 0.0, 601.5, 242.0, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [0.08, -0.15, 0.0, 0.0, 0.0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
)";

TEST(CameraModel, DefaultIsThe640x480TestCamera) {
  const CameraModel c;
  EXPECT_EQ(c.width(), 640);
  EXPECT_EQ(c.height(), 480);
  EXPECT_DOUBLE_EQ(c.fx(), 600.0);
  EXPECT_DOUBLE_EQ(c.fy(), 600.0);
  EXPECT_FALSE(c.has_distortion());
  EXPECT_FALSE(c.has_extrinsics());
  // A point on the optical axis lands on the principal point; one 0.1 m to the right at 1 m, 60 px right.
  const cv::Point2d p = c.project(Eigen::Vector3d(0.1, 0.0, 1.0));
  EXPECT_NEAR(p.x, 319.5 + 60.0, 1e-12);
  EXPECT_NEAR(p.y, 239.5, 1e-12);
}

TEST(CameraModel, ProjectionAndViewingRayAreInverse) {
  const CameraModel c = CameraModel::parse(kOpenCvYaml, "test");
  ASSERT_TRUE(c.has_distortion());
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.1, -0.05, 0.6), Eigen::Vector3d(-0.25, 0.18, 0.7),
                                   Eigen::Vector3d(0.3, 0.2, 0.8)}) {
    const cv::Point2d px = c.project(p);
    const Eigen::Vector3d ray = c.pixel_ray(px);
    EXPECT_NEAR(ray.x(), p.x() / p.z(), 1e-9);
    EXPECT_NEAR(ray.y(), p.y() / p.z(), 1e-9);
    // Distortion moves pixels, and undistorting gives back the ideal pinhole pixel.
    const cv::Point2d ideal = c.project_ideal(p);
    EXPECT_GT(cv::norm(px - ideal), 0.5);
    EXPECT_LT(cv::norm(c.undistort_pixels({px})[0] - ideal), 1e-7);
    EXPECT_LT(cv::norm(c.distort_pixels({ideal})[0] - px), 1e-7);
  }
}

TEST(CameraModel, SaveAndLoadRoundTripInOpenCvFormat) {
  CameraModel c(640, 480, 612.5, 608.25, 318.75, 241.5, {-0.1, 0.02, 0.001, -0.002, 0.003});
  c.set_world_from_camera(pose_from_xyz_rpy(0.2, -0.4, 0.6, -2.2, 0.05, 0.1));
  const std::string path = ::testing::TempDir() + "/hlt_camera_roundtrip.yaml";
  c.save(path, 0.123);
  const std::string text = read_file(path);
  EXPECT_EQ(text.rfind("%YAML:1.0", 0), 0u);
  for (const char* field : {"image_width: 640", "camera_matrix: !!opencv-matrix", "distortion_coefficients:",
                            "avg_reprojection_error:", "world_from_camera: !!opencv-matrix"})
    EXPECT_NE(text.find(field), std::string::npos) << field;
  const CameraModel d = CameraModel::load(path);
  EXPECT_EQ(d.width(), 640);
  EXPECT_EQ(d.height(), 480);
  EXPECT_DOUBLE_EQ(d.fx(), 612.5);
  EXPECT_DOUBLE_EQ(d.fy(), 608.25);
  EXPECT_DOUBLE_EQ(d.cx(), 318.75);
  EXPECT_DOUBLE_EQ(d.cy(), 241.5);
  EXPECT_EQ(d.distortion(), c.distortion());
  ASSERT_TRUE(d.has_extrinsics());
  EXPECT_TRUE(d.world_from_camera().isApprox(c.world_from_camera(), 1e-12));
  std::filesystem::remove(path);
}

TEST(CameraModel, ReadsRosCalibrationFiles) {
  const CameraModel c = CameraModel::parse(kRosYaml, "ost.yaml");
  EXPECT_DOUBLE_EQ(c.fx(), 600.5);
  EXPECT_DOUBLE_EQ(c.fy(), 601.5);
  EXPECT_DOUBLE_EQ(c.cx(), 318.0);
  EXPECT_DOUBLE_EQ(c.cy(), 242.0);
  ASSERT_EQ(c.distortion().size(), 5u);
  EXPECT_DOUBLE_EQ(c.distortion()[0], 0.08);
}

TEST(CameraModel, ReadsTheExampleCalibration) {
  const CameraModel c = CameraModel::load(test::config_path("camera_640x480.yaml"));
  EXPECT_EQ(c.size(), cv::Size(640, 480));
  EXPECT_DOUBLE_EQ(c.fx(), 600.0);
  EXPECT_TRUE(c.has_extrinsics());
}

TEST(CameraModel, BadFilesGiveErrorsNamingTheField) {
  auto parse = [](const std::string& text) {
    return error_of([&] { CameraModel::parse(text, "cam.yaml"); });
  };
  std::string ok = kOpenCvYaml;
  auto without = [&](const std::string& field) {
    std::string t = ok;
    const size_t a = t.find(field + ":");
    size_t b = t.find('\n', a);
    while (b + 1 < t.size() && t[b + 1] == ' ')
      b = t.find('\n', b + 1);  // the field's indented lines too
    return t.erase(a, b - a + 1);
  };
  EXPECT_NE(parse(without("camera_matrix")).find("cam.yaml: field 'camera_matrix' is missing"),
            std::string::npos);
  EXPECT_NE(parse(without("distortion_coefficients")).find("field 'distortion_coefficients' is missing"),
            std::string::npos);
  EXPECT_NE(parse(without("image_width")).find("field 'image_width' is missing"), std::string::npos);

  std::string m = replaced(ok, "rows: 3", "rows: 2");
  EXPECT_NE(parse(m).find("field 'camera_matrix' says 2x3 but its data has 9 numbers"), std::string::npos)
      << parse(m);
  m = replaced(replaced(ok, "[ -0.12, 0.05, 0.001, -0.0005, 0. ]", "[ -0.12, 0.05, 0.001 ]"), "cols: 5",
               "cols: 3");
  EXPECT_NE(parse(m).find("'distortion_coefficients' must have 4, 5, 8, 12 or 14 entries, got 3"),
            std::string::npos)
      << parse(m);
  EXPECT_NE(parse(replaced(ok, "610.", "-10.")).find("focal lengths"), std::string::npos);
  // Intrinsics no lens has are reported with the file they came from.
  EXPECT_NE(parse(replaced(ok, "321.5", "1e6")).find("cam.yaml: camera model: principal point"),
            std::string::npos)
      << parse(replaced(ok, "321.5", "1e6"));
  EXPECT_NE(parse(replaced(ok, "610.", "1e12")).find("cam.yaml: camera model: focal lengths"),
            std::string::npos);
  EXPECT_NE(parse(replaced(ok, "image_width: 640", "image_width: wide"))
                .find("field 'image_width' must be an integer"),
            std::string::npos);
  EXPECT_NE(parse("%YAML:1.0\n---\ncamera_matrix: [1, 2\nfoo: 3\n").find("cam.yaml: not a readable YAML"),
            std::string::npos);
  EXPECT_NE(parse(replaced(kRosYaml, "plumb_bob", "equidistant")).find("'distortion_model' is 'equidistant'"),
            std::string::npos);
  const std::string missing = error_of([] { CameraModel::load("/nonexistent/cam.yaml"); });
  EXPECT_NE(missing.find("/nonexistent/cam.yaml"), std::string::npos) << missing;
  EXPECT_NE(missing.find("no such file"), std::string::npos) << missing;
}

TEST(CameraModel, RejectsBadExtrinsicsAndParameters) {
  CameraModel c;
  Eigen::Isometry3d bad = Eigen::Isometry3d::Identity();
  bad.linear() *= 2.0;
  EXPECT_NE(error_of([&] { c.set_world_from_camera(bad); }).find("not a proper rotation"), std::string::npos);
  EXPECT_NE(error_of([&] { c.world_from_camera(); }).find("no extrinsics"), std::string::npos);
  EXPECT_NE(error_of([] { CameraModel(0, 480, 600, 600, 320, 240); }).find("image size must be positive"),
            std::string::npos);
  EXPECT_NE(error_of([] {
              CameraModel(640, 480, 600, 600, 320, 240, {0.1, 0.2});
            }).find("2"),
            std::string::npos);
  EXPECT_NE(error_of([&] { c.project(Eigen::Vector3d(0, 0, -1)); }).find("not in front of the camera"),
            std::string::npos);
  // Intrinsics no lens has (libapriltag would abort on them).
  EXPECT_NE(error_of([] { CameraModel(640, 480, 1e9, 600, 320, 240); }).find("focal lengths"),
            std::string::npos);
  EXPECT_NE(error_of([] { CameraModel(640, 480, 600, 600, 1e6, 240); }).find("far outside the 640x480 image"),
            std::string::npos);
  EXPECT_NE(error_of([] { CameraModel(640, 480, 600, 600, 320, -1000); }).find("far outside"),
            std::string::npos);
  CameraModel(640, 480, 60000, 60000, 330, 250);  // a long telephoto lens is fine
}

}  // namespace
}  // namespace hlt
