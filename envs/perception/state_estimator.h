// hlt::StateEstimator: turns tag detections (and, when an object's tags are not seen, a colour-tracked
// position) into the poses of the objects a task names, in the table frame, with a simple filter and explicit
// handling of missed detections. By default the objects are the pushing task's: block, target, end-effector.
//
// The camera-to-table transform comes from the reference tag (or a prior such as the calibration's
// extrinsics) and is averaged over frames, since the camera is fixed. Each object's pose is an exponential
// filter of its measurements; a measurement far from the estimate replaces it (the object was moved, or
// re-acquired). A frame without a measurement holds the last estimate, marks it stale and counts the miss;
// after too many misses or too long the object is reported invalid, but its value stays the last finite
// estimate. Nothing here ever produces NaN: non-finite measurements are rejected as misses.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "envs/perception/tag_config.h"
#include "envs/perception/tag_detector.h"

namespace hlt {

enum class EstimateSource { kNone, kTag, kColour, kHeld };
const char* to_string(EstimateSource source);

struct ObjectEstimate {
  Eigen::Isometry3d table_from_object = Eigen::Isometry3d::Identity();
  bool ever_measured = false;
  bool valid = false;                             // measured, and not missed for longer than the limits
  bool stale = false;                             // not measured in the latest frame: the value is held
  EstimateSource source = EstimateSource::kNone;  // what updated it in the latest frame
  int misses = 0;                                 // consecutive frames without a measurement
  double age = 0.0;                               // seconds since the last measurement (0 if never measured)
};

// One object a task wants located.
struct TrackedObject {
  std::string name;
  // Tag-config names of the tags stuck on it (several faces of a block, say); empty means one tag named
  // like the object. Seen together, their positions are averaged and the orientation is taken from the
  // tag with the largest decision margin.
  std::vector<std::string> tags;
  // Whether to ask the estimator's position fallback (colour tracking) when none of its tags is seen.
  bool colour_fallback = false;
  // Set for an object that rests on the table: the measured pose is constrained to this height with only
  // its yaw kept (roll and pitch are then not noise on the estimate).
  std::optional<double> planar_height;
};

// The pushing task's objects: the block (with the colour fallback), the target and the end-effector.
std::vector<TrackedObject> pushing_objects();

struct TaskState {
  int64_t frame = 0;
  double time = 0.0;
  bool table_known = false;  // a camera-to-table transform is available
  bool table_stale = false;  // the reference tag was not seen in the latest frame
  Eigen::Isometry3d table_from_camera = Eigen::Isometry3d::Identity();
  std::vector<std::string> names;       // the tracked objects, in the estimator's order
  std::vector<ObjectEstimate> objects;  // their estimates, same order

  // Throws hlt::Error naming the tracked objects for an unknown name.
  const ObjectEstimate& object(const std::string& name) const;
  bool has(const std::string& name) const;
  bool valid() const;  // the table and every object valid
  // The pushing task's observation in the table frame: end-effector to block (dx, dy, dyaw), then block to
  // target (dx, dy, dyaw); yaw differences wrapped to (-pi, pi]. Always finite. Empty unless the objects
  // block, target and end_effector are tracked.
  Eigen::VectorXd vector() const;
};

struct StateEstimatorOptions {
  double position_gain = 0.6;   // weight of a new position measurement (1 = no filtering)
  double rotation_gain = 0.6;   // weight of a new orientation measurement (slerp)
  double table_gain = 0.2;      // the same for the camera-to-table transform
  double jump_distance = 0.05;  // metres; a measurement farther than this from the estimate replaces it
  double jump_angle = 0.5;      // radians; the same for orientation
  int max_misses = 30;          // an object missed for more frames than this is invalid
  double max_age = 3.0;         // or for longer than this (seconds)
  std::vector<TrackedObject> objects = pushing_objects();
};

class StateEstimator {
 public:
  // `table_from_camera`: a prior camera-to-table transform (e.g. the calibration's extrinsics), used until
  // the reference tag is seen. Without a reference tag in `config`, the prior is required.
  explicit StateEstimator(TagConfig config, StateEstimatorOptions options = {},
                          std::optional<Eigen::Isometry3d> table_from_camera = std::nullopt);

  // Position of an object (one with `colour_fallback`) in the table frame from another cue, given the
  // current camera-to-table transform; consulted only when none of the object's tags is seen.
  using PositionFallback = std::function<std::optional<Eigen::Vector3d>(
      const TrackedObject& object, const Eigen::Isometry3d& table_from_camera)>;

  // One frame. `time` (seconds) must not decrease.
  const TaskState& update(double time, const std::vector<TagDetection>& tags,
                          const PositionFallback& fallback = {});
  const TaskState& state() const { return state_; }
  const std::vector<TrackedObject>& objects() const { return options_.objects; }
  void reset();

  // The whole filter state as numbers, and back: a restored estimator continues exactly as the saved one
  // would have (the robot tasks put this into their snapshots). restore() throws hlt::Error for a vector
  // of the wrong size or with non-finite values.
  std::vector<double> save() const;
  void restore(const std::vector<double>& saved);

 private:
  void update_table(const std::vector<TagDetection>& tags);
  void update_object(size_t index, const std::vector<TagDetection>& tags, const PositionFallback& fallback);
  void blend(ObjectEstimate& est, const Eigen::Isometry3d& measured, bool has_rotation);

  TagConfig config_;
  StateEstimatorOptions options_;
  std::optional<Eigen::Isometry3d> prior_;
  TaskState state_;
  bool started_ = false;
  double last_time_ = 0.0;
  std::vector<std::vector<size_t>> tag_index_;  // per object, its tags' places in config_.tags()
  std::vector<double> last_seen_;               // per object, the time of its last measurement
};

}  // namespace hlt
