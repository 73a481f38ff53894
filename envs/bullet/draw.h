// Drawing a Bullet robot from its link poses: every shape projected onto a plane of the world, far shapes
// first so that near ones cover them.
#pragma once

#include "envs/bullet/robot.h"
#include "envs/render.h"

namespace hlt::bullet {

// The side view: world x to the right, z up, seen from -y. A dot marks each hinge that is limited or moves a
// body with shapes.
void draw_side(SideView& view, const Robot& robot);
// The top view: world x to the right, y up (the view's second coordinate is y), seen from above.
void draw_top(SideView& view, const Robot& robot);

}  // namespace hlt::bullet
