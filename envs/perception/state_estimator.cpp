#include "envs/perception/state_estimator.h"

#include <cmath>

#include "envs/perception/pose_math.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

Eigen::Isometry3d interpolate(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to,
                              double position_gain, double rotation_gain) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translation() = from.translation() + position_gain * (to.translation() - from.translation());
  const Eigen::Quaterniond a(from.linear()), b(to.linear());
  out.linear() = a.slerp(rotation_gain, b).normalized().toRotationMatrix();
  return out;
}

const TagDetection* find_tag(const std::vector<TagDetection>& tags, int id) {
  for (const TagDetection& t : tags)
    if (t.id == id) return &t;
  return nullptr;
}

}  // namespace

const char* to_string(EstimateSource source) {
  switch (source) {
    case EstimateSource::kNone:
      return "none";
    case EstimateSource::kTag:
      return "tag";
    case EstimateSource::kColour:
      return "colour";
    case EstimateSource::kHeld:
      return "held";
  }
  return "?";
}

Eigen::VectorXd TaskState::vector() const {
  Eigen::VectorXd v(6);
  const Eigen::Vector3d e = end_effector.table_from_object.translation();
  const Eigen::Vector3d b = block.table_from_object.translation();
  const Eigen::Vector3d t = target.table_from_object.translation();
  const double ye = yaw_of(end_effector.table_from_object.linear());
  const double yb = yaw_of(block.table_from_object.linear());
  const double yt = yaw_of(target.table_from_object.linear());
  v << b.x() - e.x(), b.y() - e.y(), wrap_angle(yb - ye), t.x() - b.x(), t.y() - b.y(), wrap_angle(yt - yb);
  for (int i = 0; i < v.size(); ++i)
    if (!std::isfinite(v(i))) v(i) = 0.0;  // unreachable by construction; kept as the last line of defence
  return v;
}

StateEstimator::StateEstimator(TagConfig config, StateEstimatorOptions options,
                               std::optional<Eigen::Isometry3d> table_from_camera)
    : config_(std::move(config)), options_(std::move(options)), prior_(table_from_camera) {
  auto gain_ok = [](double g) { return std::isfinite(g) && g > 0 && g <= 1; };
  check(gain_ok(options_.position_gain) && gain_ok(options_.rotation_gain) && gain_ok(options_.table_gain),
        "StateEstimator: filter gains must be in (0, 1]");
  check(options_.jump_distance > 0 && options_.jump_angle > 0,
        "StateEstimator: jump limits must be positive");
  check(options_.max_misses >= 0 && options_.max_age > 0, "StateEstimator: max_misses >= 0 and max_age > 0");
  for (const std::string* name : {&options_.block, &options_.target, &options_.end_effector})
    config_.by_name(*name);  // throws, naming the configured tags, if the task's object has no tag
  check(config_.reference() != nullptr || prior_.has_value(),
        "StateEstimator: the tag config has no reference tag (a tag with 'table_pose') and no camera "
        "extrinsics "
        "were given, so the table frame is unknown");
  if (prior_) check(is_finite(*prior_), "StateEstimator: the prior camera-to-table transform is not finite");
  reset();
}

void StateEstimator::reset() {
  state_ = TaskState{};
  started_ = false;
  last_time_ = 0.0;
  for (double& t : last_seen_)
    t = 0.0;
  state_.frame = -1;
  if (prior_) {
    state_.table_known = true;
    state_.table_from_camera = *prior_;
  }
}

