// CameraObserved: a robot task observed through the camera pipeline instead of read from the simulator.
// At every control step the synthetic camera renders the simulator's poses (the objects with their tags),
// AprilTag detection, colour tracking and the state estimator locate the objects, and the task's own
// observation is assembled from those estimates, with the robot's own sensors (gripper, wrist wrench)
// taken as they are. The observation has the state-observed task's layout and meaning, and the reward is the
// task's reward of that observation, so a learner cannot tell the two apart except by the estimator's error.
//
// Rendering and perception run once per control step (the wrapped task's step, itself many simulator
// sub-steps). The estimator's filter is part of the snapshot, so save_state()/restore_state() stay exact;
// the image noise is seeded from the episode's generator and the frame number, so a restored environment
// renders the same images.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "envs/env.h"
#include "envs/perception/perception_pipeline.h"
#include "envs/perception/synthetic_camera.h"
#include "envs/perception/tabletop_scene.h"

namespace hlt::robot {

// What a task declares to be camera-observed. The perception table frame is the simulator's world frame.
struct CameraTaskSpec {
  TagConfig tags = TagConfig("tag36h11", {});  // every tag in the scene, the reference tag included
  std::vector<TrackedObject> objects;          // what the estimator locates
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
  TabletopLayout layout;         // the rendered table's extent and texture
  PerceptionOptions perception;  // detector, filter and colour settings (objects are set from `objects`)
  double noise_sigma = 2.0;      // sensor noise of the rendered images, grey levels
  // The moving objects as the camera sees them, read from the simulator.
  std::function<std::vector<ScenePart>()> scene;
  // The simulator's pose of each tracked object (in `objects`' order), for the error report.
  std::function<std::vector<Eigen::Isometry3d>()> truth;
  // The task's observation from the estimate; `state` is the state-observed task's own observation, from
  // which only the robot's own sensors may be taken.
  std::function<Eigen::VectorXd(const TaskState& estimate, const Eigen::VectorXd& state)> observe;
  // The task's reward of an observation and the agent's action.
  std::function<double(const Eigen::VectorXd& observation, const Eigen::VectorXd& action)> reward;
};

// What the camera saw at one control step, against the simulator's truth.
struct PerceptionRecord {
  // CPU time of the thread (so a shared core does not inflate it), milliseconds.
  double render_ms = 0.0;              // synthetic image
  double perceive_ms = 0.0;            // tag detection, colour tracking if asked, state estimate, observation
  std::vector<double> position_error;  // per tracked object: |estimate - truth|, metres
  std::vector<double> yaw_error;       // per tracked object: |yaw difference|, radians
  std::vector<EstimateSource> source;  // per tracked object: tag, colour, held (a miss) or none
  Eigen::VectorXd state_observation;   // the state-observed task's observation at the same step
};

class CameraObserved : public Env {
 public:
  CameraObserved(std::string name, std::unique_ptr<Env> task, CameraTaskSpec spec);

  std::string name() const override { return name_; }
  int observation_dim() const override { return task_->observation_dim(); }
  int action_dim() const override { return task_->action_dim(); }
  int max_episode_steps() const override { return task_->max_episode_steps(); }
  double dt() const override { return task_->dt(); }
  cv::Mat render(int width = 480, int height = 360) const override { return task_->render(width, height); }
  // Success is judged on the simulator's truth, not on the camera's estimate.
  std::optional<bool> episode_success() const override { return task_->episode_success(); }
  std::optional<ObservationScale> observation_scale() const override { return task_->observation_scale(); }

  // The state-observed task underneath (its observation is the simulator's truth).
  const Env& task() const { return *task_; }
  const std::vector<TrackedObject>& objects() const { return spec_.objects; }
  // The latest control step's perception (set by reset() and every step()).
  const PerceptionRecord& last_perception() const { return record_; }
  const FrameResult& last_frame() const { return pipeline_.last(); }
  // The camera image of the latest control step.
  const cv::Mat& last_image() const { return image_; }

 protected:
  Eigen::VectorXd reset_impl(std::mt19937_64& rng) override;
  StepResult step_impl(const Eigen::VectorXd& action) override;
  std::vector<double> save_sim() const override;
  void restore_sim(const std::vector<double>& sim) override;
  void save_wrapped(EnvState& state) const override { state.wrapped = {task_->save_state()}; }
  void restore_wrapped(const EnvState& state) override;

 private:
  // Renders the simulator's current poses, perceives them and returns the camera observation.
  Eigen::VectorXd perceive(const Eigen::VectorXd& state_observation);

  std::string name_;
  std::unique_ptr<Env> task_;
  CameraTaskSpec spec_;
  TabletopScene scene_;
  SyntheticCamera renderer_;
  PerceptionPipeline pipeline_;
  uint64_t noise_seed_ = 0;
  cv::Mat image_;
  PerceptionRecord record_;
};

}  // namespace hlt::robot
