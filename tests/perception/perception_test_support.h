// Shared helpers for the perception tests: the example configs, tags rendered at known poses, error capture.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "envs/perception/synthetic_camera.h"
#include "envs/perception/tabletop_scene.h"
#include "envs/perception/tag_config.h"
#include "envs/perception/tag_family.h"
#include "hlt/util/error.h"
#include "support/error_of.h"

namespace hlt::test {

// The repository root: HLT_SOURCE_DIR (set by ctest) or, when run by hand, relative to this file.
inline std::string source_dir() {
  if (const char* env = std::getenv("HLT_SOURCE_DIR")) return env;
  return std::filesystem::path(__FILE__).parent_path().parent_path().parent_path().string();
}

inline std::string config_path(const std::string& name) {
  return source_dir() + "/experiments/configs/perception/" + name;
}

inline TagConfig sawyer_tags() {
  return TagConfig::load(config_path("sawyer_tags.yaml"));
}

using testing::error_of;

// A tag seen from `distance` metres, turned `yaw` about its own normal and tilted `tilt_deg` about its x
// axis, offset from the optical axis by (dx, dy) metres. Camera frame: the tag's z axis faces the camera.
inline Eigen::Isometry3d tag_in_front(double distance, double tilt_deg, double yaw, double dx = 0.03,
                                      double dy = -0.02) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::Vector3d(1, -1, -1).asDiagonal();  // tag x = camera x, tag z towards the camera
  return Eigen::Translation3d(dx, dy, distance) * pose * Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(tilt_deg * M_PI / 180.0, Eigen::Vector3d::UnitX());
}

// One tag on a plain grey background, rendered by a camera at the origin of the world frame.
inline cv::Mat render_tag(const SyntheticCamera& camera, const TagFamily& family, int id, double size,
                          const Eigen::Isometry3d& camera_from_tag, const ImageEffects& effects = {}) {
  TexturedQuad q = TabletopScene::tag_quad(family, id, size, camera_from_tag);
  q.lit = false;
  return camera.render({q}, Eigen::Isometry3d::Identity(), effects);
}

}  // namespace hlt::test
