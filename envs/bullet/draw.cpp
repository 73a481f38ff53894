#include "envs/bullet/draw.h"

#include <algorithm>
#include <vector>

namespace hlt::bullet {

namespace {

struct Piece {
  Shape shape;
  double depth;  // of the shape's nearest point; larger is further from the viewer
  bool body;
};

// Projects onto the world axes (u, v), looking along `depth_axis` (+1: looking towards +axis).
void draw_projected(SideView& view, const Robot& robot, int u, int v, int depth_axis, double looking) {
  // The base, or the first link with shapes, is the body; everything after it a limb.
  std::vector<Piece> pieces;
  bool body_found = false;
  for (int link = -1; link < robot.num_links(); ++link) {
    const std::vector<Shape> shapes = robot.world_shapes(link);
    if (shapes.empty()) continue;
    const bool body = !body_found;
    body_found = true;
    for (const Shape& s : shapes) {
      // Boxes are the scenes' to draw (their orientation is not in a Shape); robots here are capsules.
      if (s.is_box()) continue;
      pieces.push_back({s, looking * 0.5 * (s.from[depth_axis] + s.to[depth_axis]) - s.radius, body});
    }
  }
  std::stable_sort(pieces.begin(), pieces.end(),
                   [](const Piece& a, const Piece& b) { return a.depth > b.depth; });
  for (const Piece& p : pieces) {
    view.capsule(p.shape.from[u], p.shape.from[v], p.shape.to[u], p.shape.to[v], p.shape.radius,
                 p.body ? colours::kBody : colours::kLimb);
  }
  for (int link = 0; link < robot.num_links(); ++link) {
    const LinkSpec& l = robot.spec().links[link];
    if (l.joint != JointType::kRevolute || (l.shapes.empty() && !l.limits)) continue;
    // The joint anchor is fixed in the link's frame, so its world position follows the link's pose.
    const Eigen::Vector3d anchor = robot.body_pose(link) * (l.anchor - l.com);
    view.disc(anchor[u], anchor[v], 0.02, colours::kJoint);
  }
}

}  // namespace

void draw_side(SideView& view, const Robot& robot) {
  draw_projected(view, robot, 0, 2, 1, 1.0);
}

void draw_top(SideView& view, const Robot& robot) {
  draw_projected(view, robot, 0, 1, 2, -1.0);
}

}  // namespace hlt::bullet
