#include "envs/perception/state_estimator.h"

#include <algorithm>
#include <cmath>
#include <set>

#include <fmt/format.h>

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

std::vector<TrackedObject> pushing_objects() {
  TrackedObject block{"block", {}, true, std::nullopt};
  TrackedObject target{"target", {}, false, std::nullopt};
  TrackedObject end_effector{"end_effector", {}, false, std::nullopt};
  return {block, target, end_effector};
}

bool TaskState::has(const std::string& name) const {
  return std::find(names.begin(), names.end(), name) != names.end();
}

const ObjectEstimate& TaskState::object(const std::string& name) const {
  const auto it = std::find(names.begin(), names.end(), name);
  check(it != names.end(), "TaskState: no tracked object '{}'; tracked: {}", name, fmt::join(names, ", "));
  return objects[static_cast<size_t>(it - names.begin())];
}

bool TaskState::valid() const {
  return table_known &&
         std::all_of(objects.begin(), objects.end(), [](const ObjectEstimate& o) { return o.valid; });
}

Eigen::VectorXd TaskState::vector() const {
  if (!has("block") || !has("target") || !has("end_effector")) return {};
  const Eigen::Isometry3d &ee = object("end_effector").table_from_object,
                          &bl = object("block").table_from_object, &ta = object("target").table_from_object;
  Eigen::VectorXd v(6);
  const Eigen::Vector3d e = ee.translation();
  const Eigen::Vector3d b = bl.translation();
  const Eigen::Vector3d t = ta.translation();
  const double ye = yaw_of(ee.linear());
  const double yb = yaw_of(bl.linear());
  const double yt = yaw_of(ta.linear());
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
  check(!options_.objects.empty(), "StateEstimator: no objects to track");
  std::set<std::string> seen;
  for (TrackedObject& o : options_.objects) {
    check(!o.name.empty(), "StateEstimator: a tracked object has no name");
    check(seen.insert(o.name).second, "StateEstimator: object '{}' is listed twice", o.name);
    check(!o.planar_height || std::isfinite(*o.planar_height),
          "StateEstimator: object '{}': planar height "
          "is not finite",
          o.name);
    if (o.tags.empty()) o.tags = {o.name};
    std::vector<size_t> index;
    for (const std::string& tag : o.tags) {
      const TagSpec& spec = config_.by_name(tag);  // throws, naming the configured tags, if there is none
      check(!spec.table_from_tag, "StateEstimator: object '{}' names the reference tag '{}'", o.name, tag);
      index.push_back(static_cast<size_t>(&spec - config_.tags().data()));
    }
    tag_index_.push_back(std::move(index));
  }
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
  last_seen_.assign(options_.objects.size(), 0.0);
  for (const TrackedObject& o : options_.objects)
    state_.names.push_back(o.name);
  state_.objects.assign(options_.objects.size(), ObjectEstimate{});
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

void StateEstimator::update_object(size_t index, const std::vector<TagDetection>& tags,
                                   const PositionFallback& fallback) {
  const TrackedObject& object = options_.objects[index];
  ObjectEstimate& est = state_.objects[index];
  std::optional<Eigen::Isometry3d> measured;
  EstimateSource source = EstimateSource::kNone;
  bool has_rotation = true;
  if (state_.table_known) {
    // Every seen tag of the object gives a pose; positions are averaged, the orientation is the one of the
    // tag decoded with the largest margin (the most confident, usually the least foreshortened).
    Eigen::Vector3d position_sum = Eigen::Vector3d::Zero();
    int count = 0;
    double best_margin = -1.0;
    Eigen::Isometry3d best = Eigen::Isometry3d::Identity();
    for (size_t t : tag_index_[index]) {
      const TagSpec& spec = config_.tags()[t];
      const TagDetection* d = find_tag(tags, spec.id);
      if (!d) continue;
      const Eigen::Isometry3d m = state_.table_from_camera * d->camera_from_tag * spec.tag_from_object;
      if (!is_finite(m)) continue;
      position_sum += m.translation();
      ++count;
      if (d->decision_margin > best_margin) {
        best_margin = d->decision_margin;
        best = m;
      }
    }
    if (count > 0) {
      best.translation() = position_sum / count;
      measured = best;
      source = EstimateSource::kTag;
    }
    if (!measured && object.colour_fallback && fallback) {
      if (const std::optional<Eigen::Vector3d> p = fallback(object, state_.table_from_camera);
          p && p->allFinite()) {
        Eigen::Isometry3d m = est.table_from_object;
        m.translation() = *p;
        measured = m;
        source = EstimateSource::kColour;
        has_rotation = false;
      }
    }
    if (measured && object.planar_height) {
      // Resting on the table: the height is known and only the yaw is free.
      measured->translation().z() = *object.planar_height;
      if (has_rotation)
        measured->linear() =
            Eigen::AngleAxisd(yaw_of(measured->linear()), Eigen::Vector3d::UnitZ()).toRotationMatrix();
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
    last_seen_[index] = state_.time;
    return;
  }
  est.stale = true;
  est.source = est.ever_measured ? EstimateSource::kHeld : EstimateSource::kNone;
  ++est.misses;
  est.age = est.ever_measured ? state_.time - last_seen_[index] : 0.0;
  est.valid = est.ever_measured && est.misses <= options_.max_misses && est.age <= options_.max_age;
}

const TaskState& StateEstimator::update(double time, const std::vector<TagDetection>& tags,
                                        const PositionFallback& fallback) {
  check(std::isfinite(time), "StateEstimator::update: time is not finite");
  check(!started_ || time >= last_time_, "StateEstimator::update: time went backwards ({} after {})", time,
        last_time_);
  started_ = true;
  last_time_ = time;
  ++state_.frame;
  state_.time = time;
  update_table(tags);
  for (size_t i = 0; i < options_.objects.size(); ++i)
    update_object(i, tags, fallback);
  return state_;
}

namespace {

// Snapshot layout: a pose is its translation then its rotation matrix column by column (12 numbers).
void put_pose(std::vector<double>& out, const Eigen::Isometry3d& pose) {
  // linear() is a block of the 4x4 matrix (outer stride 4), so it is copied entry by entry.
  for (int i = 0; i < 3; ++i)
    out.push_back(pose.translation()(i));
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      out.push_back(pose.linear()(r, c));
}

Eigen::Isometry3d get_pose(const double*& p) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Map<const Eigen::Vector3d>(p);
  pose.linear() = Eigen::Map<const Eigen::Matrix3d>(p + 3);
  p += 12;
  return pose;
}

constexpr size_t kHeaderSize = 7 + 12;  // started, last time, frame, time, table known, table stale, count
constexpr size_t kObjectSize = 12 + 7;  // pose, ever measured, valid, stale, source, misses, age, last seen

}  // namespace

std::vector<double> StateEstimator::save() const {
  std::vector<double> out;
  out.reserve(kHeaderSize + kObjectSize * state_.objects.size());
  out.insert(out.end(), {started_ ? 1.0 : 0.0, last_time_, static_cast<double>(state_.frame), state_.time,
                         state_.table_known ? 1.0 : 0.0, state_.table_stale ? 1.0 : 0.0,
                         static_cast<double>(state_.objects.size())});
  put_pose(out, state_.table_from_camera);
  for (size_t i = 0; i < state_.objects.size(); ++i) {
    const ObjectEstimate& o = state_.objects[i];
    put_pose(out, o.table_from_object);
    out.insert(out.end(),
               {o.ever_measured ? 1.0 : 0.0, o.valid ? 1.0 : 0.0, o.stale ? 1.0 : 0.0,
                static_cast<double>(o.source), static_cast<double>(o.misses), o.age, last_seen_[i]});
  }
  return out;
}

void StateEstimator::restore(const std::vector<double>& saved) {
  const size_t n = options_.objects.size();
  check(saved.size() == kHeaderSize + kObjectSize * n,
        "StateEstimator::restore: {} numbers, expected {} for {} objects", saved.size(),
        kHeaderSize + kObjectSize * n, n);
  check(std::all_of(saved.begin(), saved.end(), [](double x) { return std::isfinite(x); }),
        "StateEstimator::restore: the snapshot contains NaN or Inf");
  check(saved[6] == static_cast<double>(n), "StateEstimator::restore: snapshot of {} objects, tracking {}",
        saved[6], n);
  const double* p = saved.data();
  started_ = p[0] != 0;
  last_time_ = p[1];
  state_.frame = static_cast<int64_t>(p[2]);
  state_.time = p[3];
  state_.table_known = p[4] != 0;
  state_.table_stale = p[5] != 0;
  p += 7;
  state_.table_from_camera = get_pose(p);
  for (size_t i = 0; i < n; ++i) {
    ObjectEstimate& o = state_.objects[i];
    o.table_from_object = get_pose(p);
    o.ever_measured = p[0] != 0;
    o.valid = p[1] != 0;
    o.stale = p[2] != 0;
    const int source = static_cast<int>(p[3]);
    check(source >= 0 && source <= static_cast<int>(EstimateSource::kHeld),
          "StateEstimator::restore: bad estimate source {}", p[3]);
    o.source = static_cast<EstimateSource>(source);
    o.misses = static_cast<int>(p[4]);
    o.age = p[5];
    last_seen_[i] = p[6];
    p += 7;
  }
}

}  // namespace hlt
