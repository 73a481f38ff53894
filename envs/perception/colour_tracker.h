// hlt::ColourTracker: finds a coloured block by HSV thresholding and the moments of the convex hull of the
// largest blob's outer contour (a box's silhouette is convex), and places it in 3-D by intersecting the
// viewing ray through the centroid with a horizontal plane of the table frame (by default at the height of
// the block's centre). The tag-free fallback for the block when its tag is occluded or unreadable.
//
// For a cube the silhouette's centroid lies, up to perspective, on the ray through the cube's centre (the
// visible faces' offsets from the centre, weighted by their projected areas, add up to a vector along the
// viewing direction), so intersecting at the centre's height recovers the centre rather than a face.
#pragma once

#include <optional>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "envs/perception/camera_model.h"

namespace hlt {

struct ColourTrackerOptions {
  // OpenCV HSV ranges (H in [0, 180), S and V in [0, 255]). hsv_low[0] > hsv_high[0] wraps around red.
  cv::Scalar hsv_low{95, 110, 35};
  cv::Scalar hsv_high{125, 255, 255};
  double min_area = 40.0;       // pixels; smaller blobs are noise
  int open_radius = 0;          // morphological opening (pixels) against speckle; 0 disables
  double plane_height = 0.025;  // metres above the table: where the centroid's ray is intersected
  // A blob much smaller than a whole block at the located position is a partly hidden block, whose centroid
  // is off: locate() then reports nothing rather than a wrong position. block_size 0 disables the check.
  double block_size = 0.05;           // edge of the (cubic) block, metres
  double min_visible_fraction = 0.6;  // of the silhouette area expected for the whole block
};

struct ColourBlob {
  bool found = false;
  cv::Point2d centroid;                 // pixels, distorted image
  double area = 0.0;                    // pixels, inside the convex hull of the outer contour
  Eigen::Vector3d ray_camera{0, 0, 1};  // viewing ray through the centroid (camera frame, z = 1)
};

class ColourTracker {
 public:
  explicit ColourTracker(CameraModel camera, ColourTrackerOptions options = {});

  // The largest blob in range. Accepts BGR or BGRA of the camera's size; grey images throw.
  ColourBlob detect(const cv::Mat& image) const;
  // The blob's point on the plane z = plane_height of the table frame; nothing if the ray misses the plane or
  // the blob is too small for a whole block there (partly occluded).
  std::optional<Eigen::Vector3d> locate(const ColourBlob& blob,
                                        const Eigen::Isometry3d& table_from_camera) const;
  // The binary mask of in-range pixels (after opening), for inspection.
  cv::Mat mask(const cv::Mat& image) const;

  const ColourTrackerOptions& options() const { return options_; }
  // Area in pixels of the silhouette of the whole block centred at `p_table` (yaw 0).
  double expected_area(const Eigen::Vector3d& p_table, const Eigen::Isometry3d& table_from_camera) const;

 private:
  CameraModel camera_;
  ColourTrackerOptions options_;
};

}  // namespace hlt
