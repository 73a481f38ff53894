// The locomotion robots as data: PyBullet's Hopper, HalfCheetah and Ant (pybullet_data/mjcf hopper.xml,
// half_cheetah.xml, ant.xml) with their task settings, registered as hopper, half_cheetah and ant.
#pragma once

#include "envs/locomotion/walker.h"

namespace hlt::locomotion {

WalkerSpec hopper_spec();
WalkerSpec half_cheetah_spec();
WalkerSpec ant_spec();

}  // namespace hlt::locomotion
