#include "envs/robot/camera_observed.h"

#include <cmath>
#include <ctime>

#include "envs/perception/pose_math.h"
#include "envs/robot/block_push.h"
#include "envs/robot/block_stack.h"
#include "hlt/util/error.h"

namespace hlt::robot {

namespace {

// CPU time of the calling thread: what a control step costs on one core, whatever else shares it.
double thread_cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

// A pose with the given position and only the yaw of `orientation` (the tools point down; the camera's
// objects are z up).
Eigen::Isometry3d upright(const Eigen::Vector3d& position, double yaw) {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  p.translation() = position;
  return p;
}

Eigen::Isometry3d offset(double x, double y, double z) {
  return Eigen::Isometry3d(Eigen::Translation3d(x, y, z));
}

TagSpec tag(int id, std::string name, double size, const Eigen::Isometry3d& object_from_tag) {
  return {id, std::move(name), size, object_from_tag.inverse(), std::nullopt};
}

TagSpec reference_tag(int id, double size, double x, double y, double yaw) {
  return {id, "table", size, Eigen::Isometry3d::Identity(), upright({x, y, 0.0}, yaw)};
}

// A 640x480 camera with fx = fy = 600 (experiments/configs/perception/camera_640x480.yaml).
CameraModel task_camera(const Eigen::Isometry3d& world_from_camera) {
  CameraModel camera;
  camera.set_world_from_camera(world_from_camera);
  return camera;
}

// In the loop the tool moves up to 4 cm per control step: an exponential filter of the positions would lag
// by centimetres, while a tag's pose is good to a fraction of a millimetre. So each measurement is taken as
// it is; the filter still averages the fixed camera's table transform, holds missed objects and counts the
// misses.
PerceptionOptions loop_perception() {
  PerceptionOptions o;
  o.estimator.position_gain = 1.0;
  o.estimator.rotation_gain = 1.0;
  return o;
}

// Only the images are rendered from the true camera pose: perception finds the table frame from the
// reference tag alone, as it would without a calibrated camera pose.
CameraModel without_extrinsics(CameraModel camera) {
  camera.clear_extrinsics();
  return camera;
}

uint64_t frame_seed(uint64_t seed, int64_t frame) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL * static_cast<uint64_t>(frame + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

}  // namespace

CameraObserved::CameraObserved(std::string name, std::unique_ptr<Env> task, CameraTaskSpec spec)
    : name_(std::move(name)),
      task_(std::move(task)),
      spec_(std::move(spec)),
      scene_(spec_.tags, spec_.layout),
      renderer_(task_camera(spec_.world_from_camera)),
      pipeline_(without_extrinsics(renderer_.camera()), spec_.tags, [&] {
        PerceptionOptions o = spec_.perception;
        o.estimator.objects = spec_.objects;
        return o;
      }()) {
  check(task_ != nullptr, "{}: no task to observe", name_);
  check(spec_.scene && spec_.truth && spec_.observe && spec_.reward, "{}: incomplete camera task", name_);
  check(spec_.noise_sigma >= 0 && std::isfinite(spec_.noise_sigma), "{}: bad noise sigma", name_);
  renderer_.set_static_quads(scene_.static_quads());
}

Eigen::VectorXd CameraObserved::perceive(const Eigen::VectorXd& state_observation) {
  const double t0 = thread_cpu_ms();
  ImageEffects effects;
  effects.noise_sigma = spec_.noise_sigma;
  const int64_t frame = pipeline_.estimator().state().frame + 1;
  effects.seed = frame_seed(noise_seed_, frame);
  image_ = renderer_.render(scene_.part_quads(spec_.scene()), effects);
  const double t1 = thread_cpu_ms();
  record_.render_ms = t1 - t0;
  const FrameResult& r = pipeline_.process(image_, static_cast<double>(frame) * task_->dt());
  Eigen::VectorXd observation = spec_.observe(r.state, state_observation);
  record_.perceive_ms = thread_cpu_ms() - t1;

  const std::vector<Eigen::Isometry3d> truth = spec_.truth();
  const size_t n = spec_.objects.size();
  check(truth.size() == n, "{}: {} true poses for {} objects", name_, truth.size(), n);
  record_.position_error.resize(n);
  record_.yaw_error.resize(n);
  record_.source.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Isometry3d& est = r.state.objects[i].table_from_object;
    record_.position_error[i] = (est.translation() - truth[i].translation()).norm();
    record_.yaw_error[i] = std::abs(wrap_angle(hlt::yaw_of(est.linear()) - hlt::yaw_of(truth[i].linear())));
    record_.source[i] = r.state.objects[i].source;
  }
  record_.state_observation = state_observation;
  return observation;
}

Eigen::VectorXd CameraObserved::reset_impl(std::mt19937_64& rng) {
  const Eigen::VectorXd state = task_->reset(rng());
  noise_seed_ = rng();
  pipeline_.reset();
  return perceive(state);
}

StepResult CameraObserved::step_impl(const Eigen::VectorXd& action) {
  StepResult r = task_->step(action);
  if (!r.failure.empty()) return r;  // the simulation failed: nothing to render
  r.observation = perceive(r.observation);
  r.reward = spec_.reward(r.observation, action);
  return r;
}

std::vector<double> CameraObserved::save_sim() const {
  std::vector<double> s = pipeline_.estimator().save();
  // The noise seed as two exact 32-bit halves.
  s.push_back(static_cast<double>(noise_seed_ >> 32));
  s.push_back(static_cast<double>(noise_seed_ & 0xffffffffULL));
  return s;
}

void CameraObserved::restore_sim(const std::vector<double>& sim) {
  check(sim.size() >= 2, "{}: snapshot has {} values", name_, sim.size());
  const double hi = sim[sim.size() - 2], lo = sim[sim.size() - 1];
  check(hi >= 0 && hi < 4294967296.0 && lo >= 0 && lo < 4294967296.0 && hi == std::floor(hi) &&
            lo == std::floor(lo),
        "{}: snapshot has a bad noise seed", name_);
  pipeline_.estimator().restore(std::vector<double>(sim.begin(), sim.end() - 2));
  noise_seed_ = (static_cast<uint64_t>(hi) << 32) | static_cast<uint64_t>(lo);
}

void CameraObserved::restore_wrapped(const EnvState& state) {
  check(state.wrapped.size() == 1, "{}: snapshot does not hold the observed task", name_);
  task_->restore_state(state.wrapped.front());
}

namespace {

// Block pushing seen by the Sawyer set-up's camera (TabletopScene's, moved onto the task's workspace): tags
// on the block's top, the target plate and the top of the end-effector's mount.
std::unique_ptr<Env> make_push_camera() {
  auto task = std::make_unique<BlockPush>();
  BlockPush* push = task.get();
  // The workspace's centre is where TabletopScene's default set-up has its objects, shifted by this.
  const Eigen::Vector3d shift(0.425, -0.075, 0.0);
  CameraTaskSpec spec;
  const double ee_height = 0.10;  // the tag sits on the mount's top, 10 cm over the tool's tip
  spec.tags = TagConfig(
      "tag36h11", {reference_tag(0, 0.048, shift.x(), shift.y(), 0.0),
                   tag(1, "block", 0.033, offset(0, 0, 0.025)), tag(2, "target", 0.048, offset(0, 0, 0.0015)),
                   tag(3, "end_effector", 0.033, offset(0, 0, ee_height))});
  spec.perception = loop_perception();
  spec.objects = pushing_objects();
  spec.objects[0].planar_height = 0.025;                   // the block rests on the table,
  spec.objects[1].planar_height = 0.0015;                  // the target is a plate on it,
  spec.objects[2].planar_height = BlockPush::kToolHeight;  // and the tool is held at the block's mid-height
  spec.world_from_camera = Eigen::Translation3d(shift) * TabletopScene::default_camera_pose();
  spec.layout.table_x0 = 0.1;
  spec.layout.table_x1 = 1.1;
  spec.layout.table_y0 = -0.7;
  spec.layout.table_y1 = 0.7;
  const TabletopLayout L = spec.layout;
  auto poses = [push] {
    const Eigen::Isometry3d tool = push->scene().arm().tool_pose();
    const Eigen::Vector3d& t = push->target();
    return std::vector<Eigen::Isometry3d>{push->scene().block_pose(0), upright({t.x(), t.y(), 0.0015}, t.z()),
                                          upright(tool.translation(), yaw_of(tool))};
  };
  spec.truth = poses;
  spec.scene = [poses, L, ee_height] {
    const std::vector<Eigen::Isometry3d> p = poses();
    const Eigen::Vector3d ee_size(L.end_effector_size.x(), L.end_effector_size.y(), ee_height);
    return std::vector<ScenePart>{
        {p[1], {{Eigen::Isometry3d::Identity(), L.target_size, L.target_colour}}, {"target"}},
        {p[0], {{Eigen::Isometry3d::Identity(), L.block_size, L.block_colour}}, {"block"}},
        {p[2], {{offset(0, 0, 0.5 * ee_height), ee_size, L.end_effector_colour}}, {"end_effector"}}};
  };
  // The poses from the camera; the tool's position and command from the robot itself.
  spec.observe = [](const TaskState& estimate, const Eigen::VectorXd& state) {
    Eigen::VectorXd o(BlockPush::kObservationDim);
    o << estimate.vector(), state.tail(BlockPush::kObservationDim - 6);
    return o;
  };
  spec.reward = [](const Eigen::VectorXd& o, const Eigen::VectorXd& a) {
    return BlockPush::reward(o, a.cwiseMax(-1.0).cwiseMin(1.0));
  };
  return std::make_unique<CameraObserved>("block_push_camera", std::move(task), std::move(spec));
}

// Block stacking seen from in front of the Panda (the camera at the far side of the table, looking back
// and down at about 35 degrees). Each block has a tag on its top and one on its +x face (towards the
// camera), so a block held in the gripper, whose top the hand hides, is still seen; the hand has tags on
// its top and front. Positions are 3-D (the block is lifted); the gripper opening and the wrench come from
// the robot.
std::unique_ptr<Env> make_stack_camera() {
  auto task = std::make_unique<BlockStack>();
  BlockStack* stack = task.get();
  constexpr double h = BlockStack::kBlockHalf;
  // The hand: a box 4.4 cm over the tool centre point (between the fingertips).
  const Eigen::Vector3d hand_size(0.06, 0.2, 0.06);
  constexpr double hand_bottom = 0.044;
  const Eigen::Isometry3d front =
      offset(h, 0, 0) * Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()) *
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());  // tag z along the block's x, tag y up
  // The hand's top tag is seen at a grazing angle from the front camera (missed in about one frame in 20),
  // so the hand has a second one on its front face.
  const Eigen::Isometry3d hand_front = offset(0.5 * hand_size.x(), 0, hand_bottom + 0.5 * hand_size.z()) *
                                       Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()) *
                                       Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
  CameraTaskSpec spec;
  spec.tags =
      TagConfig("tag36h11", {reference_tag(0, 0.048, 0.82, -0.12, 0.0),
                             tag(1, "block_top", 0.036, offset(0, 0, h)), tag(2, "block_front", 0.036, front),
                             tag(3, "base_top", 0.036, offset(0, 0, h)), tag(4, "base_front", 0.036, front),
                             tag(5, "hand", 0.04, offset(0, 0, hand_bottom + hand_size.z())),
                             tag(6, "hand_front", 0.04, hand_front)});
  spec.perception = loop_perception();
  spec.perception.colour_fallback = false;  // two blocks, and a lifted one is off the table plane
  spec.objects = {{"block", {"block_top", "block_front"}, false, std::nullopt},
                  {"base", {"base_top", "base_front"}, false, std::nullopt},
                  {"end_effector", {"hand", "hand_front"}, false, std::nullopt}};
  spec.world_from_camera = look_at(Eigen::Vector3d(1.2, 0.05, 0.55), Eigen::Vector3d(0.52, 0.05, 0.04));
  spec.layout.table_x0 = -0.2;
  spec.layout.table_x1 = 1.1;
  spec.layout.table_y0 = -0.7;
  spec.layout.table_y1 = 0.7;
  auto poses = [stack] {
    const Eigen::Isometry3d tool = stack->scene().arm().tool_pose();
    return std::vector<Eigen::Isometry3d>{stack->scene().block_pose(0), stack->scene().block_pose(1),
                                          upright(tool.translation(), yaw_of(tool))};
  };
  spec.truth = poses;
  const cv::Vec3b red(40, 40, 200), blue(190, 110, 40), grey(95, 95, 100), dark(60, 60, 60);
  spec.scene = [poses, stack, hand_size, red, blue, grey, dark] {
    const std::vector<Eigen::Isometry3d> p = poses();
    const Eigen::Vector3d cube = Eigen::Vector3d::Constant(2 * h);
    const double opening = stack->scene().arm().finger_opening();
    const Eigen::Vector3d finger(0.02, 0.01, 0.05);
    return std::vector<ScenePart>{
        {p[1], {{Eigen::Isometry3d::Identity(), cube, blue}}, {"base_top", "base_front"}},
        {p[0], {{Eigen::Isometry3d::Identity(), cube, red}}, {"block_top", "block_front"}},
        {p[2],
         {{offset(0, 0, hand_bottom + 0.5 * hand_size.z()), hand_size, grey},
          {offset(0, opening + 0.5 * finger.y(), hand_bottom - 0.5 * finger.z()), finger, dark},
          {offset(0, -opening - 0.5 * finger.y(), hand_bottom - 0.5 * finger.z()), finger, dark}},
         {"hand", "hand_front"}}};
  };
  spec.observe = [](const TaskState& estimate, const Eigen::VectorXd& state) {
    Eigen::VectorXd o = state;  // gripper opening and wrench: the robot's own sensors
    o.segment<3>(BlockStack::kEe) = estimate.object("end_effector").table_from_object.translation();
    o.segment<3>(BlockStack::kBlock) = estimate.object("block").table_from_object.translation();
    o.segment<3>(BlockStack::kBase) = estimate.object("base").table_from_object.translation();
    return o;
  };
  spec.reward = [](const Eigen::VectorXd& o, const Eigen::VectorXd& a) {
    return BlockStack::reward(o, Eigen::Vector4d(a.cwiseMax(-1.0).cwiseMin(1.0)));
  };
  return std::make_unique<CameraObserved>("block_stack_camera", std::move(task), std::move(spec));
}

}  // namespace

}  // namespace hlt::robot

namespace hlt {

std::unique_ptr<Env> make_block_push_camera() {
  return robot::make_push_camera();
}

std::unique_ptr<Env> make_block_stack_camera() {
  return robot::make_stack_camera();
}

}  // namespace hlt
