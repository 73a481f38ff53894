#include "envs/perception/tag_detector.h"

#include <apriltag/apriltag.h>
#include <apriltag/apriltag_pose.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>

#include "envs/perception/image_checks.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

// libapriltag reports positions with the centre of the top-left pixel at (0.5, 0.5); OpenCV and the camera
// model put it at (0, 0).
constexpr double kApriltagPixelOffset = 0.5;

// A 3x3 matd_t that libapriltag can read. matd_create is not exported by Debian's library, so the same
// single-allocation layout (header followed by the data) is built here.
struct Matd3x3 {
  matd_t* m;
  Matd3x3() : m(static_cast<matd_t*>(std::malloc(sizeof(matd_t) + 9 * sizeof(double)))) {
    check(m != nullptr, "out of memory");
    m->nrows = 3;
    m->ncols = 3;
  }
  ~Matd3x3() { std::free(m); }
  Matd3x3(const Matd3x3&) = delete;
  Matd3x3& operator=(const Matd3x3&) = delete;
};

// The homography mapping libapriltag's ideal tag corners (-1,1), (1,1), (1,-1), (-1,-1) to `p` (DLT with h33
// = 1).
cv::Matx33d tag_homography(const std::array<cv::Point2d, 4>& p) {
  const double tx[4] = {-1, 1, 1, -1}, ty[4] = {1, 1, -1, -1};
  cv::Matx<double, 8, 8> A;
  cv::Vec<double, 8> b;
  for (int i = 0; i < 4; ++i) {
    const double x = tx[i], y = ty[i], u = p[i].x, v = p[i].y;
    const double r0[8] = {x, y, 1, 0, 0, 0, -u * x, -u * y};
    const double r1[8] = {0, 0, 0, x, y, 1, -v * x, -v * y};
    for (int j = 0; j < 8; ++j) {
      A(2 * i, j) = r0[j];
      A(2 * i + 1, j) = r1[j];
    }
    b(2 * i) = u;
    b(2 * i + 1) = v;
  }
  cv::Vec<double, 8> h;
  cv::solve(A, b, h, cv::DECOMP_LU);
  return {h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), 1.0};
}

struct DetectionsGuard {
  zarray_t* d;
  ~DetectionsGuard() {
    if (d) apriltag_detections_destroy(d);
  }
};

}  // namespace

TagDetector::TagDetector(CameraModel camera, TagConfig config, TagDetectorOptions options)
    : camera_(std::move(camera)), config_(std::move(config)), options_(options) {
  check(options_.quad_decimate >= 1.0 && options_.quad_decimate <= 8.0,
        "TagDetector: quad_decimate must be in [1, 8], got {}", options_.quad_decimate);
  check(options_.quad_sigma >= 0.0 && options_.quad_sigma <= 10.0,
        "TagDetector: quad_sigma must be in [0, 10]");
  check(options_.threads >= 1 && options_.threads <= 64, "TagDetector: threads must be in [1, 64]");
  check(options_.max_hamming >= 0 && options_.max_hamming <= 2,
        "TagDetector: max_hamming must be 0, 1 or 2, got {}", options_.max_hamming);
  check(options_.min_decision_margin >= 0, "TagDetector: min_decision_margin must be >= 0");
  family_ = std::make_unique<TagFamily>(config_.family());
  refiner_ = std::make_unique<TagCornerRefiner>(family_->width_at_border());
  detector_ = apriltag_detector_create();
  apriltag_detector_add_family_bits(detector_, family_->raw(), options_.max_hamming);
  detector_->quad_decimate = static_cast<float>(options_.quad_decimate);
  detector_->quad_sigma = static_cast<float>(options_.quad_sigma);
  detector_->refine_edges = options_.refine_edges;
  detector_->nthreads = options_.threads;
}

TagDetector::~TagDetector() {
  if (detector_) apriltag_detector_destroy(detector_);
}

