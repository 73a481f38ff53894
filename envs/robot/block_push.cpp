#include "envs/robot/block_push.h"

#include <algorithm>
#include <cmath>

#include "hlt/util/error.h"

namespace hlt::robot {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kBlockHalf = 0.025;  // a 5 cm cube
// Reset draws block and target this far apart at least, and the block this far from the tool's start, so
// that an episode starts neither solved nor with the tool inside the block.
constexpr double kMinTargetDistance = 0.1;
constexpr double kMinToolDistance = 0.07;
// The block starts this far inside the workspace's edges, so that the tool (clamped to the workspace) can get
// to every side of it: the tool's centre touches the block 4 cm from the block's centre.
constexpr double kBlockMargin = 0.07;

double wrap(double a) {
  a = std::fmod(a + kPi, 2 * kPi);
  if (a <= 0) a += 2 * kPi;
  return a - kPi;
}

TabletopSettings push_settings() {
  TabletopSettings s;
  s.arm = ArmKind::kSawyer;
  BlockSpec block;
  block.half_extents = Eigen::Vector3d::Constant(kBlockHalf);
  block.mass = 0.2;
  block.friction = 0.5;
  s.blocks = {block};
  EeControlSettings& c = s.control;
  c.filter = BlockPush::kFilter;
  c.workspace = Eigen::AlignedBox3d(Eigen::Vector3d(BlockPush::kXMin, BlockPush::kYMin, 0.0),
                                    Eigen::Vector3d(BlockPush::kXMax, BlockPush::kYMax, 0.3));
  c.hold_height = BlockPush::kToolHeight;
  c.hold_orientation = tool_down();
  return s;
}

// The tool's start: the middle of the workspace's near edge.
Eigen::Vector3d tool_start() {
  return {BlockPush::kXMin, 0.5 * (BlockPush::kYMin + BlockPush::kYMax), BlockPush::kToolHeight};
}

}  // namespace

BlockPush::BlockPush() : scene_(std::make_unique<Tabletop>(push_settings())) {
  Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
  start.linear() = tool_down();
  start.translation() = tool_start();
  Arm& arm = scene_->arm();
  check(arm.solve_ik(start, arm.model().seed, &home_),
        "block_push: no joint configuration reaches the start");
  place({0.65, 0.0, 0.0}, {0.7, 0.1, 0.0});
}

void BlockPush::place(const Eigen::Vector3d& block, const Eigen::Vector3d& target) {
  scene_->reset_arm(home_);
  scene_->set_block(0, {block.x(), block.y(), kBlockHalf}, block.z());
  target_ = target;
}

Eigen::VectorXd BlockPush::reset_impl(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> bx(kXMin + kBlockMargin, kXMax - kBlockMargin);
  std::uniform_real_distribution<double> by(kYMin + kBlockMargin, kYMax - kBlockMargin);
  std::uniform_real_distribution<double> ux(kXMin + kBlockHalf, kXMax - kBlockHalf);
  std::uniform_real_distribution<double> uy(kYMin + kBlockHalf, kYMax - kBlockHalf);
  std::uniform_real_distribution<double> uyaw(-kPi, kPi);
  const Eigen::Vector2d tool = tool_start().head<2>();
  Eigen::Vector3d block, target;
  do {
    block << bx(rng), by(rng), uyaw(rng);
  } while ((block.head<2>() - tool).norm() < kMinToolDistance);
  do {
    target << ux(rng), uy(rng), uyaw(rng);
  } while ((target.head<2>() - block.head<2>()).norm() < kMinTargetDistance);
  place(block, target);
  return observation();
}

std::optional<ObservationScale> BlockPush::observation_scale() const {
  ObservationScale s;
  // ee -> block (dx, dy, dyaw), block -> target (dx, dy, dyaw). The block starts 7-25 cm ahead of the tool
  // (x), within the workspace's +-22 cm sideways (y); the target anywhere in the workspace. The tool's
  // position (already from the workspace's centre) over the workspace's half-sizes, its command over the
  // top speed.
  s.offset = Eigen::VectorXd::Zero(kObservationDim);
  s.offset[0] = 0.12;
  s.scale.resize(kObservationDim);
  s.scale << 0.1, 0.15, kPi / 2, 0.1, 0.15, kPi / 2, 0.5 * (kXMax - kXMin), 0.5 * (kYMax - kYMin), kSpeed,
      kSpeed;
  s.reference = Eigen::VectorXi::Constant(kObservationDim, -1);
  return s;
}

Eigen::VectorXd BlockPush::observation() const {
  const Eigen::Isometry3d e = scene_->arm().tool_pose();
  const Eigen::Isometry3d b = scene_->block_pose(0);
  const Vector6d& command = scene_->controller().filtered();
  Eigen::VectorXd v(kObservationDim);
  v << b.translation().x() - e.translation().x(), b.translation().y() - e.translation().y(),
      wrap(yaw_of(b) - yaw_of(e)), target_.x() - b.translation().x(), target_.y() - b.translation().y(),
      wrap(target_.z() - yaw_of(b)), e.translation().x() - 0.5 * (kXMin + kXMax),
      e.translation().y() - 0.5 * (kYMin + kYMax), command[0], command[1];
  return v;
}

double BlockPush::reward(const Eigen::VectorXd& o, const Eigen::Vector2d& a) {
  check(o.size() >= 6, "block_push: observation has {} values, expected at least 6", o.size());
  return -5.0 * o.segment<2>(3).norm() - 10.0 * o.head<2>().norm() - 0.01 * a.squaredNorm();
}

bool BlockPush::success() const {
  const Eigen::Vector3d b = scene_->block_pose(0).translation();
  return (b.head<2>() - target_.head<2>()).norm() < kSuccessRadius;
}

StepResult BlockPush::step_impl(const Eigen::VectorXd& action) {
  const Eigen::Vector2d a = action.cwiseMax(-1.0).cwiseMin(1.0);
  Vector6d twist = Vector6d::Zero();
  twist.head<2>() = kSpeed * a;
  scene_->step(twist);
  StepResult r;
  if (!scene_->state_is_finite()) {
    r.terminated = true;
    r.failure = "block_push: the simulation became non-finite";
    r.observation = Eigen::VectorXd::Zero(kObservationDim);
    return r;
  }
  r.observation = observation();
  r.reward = reward(r.observation, a);
  return r;
}

std::vector<double> BlockPush::save_sim() const {
  std::vector<double> s = scene_->save_state();
  s.insert(s.end(), {target_.x(), target_.y(), target_.z()});
  return s;
}

void BlockPush::restore_sim(const std::vector<double>& sim) {
  check(sim.size() > 3, "block_push: snapshot has {} values", sim.size());
  check(std::all_of(sim.end() - 3, sim.end(), [](double x) { return std::isfinite(x); }),
        "block_push: snapshot contains NaN or Inf");
  scene_->restore_state(std::vector<double>(sim.begin(), sim.end() - 3));
  target_ << sim[sim.size() - 3], sim[sim.size() - 2], sim[sim.size() - 1];
}

cv::Mat BlockPush::render(int width, int height) const {
  cv::Mat img = scene_->render(width, height, {Eigen::Vector3d(target_.x(), target_.y(), 0.0)});
  return img;
}

}  // namespace hlt::robot

namespace hlt {

std::unique_ptr<Env> make_block_push() {
  return std::make_unique<robot::BlockPush>();
}

}  // namespace hlt
