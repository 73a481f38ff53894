#include "envs/locomotion/model.h"

#include <cmath>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <Eigen/Geometry>

#include "hlt/util/error.h"

namespace hlt::locomotion {

namespace {

constexpr double kPi = 3.14159265358979323846;

Eigen::Vector3d single3(const Eigen::Vector3d& v) {
  return {single(v.x()), single(v.y()), single(v.z())};
}

// Bullet's collision filter bits: robot geoms are in the default group and see static objects only, so links
// never touch each other (the three MJCF files rule self-contacts out too) and no link pair enters Bullet's
// pair cache.
constexpr int kDefaultFilter = 1;
constexpr int kStaticFilter = 2;

struct Frames {
  std::vector<Eigen::Vector3d> origin;  // world position of each body's frame at the zero configuration
  std::vector<std::vector<int>> children;
};

Frames check_and_place(const Model& m) {
  check(!m.bodies.empty(), "robot model '{}' has no bodies", m.name);
  Frames f;
  f.children.resize(m.bodies.size());
  std::map<std::string, int> index;
  std::set<std::string> joint_names;
  for (size_t i = 0; i < m.bodies.size(); ++i) {
    const Body& b = m.bodies[i];
    check(!b.name.empty(), "robot model '{}': body {} has no name", m.name, i);
    check(index.count(b.name) == 0, "robot model '{}': two bodies are named '{}'", m.name, b.name);
    check(b.pos.allFinite(), "robot model '{}': body '{}' has a non-finite position", m.name, b.name);
    check(!b.geoms.empty(), "robot model '{}': body '{}' has no geoms", m.name, b.name);
    check(!b.mass || (*b.mass > 0 && std::isfinite(*b.mass)), "robot model '{}': body '{}' has mass {}",
          m.name, b.name, b.mass.value_or(0.0));
    check(b.friction >= 0 && std::isfinite(b.friction), "robot model '{}': body '{}' has friction {}", m.name,
          b.name, b.friction);
    if (i == 0) {
      check(b.parent.empty(), "robot model '{}': the first body '{}' must be the root (no parent)", m.name,
            b.name);
      f.origin.push_back(single3(b.pos));
    } else {
      auto p = index.find(b.parent);
      check(p != index.end(), "robot model '{}': body '{}' names parent '{}', which is not an earlier body",
            m.name, b.name, b.parent);
      f.origin.push_back(f.origin[p->second] + single3(b.pos));
      f.children[p->second].push_back(static_cast<int>(i));
    }
    for (const Joint& j : b.joints) {
      check(!j.name.empty() && joint_names.insert(j.name).second,
            "robot model '{}': body '{}' has a joint without a name or with a name used before ('{}')",
            m.name, b.name, j.name);
      check(j.type == bullet::JointType::kRevolute || j.type == bullet::JointType::kPrismatic,
            "robot model '{}': joint '{}' must be a hinge or a slide", m.name, j.name);
      check(j.pos.allFinite() && j.axis.allFinite() && j.axis.norm() > 0,
            "robot model '{}': joint '{}' has a bad position or axis", m.name, j.name);
      check(!j.actuated || j.range, "robot model '{}': actuated joint '{}' needs a range", m.name, j.name);
      // PyBullet places a body's further joints relative to its first one in a way that agrees with MJCF only
      // when they coincide.
      check(single3(j.pos) == single3(b.joints.front().pos),
            "robot model '{}': the joints of body '{}' must share one position", m.name, b.name);
      check(!j.range || j.range->first < j.range->second, "robot model '{}': joint '{}' has range [{}, {}]",
            m.name, j.name, j.range.value_or(std::make_pair(0.0, 0.0)).first,
            j.range.value_or(std::make_pair(0.0, 0.0)).second);
    }
    for (const Geom& g : b.geoms) {
      check(g.radius > 0 && std::isfinite(g.radius) && g.from.allFinite() && g.to.allFinite() &&
                g.pos.allFinite() && g.half_length >= 0 && std::isfinite(g.half_length) &&
                g.turn_axis.allFinite() && g.turn_axis.norm() > 0 && std::isfinite(g.turn_angle),
            "robot model '{}': body '{}' has a bad geom", m.name, b.name);
      check(g.kind != Geom::Kind::kFromTo || g.from != g.to,
            "robot model '{}': body '{}' has a fromto geom of length 0", m.name, b.name);
    }
    index[b.name] = static_cast<int>(i);
  }
  if (m.bodies[0].joints.empty()) {
    check(!m.bodies[0].mass || *m.bodies[0].mass > 0, "robot model '{}': a floating root needs a mass",
          m.name);
  }
  return f;
}

// The body's shapes in world coordinates at the zero configuration, with their volume.
std::vector<bullet::Shape> world_shapes(const Body& b, const Eigen::Vector3d& origin, double* volume) {
  std::vector<bullet::Shape> shapes;
  *volume = 0.0;
  for (const Geom& g : b.geoms) {
    switch (g.kind) {
      case Geom::Kind::kFromTo: {
        // PyBullet keeps a fromto capsule's radius in single precision too.
        const double r = single(g.radius);
        const Eigen::Vector3d from = origin + single3(g.from), to = origin + single3(g.to);
        shapes.push_back(bullet::Shape::sphere_pair_capsule(from, to, r));
        *volume += bullet::capsule_volume(r, (single3(g.to) - single3(g.from)).norm());
        break;
      }
      case Geom::Kind::kCapsule: {
        const double r = single(g.radius), half = single(g.half_length);
        const Eigen::Vector3d axis =
            Eigen::AngleAxisd(single(g.turn_angle), single3(g.turn_axis).normalized()) *
            Eigen::Vector3d::UnitZ();
        const Eigen::Vector3d centre = origin + single3(g.pos);
        shapes.push_back(bullet::Shape::capsule(centre - half * axis, centre + half * axis, r));
        *volume += bullet::capsule_volume(r, 2 * half);
        break;
      }
      case Geom::Kind::kSphere: {
        // A sphere's size is read in double precision.
        shapes.push_back(bullet::Shape::sphere(origin + single3(g.pos), g.radius));
        *volume += 4.0 / 3.0 * kPi * g.radius * g.radius * g.radius;
        break;
      }
    }
  }
  return shapes;
}

void fill_body(const Body& b, const Eigen::Vector3d& origin, bullet::BodySpec& out) {
  double volume = 0.0;
  out.name = b.name;
  out.shapes = world_shapes(b, origin, &volume);
  out.mass = b.mass ? *b.mass : bullet::kDefaultDensity * volume;
  // PyBullet puts the inertial frame at the middle of the body's last geom if that is a fromto capsule, and
  // at the body's frame origin otherwise (an explicit mass does not move it).
  const Geom& last = b.geoms.back();
  out.com = origin;
  if (last.kind == Geom::Kind::kFromTo) out.com = origin + 0.5 * (single3(last.from) + single3(last.to));
  out.inertia = bullet::estimated_inertia(out.mass, out.shapes, out.com);
  out.collides = true;
  out.friction = single(b.friction);
  out.restitution = 0.0;
  out.collision_group = kDefaultFilter;
  out.collision_mask = kStaticFilter;
}

// The offset of a body's COM from its frame origin, as PyBullet's import holds it.
Eigen::Vector3d local_com(const Body& b) {
  const Geom& last = b.geoms.back();
  if (last.kind == Geom::Kind::kFromTo) return 0.5 * (single3(last.from) + single3(last.to));
  return Eigen::Vector3d::Zero();
}

struct Builder {
  const Model& model;
  const Frames& frames;
  BuiltModel out;

