#include "envs/robot/tabletop.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "envs/bullet/draw.h"
#include "envs/render.h"
#include "hlt/util/error.h"

namespace hlt::robot {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTableThickness = 0.05;
// Snapshot layout after the world's values: the filter, the mean wrench, the finger speed, the external
// force, the hand's momentum.
constexpr size_t kExtra = 6 + 6 + 1 + 3 + 3;

bullet::RobotSpec block_spec(const BlockSpec& b, int index) {
  bullet::RobotSpec spec;
  spec.name = "block" + std::to_string(index);
  spec.fixed_base = false;
  bullet::BodySpec& body = spec.base;
  body.name = spec.name;
  body.mass = b.mass;
  // Placed away from the table and each other; set_block puts them where a task wants them.
  body.com = Eigen::Vector3d(0.5 + 0.2 * index, 0.5, b.half_extents.z());
  const Eigen::Vector3d sq = (2 * b.half_extents).cwiseAbs2();
  body.inertia = b.mass / 12.0 * Eigen::Vector3d(sq.y() + sq.z(), sq.x() + sq.z(), sq.x() + sq.y());
  body.shapes = {bullet::Shape::box(body.com, b.half_extents)};
  body.collides = true;
  body.friction = b.friction;
  body.world_sized_bounds = true;
  return spec;
}

}  // namespace

double yaw_of(const Eigen::Isometry3d& pose) {
  const Eigen::Vector3d x = pose.linear().col(0);
  return std::atan2(x.y(), x.x());
}

Tabletop::Tabletop(const TabletopSettings& settings) : settings_(settings), controller_(settings.control) {
  check(settings_.control_dt > 0 && settings_.substeps >= 1,
        "tabletop: bad control step {} s in {} sub-steps", settings_.control_dt, settings_.substeps);
  bullet::WorldSettings ws;
  ws.solver_iterations = settings_.solver_iterations;
  gravity_z_ = ws.gravity_z;
  world_ = std::make_unique<bullet::World>(ws);
  const double near = settings_.arm == ArmKind::kSawyer ? 0.2 : -0.3;
  table_ =
      settings_.table.value_or(Eigen::AlignedBox2d(Eigen::Vector2d(near, -0.7), Eigen::Vector2d(1.1, 0.7)));
  check(!table_.isEmpty(), "tabletop: the table has no extent");
  const Eigen::Vector2d c = table_.center();
  const Eigen::Vector2d half = 0.5 * table_.sizes();
  world_->add_static_box(Eigen::Vector3d(c.x(), c.y(), -0.5 * kTableThickness),
                         Eigen::Vector3d(half.x(), half.y(), 0.5 * kTableThickness), settings_.table_friction,
                         0.0);
  const Eigen::Vector3d base = Eigen::Vector3d::Zero();
  arm_ = std::make_unique<Arm>(*world_,
                               settings_.arm == ArmKind::kSawyer ? sawyer_model(base) : panda_model(base));
  for (size_t i = 0; i < settings_.blocks.size(); ++i)
    blocks_.push_back(&world_->add_robot(block_spec(settings_.blocks[i], static_cast<int>(i))));
  world_->clear_contacts();
}

Tabletop::~Tabletop() {
  // The arm's motors live in the world: they go before it.
  arm_.reset();
}

Eigen::Isometry3d Tabletop::block_pose(int i) const {
  check(i >= 0 && i < num_blocks(), "tabletop: no block {}", i);
  return blocks_[i]->body_pose(-1);
}

Eigen::Vector3d Tabletop::block_velocity(int i) const {
  check(i >= 0 && i < num_blocks(), "tabletop: no block {}", i);
  return blocks_[i]->base_linear_velocity();
}

void Tabletop::set_block(int i, const Eigen::Vector3d& position, double yaw) {
  check(i >= 0 && i < num_blocks(), "tabletop: no block {}", i);
  blocks_[i]->set_base_state(position, Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())),
                             Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  world_->clear_contacts();
}

