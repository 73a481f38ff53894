#include "envs/bullet/draw.h"

namespace hlt::bullet {

void draw_side(SideView& view, const Robot& robot) {
  for (int link = -1; link < robot.num_links(); ++link) {
    const cv::Scalar& colour = link < 0 ? colours::kBody : (link % 2 ? colours::kLimb : colours::kBody);
    for (const Shape& s : robot.world_shapes(link)) {
      view.capsule(s.from.x(), s.from.z(), s.to.x(), s.to.z(), s.radius, colour);
    }
  }
  for (int link = 0; link < robot.num_links(); ++link) {
    const LinkSpec& l = robot.spec().links[link];
    if (l.joint != JointType::kRevolute || l.shapes.empty()) continue;
    // The joint anchor in the link's frame is fixed, so its world position follows the link's pose.
    const Eigen::Vector3d anchor = robot.body_pose(link) * (l.anchor - l.com);
    view.disc(anchor.x(), anchor.z(), 0.02, colours::kJoint);
  }
}

}  // namespace hlt::bullet
