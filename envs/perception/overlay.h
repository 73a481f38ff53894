// Drawing of perception results onto a frame, for the overlay video of hlt_perceive: tag outlines, ids and
// names, tag axes (x red, y green, z blue), the colour-tracked block and a status line per object.
#pragma once

#include <opencv2/core.hpp>

#include "envs/perception/camera_model.h"
#include "envs/perception/perception_pipeline.h"

namespace hlt {

// Draws onto `image` (BGR, the frame the result came from).
void draw_overlay(cv::Mat& image, const CameraModel& camera, const FrameResult& result);

}  // namespace hlt
