// hlt::TagCornerRefiner: sub-pixel refinement of a detected tag's four outer corners. libapriltag's own
// edge refinement reads whole pixels, which leaves corner errors of about 0.1 px; on a 25-pixel tag that is
// several degrees of tilt. Here each edge of the black border is located along many normals by the area
// ("mass") of its intensity step, which is unbiased for any symmetric blur, the edge points are freed of
// lens distortion, straight lines are fitted to them, and the corners are the lines' intersections.
#pragma once

#include <array>
#include <optional>

#include <opencv2/core.hpp>

#include "envs/perception/camera_model.h"

namespace hlt {

struct RefinedCorners {
  std::array<cv::Point2d, 4> ideal;      // undistorted (ideal pinhole) pixels
  std::array<cv::Point2d, 4> distorted;  // the same corners in the input image
  double edge_rms = 0.0;                 // RMS distance of the edge points from their fitted lines (pixels)
};

class TagCornerRefiner {
 public:
  // `width_at_border`: the family's tag width in cells at the outer edge of the black border (8 for 36h11).
  explicit TagCornerRefiner(int width_at_border);

  // `corners`: outer corners in the grey image (OpenCV pixels) in libapriltag's winding. Returns nothing when
  // an edge has too little contrast or too few consistent points, or the result strays from `corners`;
  // the caller then keeps the unrefined corners.
  std::optional<RefinedCorners> refine(const cv::Mat& grey, const CameraModel& camera,
                                       const std::array<cv::Point2d, 4>& corners) const;

 private:
  int width_at_border_;
};

}  // namespace hlt