void Tabletop::reset_arm(const Vector7d& q, double finger_opening) {
  arm_->set_configuration(q, finger_opening);
  controller_.reset();
  finger_speed_ = 0.0;
  // What the wrist reads at rest, not zero: a zero reading would be an external force of the hand's weight
  // (7.4 N on the Panda) at every episode's first observation, which no later state shows.
  mean_wrench_ = arm_->resting_wrist_wrench(gravity_z_);
  external_force_.setZero();
  hand_momentum_.setZero();
  world_->clear_contacts();
}

void Tabletop::step(const Vector6d& twist, double finger_speed) {
  check(std::isfinite(finger_speed), "tabletop: finger speed must be finite");
  controller_.command(twist);
  finger_speed_ = finger_speed;
  const double h = settings_.control_dt / settings_.substeps;
  Vector6d sum = Vector6d::Zero();
  for (int s = 0; s < settings_.substeps; ++s) {
    arm_->drive(controller_.joint_velocities(*arm_, h), finger_speed_, h);
    world_->step(h, 1);
    sum += arm_->wrist_wrench();
  }
  mean_wrench_ = sum / settings_.substeps;
  // The hand's motion: dp/dt = weight + external - wrist, and the mean of dp/dt over the step is the change
  // of p (kept from the last step's end rather than read back, so that a restored snapshot continues
  // exactly).
  const Eigen::Vector3d momentum = arm_->hand_momentum();
  const Eigen::Vector3d accelerating = (momentum - hand_momentum_) / settings_.control_dt;
  hand_momentum_ = momentum;
  external_force_ = mean_wrench_.head<3>() - arm_->resting_wrist_wrench(gravity_z_).head<3>() + accelerating;
}

std::vector<double> Tabletop::save_state() const {
  std::vector<double> s = world_->save_state();
  const Vector6d& f = controller_.state();
  s.insert(s.end(), f.data(), f.data() + 6);
  s.insert(s.end(), mean_wrench_.data(), mean_wrench_.data() + 6);
  s.push_back(finger_speed_);
  s.insert(s.end(), external_force_.data(), external_force_.data() + 3);
  s.insert(s.end(), hand_momentum_.data(), hand_momentum_.data() + 3);
  return s;
}

void Tabletop::restore_state(const std::vector<double>& state) {
  check(state.size() > kExtra, "tabletop: snapshot has {} values", state.size());
  check(std::all_of(state.begin(), state.end(), [](double x) { return std::isfinite(x); }),
        "tabletop: snapshot contains NaN or Inf");
  const std::vector<double> world(state.begin(), state.end() - kExtra);
  world_->restore_state(world);  // checks the size
  const double* extra = state.data() + world.size();
  controller_.set_state(Eigen::Map<const Vector6d>(extra));
  mean_wrench_ = Eigen::Map<const Vector6d>(extra + 6);
  finger_speed_ = extra[12];
  external_force_ = Eigen::Map<const Eigen::Vector3d>(extra + 13);
  hand_momentum_ = Eigen::Map<const Eigen::Vector3d>(extra + 16);
}

bool Tabletop::state_is_finite() const {
  return world_->state_is_finite() && controller_.state().allFinite();
}

