// hlt::SyntheticCamera: renders what a calibrated camera sees of a scene made of flat, textured,
// parallelogram patches (table top, box faces, printed tags, checkerboards). Every pixel is intersected
// exactly with each patch's plane, so perspective is exact and occlusion is resolved by depth. Lens
// distortion of the camera model is applied. Each pixel integrates light over its area, as a sensor does:
// printed patterns (tags, checkerboards) are averaged exactly over the pixel's footprint on the patch, and
// geometric edges (a patch's outline, occlusions) are resolved by several samples per pixel. Sub-pixel
// corner detectors rely on that partial coverage. Optional effects: brightness gain/offset, Gaussian blur and
// seeded Gaussian sensor noise.
//
// Output: CV_8UC3 in OpenCV's BGR channel order, camera.width() x camera.height().
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "envs/perception/camera_model.h"

namespace hlt {

struct TexturedQuad {
  // World-frame corners at the texture's top-left, top-right, bottom-right and bottom-left. They must form a
  // parallelogram. The side seen with the texture unmirrored is the visible side; the other is culled.
  std::array<Eigen::Vector3d, 4> corners;
  cv::Vec3b colour{128, 128, 128};      // BGR, used outside the texture area
  cv::Mat texture;                      // optional, CV_8UC1 or CV_8UC3
  cv::Rect2d texture_area{0, 0, 1, 1};  // where the texture lies in the patch's [0,1]^2 (x right, y down)
  bool smooth_texture = false;          // bilinear sampling (photos) instead of nearest (printed patterns)
  bool lit = true;                      // Lambertian shading; false renders colours as given
};

struct ImageEffects {
  double gain = 1.0;         // brightness multiplier
  double offset = 0.0;       // brightness offset, grey levels
  double blur_sigma = 0.0;   // Gaussian blur, pixels
  double noise_sigma = 0.0;  // Gaussian sensor noise, grey levels
  uint64_t seed = 0;         // noise seed
};

struct SyntheticCameraOptions {
  int supersample = 2;                              // geometric edges get supersample^2 samples per pixel
  cv::Vec3b background{70, 70, 70};                 // BGR where no patch is hit
  Eigen::Vector3d light_direction{0.3, -0.4, 1.0};  // world frame, towards the light
  double ambient = 0.55;                            // shade = ambient + diffuse * max(0, n . l)
  double diffuse = 0.45;
};

class SyntheticCamera {
 public:
  explicit SyntheticCamera(CameraModel camera, SyntheticCameraOptions options = {});

  const CameraModel& camera() const { return camera_; }
  const SyntheticCameraOptions& options() const { return options_; }

  // Renders `quads` (and the static quads) with the camera model's extrinsics (world_from_camera).
  cv::Mat render(const std::vector<TexturedQuad>& quads, const ImageEffects& effects = {}) const;
  // Renders from an explicit camera pose.
  cv::Mat render(const std::vector<TexturedQuad>& quads, const Eigen::Isometry3d& world_from_camera,
                 const ImageEffects& effects = {}) const;

  // Quads that never move (table, reference tag). They are drawn into every image; for the camera model's
  // own extrinsics they are drawn once here and reused, which saves most of the cost of a tabletop frame.
  void set_static_quads(std::vector<TexturedQuad> quads);

  // Applies the effects to an image (used by render; public so real images can be degraded the same way).
  static cv::Mat apply_effects(const cv::Mat& image_bgr, const ImageEffects& effects);

 private:
  void draw(const TexturedQuad& quad, const Eigen::Isometry3d& camera_from_world, cv::Mat& colour,
            cv::Mat& depth) const;
  cv::Vec3f footprint_colour(const TexturedQuad& q, const Eigen::Vector3d& n, double nc0,
                             const Eigen::Vector3d& d1, const Eigen::Vector3d& d2, double s0, double t0,
                             int x, int y) const;

  CameraModel camera_;
  SyntheticCameraOptions options_;
  int W_, H_;     // supersampled size
  cv::Mat rays_;  // CV_32FC2: per supersampled pixel, the camera-frame ray (x/z, y/z)
  double ray_x0_, ray_x1_, ray_y0_, ray_y1_;  // extent of rays_
  cv::Mat pixel_rays_;                        // CV_32FC2: per output pixel, the ray through its centre
  cv::Mat pixel_jacobians_;
  std::vector<TexturedQuad> static_quads_;
  Eigen::Isometry3d static_pose_ = Eigen::Isometry3d::Identity();
  cv::Mat static_colour_, static_depth_;  // static_quads_ drawn from static_pose_                   //
                                          // CV_32FC4: d(ray x, ray y)/d(pixel u, v) at the centre
};

}  // namespace hlt
