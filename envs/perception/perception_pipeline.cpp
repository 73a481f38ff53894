#include "envs/perception/perception_pipeline.h"

#include <algorithm>
#include <chrono>

#include <fmt/format.h>

#include "envs/perception/pose_math.h"

namespace hlt {
namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

std::optional<Eigen::Isometry3d> prior_from(const CameraModel& camera) {
  if (!camera.has_extrinsics()) return std::nullopt;
  return camera.world_from_camera();
}

void append_object(std::string& s, const ObjectEstimate& o) {
  const Eigen::Vector3d p = o.table_from_object.translation();
  s += fmt::format(",{:.6f},{:.6f},{:.6f},{:.6f},{},{},{},{},{:.3f}", p.x(), p.y(), p.z(),
                   yaw_of(o.table_from_object.linear()), o.valid ? 1 : 0, o.stale ? 1 : 0,
                   to_string(o.source), o.misses, o.age);
}

}  // namespace

PerceptionPipeline::PerceptionPipeline(CameraModel camera, TagConfig config, PerceptionOptions options)
    : camera_(camera),
      config_(config),
      options_(options),
      detector_(camera, config, options.detector),
      colour_(camera, options.colour),
      estimator_(config, options.estimator, prior_from(camera)) {}

const FrameResult& PerceptionPipeline::process(const cv::Mat& image, double time) {
  const auto t0 = std::chrono::steady_clock::now();
  FrameResult r;
  r.time = time;
  r.detections = detector_.detect(image);
  r.detect_ms = ms_since(t0);
  StateEstimator::PositionFallback fallback;
  if (options_.colour_fallback) {
    fallback = [&](const TrackedObject&,
                   const Eigen::Isometry3d& table_from_camera) -> std::optional<Eigen::Vector3d> {
      if (!r.colour) r.colour = colour_.detect(image);  // one colour: every object asking sees the same blob
      return colour_.locate(*r.colour, table_from_camera);
    };
  }
  r.state = estimator_.update(time, r.detections.tags, fallback);
  r.total_ms = ms_since(t0);
  last_ = std::move(r);
  return last_;
}

std::string PerceptionPipeline::states_csv_header(const std::vector<std::string>& objects) {
  std::string h = "frame,time,tags,unknown_tags,table_known,table_stale,colour_used";
  for (const std::string& o : objects)
    h += fmt::format(",{0}_x,{0}_y,{0}_z,{0}_yaw,{0}_valid,{0}_stale,{0}_source,{0}_misses,{0}_age", o);
  const auto has = [&](const char* n) {
    return std::find(objects.begin(), objects.end(), n) != objects.end();
  };
  if (has("block") && has("target") && has("end_effector"))
    h += ",ee_to_block_x,ee_to_block_y,ee_to_block_yaw,block_to_target_x,block_to_target_y,block_to_target_"
         "yaw";
  h += ",valid,detect_ms,total_ms";
  return h;
}

std::string PerceptionPipeline::states_csv_row(const FrameResult& r) {
  const TaskState& s = r.state;
  std::string row = fmt::format("{},{:.6f},{},{},{},{},{}", s.frame, r.time, r.detections.tags.size(),
                                r.detections.unknown_ids.size(), s.table_known ? 1 : 0, s.table_stale ? 1 : 0,
                                r.colour && r.colour->found ? 1 : 0);
  for (const ObjectEstimate& o : s.objects)
    append_object(row, o);
  const Eigen::VectorXd v = s.vector();
  for (int i = 0; i < v.size(); ++i)
    row += fmt::format(",{:.6f}", v(i));
  row += fmt::format(",{},{:.3f},{:.3f}", s.valid() ? 1 : 0, r.detect_ms, r.total_ms);
  return row;
}

std::string PerceptionPipeline::detections_csv_header() {
  return "frame,time,id,name,decision_margin,hamming,pose_error,reprojection_px,refined,x,y,z,qw,qx,qy,qz,"
         "c0x,c0y,c1x,c1y,c2x,c2y,c3x,c3y";
}

std::string PerceptionPipeline::detections_csv_rows(const FrameResult& r) {
  std::string out;
  for (const TagDetection& t : r.detections.tags) {
    const Eigen::Vector3d p = t.camera_from_tag.translation();
    const Eigen::Quaterniond q(t.camera_from_tag.linear());
    out += fmt::format(
        "{},{:.6f},{},{},{:.2f},{},{:.3e},{:.4f},{},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f}",
        r.state.frame, r.time, t.id, t.name, t.decision_margin, t.hamming, t.pose_error, t.reprojection_error,
        t.refined ? 1 : 0, p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z());
    for (const cv::Point2d& c : t.corners)
      out += fmt::format(",{:.3f},{:.3f}", c.x, c.y);
    out += "\n";
  }
  return out;
}

}  // namespace hlt