cv::Mat Tabletop::render(int width, int height, const std::vector<Eigen::Vector3d>& marks) const {
  check(width > 1 && height > 0, "render size must be positive, got {}x{}", width, height);
  const TabletopSettings& s = settings_;
  const cv::Scalar table_colour(170, 200, 225);
  // A box's 8 corners projected onto world axes (u, v); their hull is its silhouette.
  const auto box_corners = [](const Eigen::Isometry3d& pose, const Eigen::Vector3d& half, int u, int v) {
    std::vector<cv::Point2f> pts;
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d c =
          pose * Eigen::Vector3d((k & 1 ? 1 : -1) * half.x(), (k & 2 ? 1 : -1) * half.y(),
                                 (k & 4 ? 1 : -1) * half.z());
      pts.emplace_back(static_cast<float>(c[u]), static_cast<float>(c[v]));
    }
    std::vector<cv::Point2f> hull;
    cv::convexHull(pts, hull);
    return std::vector<cv::Point2d>(hull.begin(), hull.end());
  };
  const auto block_corners = [&](int i, int u, int v) {
    return box_corners(block_pose(i), s.blocks[i].half_extents, u, v);
  };
  // The arm's boxes (the Panda's hand and fingers), which bullet::draw_side leaves to the scene.
  const auto arm_boxes = [&](SideView& view, int u, int v) {
    const bullet::Robot& r = arm_->robot();
    for (int link = 0; link < r.num_links(); ++link) {
      for (const bullet::Shape& sh : r.world_shapes(link)) {
        if (!sh.is_box()) continue;
        Eigen::Isometry3d pose = r.body_pose(link);
        pose.translation() = sh.from;
        view.polygon(box_corners(pose, sh.half_extents, u, v), colours::kBody);
      }
    }
  };
  const auto tool_marker = [&](SideView& view, int u, int v) {
    const Eigen::Vector3d p = arm_->tool_pose().translation();
    view.disc(p[u], p[v], 0.012, cv::Scalar(30, 160, 30));
  };

  const int left_w = width / 2;
  // Side view: from -y, the arm and the table's edge, 1.6 m across.
  SideView side(left_w, height, 0.4, 0.35, 1.6);
  const Eigen::Vector2d lo = table_.min(), hi = table_.max();
  side.rectangle(lo.x(), 0.0, hi.x(), -kTableThickness, table_colour);
  side.rectangle(lo.x(), -kTableThickness, hi.x(), -2.0, colours::kGroundFill);
  bullet::draw_side(side, arm_->robot());
  arm_boxes(side, 0, 2);
  for (int i = 0; i < num_blocks(); ++i)
    side.polygon(block_corners(i, 0, 2), s.blocks[i].colour);
  tool_marker(side, 0, 2);
  side.caption(fmt::format("{}  wrist F ({:.1f}, {:.1f}, {:.1f}) N", arm_->model().name, mean_wrench_[0],
                           mean_wrench_[1], mean_wrench_[2]));

  // Top view: the workspace in front of the arm, 0.8 m across.
  SideView top(width - left_w, height, 0.55, 0.0, 0.8);
  top.rectangle(lo.x(), lo.y(), hi.x(), hi.y(), table_colour);
  const Eigen::AlignedBox3d& ws = s.control.workspace;
  if (ws.max().x() - ws.min().x() < 5) {
    const cv::Scalar edge(120, 140, 160);
    top.line(ws.min().x(), ws.min().y(), ws.max().x(), ws.min().y(), edge);
    top.line(ws.max().x(), ws.min().y(), ws.max().x(), ws.max().y(), edge);
    top.line(ws.max().x(), ws.max().y(), ws.min().x(), ws.max().y(), edge);
    top.line(ws.min().x(), ws.max().y(), ws.min().x(), ws.min().y(), edge);
  }
  // The arm first: seen from above it would hide the block it pushes, so blocks and marks go over it.
  bullet::draw_top(top, arm_->robot());
  arm_boxes(top, 0, 1);
  for (int i = 0; i < num_blocks(); ++i)
    top.polygon(block_corners(i, 0, 1), s.blocks[i].colour);
  for (const Eigen::Vector3d& m : marks) {
    const int n = 32;
    for (int k = 0; k < n; ++k) {
      const double a0 = 2 * kPi * k / n, a1 = 2 * kPi * (k + 1) / n, r = 0.026;
      top.line(m.x() + r * std::cos(a0), m.y() + r * std::sin(a0), m.x() + r * std::cos(a1),
               m.y() + r * std::sin(a1), cv::Scalar(60, 180, 60), 2);
    }
  }
  tool_marker(top, 0, 1);

  cv::Mat out(height, width, CV_8UC3);
  side.image().copyTo(out(cv::Rect(0, 0, left_w, height)));
  top.image().copyTo(out(cv::Rect(left_w, 0, width - left_w, height)));
  return out;
}

}  // namespace hlt::robot