TagDetectionResult TagDetector::detect(const cv::Mat& image) {
  grey_ = to_grey(image, "TagDetector::detect");
  require_size(grey_, camera_.size(), "TagDetector::detect");
  if (!grey_.isContinuous()) grey_ = grey_.clone();
  image_u8_t im{grey_.cols, grey_.rows, static_cast<int32_t>(grey_.step[0]), grey_.data};
  DetectionsGuard dets{apriltag_detector_detect(detector_, &im)};
  check(dets.d != nullptr, "TagDetector::detect: libapriltag failed (out of memory?)");

  std::map<int, TagDetection> best;
  TagDetectionResult result;
  for (int i = 0; i < zarray_size(dets.d); ++i) {
    apriltag_detection_t* det = nullptr;
    zarray_get(dets.d, i, &det);
    if (det->hamming > options_.max_hamming || det->decision_margin < options_.min_decision_margin) continue;
    const TagSpec* spec = config_.find(det->id);
    if (!spec) {
      if (std::find(result.unknown_ids.begin(), result.unknown_ids.end(), det->id) ==
          result.unknown_ids.end())
        result.unknown_ids.push_back(det->id);
      continue;
    }
    TagDetection t;
    t.id = det->id;
    t.name = spec->name;
    t.size = spec->size;
    t.decision_margin = det->decision_margin;
    t.hamming = det->hamming;
    std::array<cv::Point2d, 4> measured;
    for (int k = 0; k < 4; ++k)
      measured[k] = {det->p[k][0] - kApriltagPixelOffset, det->p[k][1] - kApriltagPixelOffset};
    t.centre = {det->c[0] - kApriltagPixelOffset, det->c[1] - kApriltagPixelOffset};
    // estimate_tag_pose assumes an ideal pinhole camera: it gets undistorted corners and their homography.
    std::array<cv::Point2d, 4> ip;
    std::optional<RefinedCorners> refined;
    if (options_.refine_corners) refined = refiner_->refine(grey_, camera_, measured);
    if (refined) {
      t.refined = true;
      measured = refined->distorted;
      ip = refined->ideal;
    } else {
      const std::vector<cv::Point2d> ideal = camera_.undistort_pixels({measured.begin(), measured.end()});
      for (int k = 0; k < 4; ++k)
        ip[k] = ideal[k];
    }
    t.corners = measured;
    const cv::Matx33d H = tag_homography(ip);
    Matd3x3 Hm;
    for (int k = 0; k < 9; ++k)
      Hm.m->data[k] = H.val[k];
    apriltag_detection_t undistorted = *det;
    undistorted.H = Hm.m;
    for (int k = 0; k < 4; ++k) {
      undistorted.p[k][0] = ip[k].x;
      undistorted.p[k][1] = ip[k].y;
    }
    undistorted.c[0] = H(0, 2);
    undistorted.c[1] = H(1, 2);
    apriltag_detection_info_t info{&undistorted, spec->size,   camera_.fx(),
                                   camera_.fy(), camera_.cx(), camera_.cy()};
    apriltag_pose_t pose{nullptr, nullptr};
    t.pose_error = estimate_tag_pose(&info, &pose);
    if (!pose.R || !pose.t) {
      std::free(pose.R);
      std::free(pose.t);
      continue;
    }
    Eigen::Matrix3d R;
    Eigen::Vector3d tr;
    for (int r = 0; r < 3; ++r) {
      tr(r) = pose.t->data[r];
      for (int c = 0; c < 3; ++c)
        R(r, c) = pose.R->data[r * 3 + c];
    }
    std::free(pose.R);  // matd_destroy is not exported; a matd_t is a single allocation
    std::free(pose.t);
    if (!R.allFinite() || !tr.allFinite() || !std::isfinite(t.pose_error) || tr.z() <= 0) continue;
    // libapriltag's tag frame has y down and z into the tag; ours has y up and z out of it.
    t.camera_from_tag.linear() = R * Eigen::Vector3d(1, -1, -1).asDiagonal();
    t.camera_from_tag.translation() = tr;

    const double h = spec->size / 2;
    const Eigen::Vector3d obj[4] = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}};
    double sq = 0;
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3d pc = t.camera_from_tag * obj[k];
      if (pc.z() <= 0) {
        sq = INFINITY;
        break;
      }
      const cv::Point2d d = camera_.project(pc) - measured[k];
      sq += d.dot(d);
    }
    if (!std::isfinite(sq)) continue;
    t.reprojection_error = std::sqrt(sq / 4);

    auto it = best.find(t.id);
    if (it == best.end()) {
      best.emplace(t.id, t);
    } else {
      ++result.duplicates;
      if (t.decision_margin > it->second.decision_margin) it->second = t;
    }
  }
  for (auto& [id, t] : best)
    result.tags.push_back(std::move(t));
  std::sort(result.unknown_ids.begin(), result.unknown_ids.end());
  return result;
}

}  // namespace hlt
