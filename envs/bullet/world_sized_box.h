// WorldSizedBox: a btBoxShape whose bounding box covers the whole scene wherever the box is, so that the
// broadphase never drops a pair it is in and the pair's contact manifold lasts as long as the world (World's
// snapshots need a fixed set of manifolds).
#pragma once

#include <BulletCollision/CollisionShapes/btBoxShape.h>

namespace hlt::bullet {

class WorldSizedBox : public btBoxShape {
 public:
  using btBoxShape::btBoxShape;
  // 100 m each way stays well inside Bullet's 1e6 m bounding-box overflow check.
  void getAabb(const btTransform&, btVector3& aabb_min, btVector3& aabb_max) const override {
    aabb_min.setValue(-100, -100, -100);
    aabb_max.setValue(100, 100, 100);
  }
  // Bullet derives the contact-breaking threshold from the bounding sphere, which it would otherwise take
  // from the world-sized bounds above: the box's own sphere keeps the threshold a box's.
  void getBoundingSphere(btVector3& center, btScalar& radius) const override {
    center.setValue(0, 0, 0);
    radius = getHalfExtentsWithMargin().length();
  }
};

}  // namespace hlt::bullet