void StateEstimator::update_table(const std::vector<TagDetection>& tags) {
  const TagSpec* ref = config_.reference();
  if (!ref) {  // the prior (extrinsics) is the table frame; nothing to refresh
    state_.table_stale = false;
    return;
  }
  const TagDetection* d = find_tag(tags, ref->id);
  if (!d || !is_finite(d->camera_from_tag)) {
    state_.table_stale = true;
    return;
  }
  const Eigen::Isometry3d measured = *ref->table_from_tag * d->camera_from_tag.inverse();
  if (!is_finite(measured)) {
    state_.table_stale = true;
    return;
  }
  state_.table_stale = false;
  const Eigen::Isometry3d& cur = state_.table_from_camera;
  const bool jump = (measured.translation() - cur.translation()).norm() > options_.jump_distance ||
                    rotation_angle_between(measured.linear(), cur.linear()) > options_.jump_angle;
  if (!state_.table_known || jump) {
    state_.table_from_camera = measured;  // first sight, or the camera was moved
  } else {
    state_.table_from_camera = interpolate(cur, measured, options_.table_gain, options_.table_gain);
  }
  state_.table_known = true;
}

void StateEstimator::blend(ObjectEstimate& est, const Eigen::Isometry3d& measured, bool has_rotation) {
  const Eigen::Isometry3d& cur = est.table_from_object;
  Eigen::Isometry3d target = measured;
  if (!has_rotation) target.linear() = cur.linear();
  const bool jump = (target.translation() - cur.translation()).norm() > options_.jump_distance ||
                    rotation_angle_between(target.linear(), cur.linear()) > options_.jump_angle;
  if (!est.valid || jump) {
    est.table_from_object = target;
  } else {
    est.table_from_object =
        interpolate(cur, target, options_.position_gain, has_rotation ? options_.rotation_gain : 0);
  }
}

void StateEstimator::update_object(ObjectEstimate& est, const TagSpec& spec,
                                   const std::vector<TagDetection>& tags, const BlockFallback* fallback) {
  const int slot = &est == &state_.block ? 0 : &est == &state_.target ? 1 : 2;
  std::optional<Eigen::Isometry3d> measured;
  EstimateSource source = EstimateSource::kNone;
  bool has_rotation = true;
  if (state_.table_known) {
    if (const TagDetection* d = find_tag(tags, spec.id)) {
      const Eigen::Isometry3d m = state_.table_from_camera * d->camera_from_tag * spec.tag_from_object;
      if (is_finite(m)) {
        measured = m;
        source = EstimateSource::kTag;
      }
    }
    if (!measured && fallback && *fallback) {
      if (const std::optional<Eigen::Vector3d> p = (*fallback)(state_.table_from_camera);
          p && p->allFinite()) {
        Eigen::Isometry3d m = est.table_from_object;
        m.translation() = *p;
        measured = m;
        source = EstimateSource::kColour;
        has_rotation = false;
      }
    }
  }
  if (measured) {
    blend(est, *measured, has_rotation);
    est.ever_measured = true;
    est.valid = true;
    est.stale = false;
    est.source = source;
    est.misses = 0;
    est.age = 0.0;
    last_seen_[slot] = state_.time;
    return;
  }
  est.stale = true;
  est.source = est.ever_measured ? EstimateSource::kHeld : EstimateSource::kNone;
  ++est.misses;
  est.age = est.ever_measured ? state_.time - last_seen_[slot] : 0.0;
  est.valid = est.ever_measured && est.misses <= options_.max_misses && est.age <= options_.max_age;
}

const TaskState& StateEstimator::update(double time, const std::vector<TagDetection>& tags,
                                        const BlockFallback& fallback) {
  check(std::isfinite(time), "StateEstimator::update: time is not finite");
  check(!started_ || time >= last_time_, "StateEstimator::update: time went backwards ({} after {})", time,
        last_time_);
  started_ = true;
  last_time_ = time;
  ++state_.frame;
  state_.time = time;
  update_table(tags);
  update_object(state_.block, config_.by_name(options_.block), tags, &fallback);
  update_object(state_.target, config_.by_name(options_.target), tags, nullptr);
  update_object(state_.end_effector, config_.by_name(options_.end_effector), tags, nullptr);
  return state_;
}

}  // namespace hlt