  // Offsets are also given in local form, composed as PyBullet's import composes its transforms, so that the
  // joint frames pick up no rounding from world coordinates.
  void add(int body, int parent_link, const Eigen::Vector3d& parent_local_com) {
    const Body& b = model.bodies[body];
    const Eigen::Vector3d& origin = frames.origin[body];
    const Eigen::Vector3d pos = single3(b.pos);
    int parent = parent_link;
    Eigen::Vector3d first_joint = Eigen::Vector3d::Zero();
    for (size_t k = 0; k < b.joints.size(); ++k) {
      const Joint& j = b.joints[k];
      bullet::LinkSpec l;
      l.name = "joint:" + j.name;
      l.parent = parent;
      l.joint = j.type;
      l.anchor = origin + single3(j.pos);
      l.com = l.anchor;
      l.axis = single3(j.axis);
      l.limits = j.range;
      if (k == 0) {
        first_joint = single3(j.pos);
        l.parent_com_to_pivot = (first_joint + pos) + (-parent_local_com);
      } else {
        l.parent_com_to_pivot = single3(j.pos) + (-first_joint);
      }
      l.pivot_to_com = Eigen::Vector3d::Zero();
      out.spec.links.push_back(l);
      parent = static_cast<int>(out.spec.links.size()) - 1;
      if (j.actuated) out.joints.push_back({j.name, parent, j.range->first, j.range->second, j.power_coef});
    }
    int link = -1;
    if (body == 0 && b.joints.empty()) {
      fill_body(b, origin, out.spec.base);
      out.spec.fixed_base = false;
    } else {
      bullet::LinkSpec l;
      fill_body(b, origin, l);
      l.parent = parent;
      l.joint = bullet::JointType::kFixed;
      l.anchor = origin;
      l.parent_com_to_pivot =
          b.joints.empty() ? Eigen::Vector3d(pos + (-parent_local_com)) : Eigen::Vector3d(-first_joint);
      l.pivot_to_com = local_com(b);
      out.spec.links.push_back(l);
      link = static_cast<int>(out.spec.links.size()) - 1;
    }
    out.bodies[b.name] = link;
    for (int child : frames.children[body])
      add(child, link, local_com(b));
  }
};

}  // namespace

Geom Geom::fromto(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double radius) {
  Geom g;
  g.kind = Kind::kFromTo;
  g.from = from;
  g.to = to;
  g.radius = radius;
  return g;
}

Geom Geom::capsule_about_y(const Eigen::Vector3d& pos, double angle, double radius, double half_length) {
  Geom g;
  g.kind = Kind::kCapsule;
  g.pos = pos;
  g.turn_axis = Eigen::Vector3d::UnitY();
  g.turn_angle = angle;
  g.radius = radius;
  g.half_length = half_length;
  return g;
}

Geom Geom::sphere(const Eigen::Vector3d& pos, double radius) {
  Geom g;
  g.kind = Kind::kSphere;
  g.pos = pos;
  g.radius = radius;
  return g;
}

int BuiltModel::link_of(const std::string& body) const {
  auto it = bodies.find(body);
  if (it != bodies.end()) return it->second;
  std::vector<std::string> names;
  for (const auto& kv : bodies)
    names.push_back(kv.first);
  throw Error(
      fmt::format("robot '{}' has no body '{}'; its bodies: {}", spec.name, body, fmt::join(names, ", ")));
}

BuiltModel build(const Model& model) {
  const Frames frames = check_and_place(model);
  Builder b{model, frames, {}};
  b.out.spec.name = model.name;
  b.out.spec.self_collision = false;
  b.out.spec.disabled_motors = true;
  if (!model.bodies[0].joints.empty()) {
    // PyBullet hangs a root body with joints from a massless fixed base at the world origin.
    b.out.spec.fixed_base = true;
    b.out.spec.base = bullet::BodySpec();
    b.out.spec.base.name = "world";
  }
  b.add(0, -1, Eigen::Vector3d::Zero());
  return std::move(b.out);
}

}  // namespace hlt::locomotion
