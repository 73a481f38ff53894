// Side-view drawing of a Bullet robot: every shape projected onto the world x-z plane.
#pragma once

#include "envs/bullet/robot.h"
#include "envs/render.h"

namespace hlt::bullet {

// Draws the base and links (in spec order, so children cover parents) and a dot at each moving joint.
void draw_side(SideView& view, const Robot& robot);

}  // namespace hlt::bullet
