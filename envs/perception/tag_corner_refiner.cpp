#include "envs/perception/tag_corner_refiner.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>

#include "hlt/util/error.h"

namespace hlt {
namespace {

// Bilinear grey value at OpenCV pixel coordinates; NaN outside the image.
double bilinear(const cv::Mat& g, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= g.cols || y0 + 1 >= g.rows) return NAN;
  const double ax = x - x0, ay = y - y0;
  const uint8_t* r0 = g.ptr<uint8_t>(y0);
  const uint8_t* r1 = g.ptr<uint8_t>(y0 + 1);
  return (r0[x0] * (1 - ax) + r0[x0 + 1] * ax) * (1 - ay) + (r1[x0] * (1 - ax) + r1[x0 + 1] * ax) * ay;
}

struct Line {
  Eigen::Vector2d point, direction;
};

// Total least squares line through points; returns the RMS residual in `rms`.
Line fit_line(const std::vector<Eigen::Vector2d>& pts, double* rms) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : pts)
    mean += p;
  mean /= static_cast<double>(pts.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& p : pts)
    cov += (p - mean) * (p - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
  const Eigen::Vector2d dir = es.eigenvectors().col(1);
  if (rms) *rms = std::sqrt(std::max(0.0, es.eigenvalues()(0)) / static_cast<double>(pts.size()));
  return {mean, dir};
}

std::optional<Eigen::Vector2d> intersect(const Line& a, const Line& b) {
  Eigen::Matrix2d A;
  A << a.direction, -b.direction;
  if (std::abs(A.determinant()) < 1e-6) return std::nullopt;
  const Eigen::Vector2d st = A.colPivHouseholderQr().solve(b.point - a.point);
  return a.point + st(0) * a.direction;
}

}  // namespace

TagCornerRefiner::TagCornerRefiner(int width_at_border) : width_at_border_(width_at_border) {
  check(width_at_border >= 3, "TagCornerRefiner: width_at_border must be >= 3, got {}", width_at_border);
}

std::optional<RefinedCorners> TagCornerRefiner::refine(const cv::Mat& grey, const CameraModel& camera,
                                                       const std::array<cv::Point2d, 4>& corners) const {
  check(grey.type() == CV_8UC1, "TagCornerRefiner: expected an 8-bit grey image");
  Eigen::Vector2d p[4];
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (int k = 0; k < 4; ++k) {
    p[k] = Eigen::Vector2d(corners[k].x, corners[k].y);
    centroid += p[k] / 4.0;
  }
  Line lines[4];
  double sum_sq = 0;
  int n_sq = 0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d a = p[k], b = p[(k + 1) % 4];
    const double len = (b - a).norm();
    if (len < 6.0) return std::nullopt;
    const Eigen::Vector2d dir = (b - a) / len;
    Eigen::Vector2d normal(-dir.y(), dir.x());
    if (normal.dot(0.5 * (a + b) - centroid) < 0) normal = -normal;  // outwards: black inside, white outside
    // The black border and the white quiet zone are each one cell wide across the edge; stay inside both.
    // Across the edge means the tag's extent along the normal, which perspective can shorten a lot.
    const Eigen::Vector2d opposite = 0.5 * (p[(k + 2) % 4] + p[(k + 3) % 4]);
    const double cell = std::abs((0.5 * (a + b) - opposite).dot(normal)) / width_at_border_;
    const double w = std::clamp(std::min(0.8 * cell, cell - 1.5), 0.6, 3.0);
    const double margin = std::max(0.12 * len, w + 1.0);  // keep clear of the neighbouring edges
    const int n = std::max(5, static_cast<int>((len - 2 * margin) / 0.7));
    constexpr double kStep = 0.125;
    const int m = static_cast<int>(std::round(2 * w / kStep));
    std::vector<cv::Point2d> edge_points;
    for (int i = 0; i < n; ++i) {
      const double s = margin + (len - 2 * margin) * (n == 1 ? 0.5 : static_cast<double>(i) / (n - 1));
      const Eigen::Vector2d base = a + s * dir;
      double offset = 0.0;  // edge position along the normal, relative to base
      bool ok = true;
      for (int iter = 0; iter < 3 && ok; ++iter) {
        std::vector<double> prof(m);
        for (int j = 0; j < m; ++j) {
          const Eigen::Vector2d q = base + (offset - w + (j + 0.5) * kStep) * normal;
          prof[j] = bilinear(grey, q.x(), q.y());
          if (std::isnan(prof[j])) ok = false;
        }
        if (!ok) break;
        const int k4 = std::max(1, m / 6);
        double ib = 0, iw = 0;
        for (int j = 0; j < k4; ++j) {
          ib += prof[j] / k4;
          iw += prof[m - 1 - j] / k4;
        }
        if (iw - ib < 12.0) {  // no clear dark-to-light step here (occlusion, glare, another edge)
          ok = false;
          break;
        }
        // The dark "mass" of the profile equals the distance from the window start to the edge.
        double mass = 0;
        for (int j = 0; j < m; ++j)
          mass += (iw - prof[j]) / (iw - ib) * kStep;
        const double next = offset - w + mass;
        if (std::abs(next - offset) > w) {
          ok = false;
          break;
        }
        offset = next;
      }
      if (ok) {
        const Eigen::Vector2d e = base + offset * normal;
        edge_points.emplace_back(e.x(), e.y());
      }
    }
    if (edge_points.size() < 4 || edge_points.size() < static_cast<size_t>(n / 2)) return std::nullopt;
    // Straight lines exist only without distortion: fit in ideal pixels.
    const std::vector<cv::Point2d> ideal = camera.undistort_pixels(edge_points);
    std::vector<Eigen::Vector2d> pts;
    for (const cv::Point2d& q : ideal)
      pts.emplace_back(q.x, q.y);
    double rms = 0;
    Line line = fit_line(pts, &rms);
    // One pass of outlier rejection (a speck of dirt, a partly occluded stretch).
    std::vector<Eigen::Vector2d> kept;
    const Eigen::Vector2d nrm(-line.direction.y(), line.direction.x());
    const double gate = std::max(0.15, 3.0 * rms);
    for (const auto& q : pts)
      if (std::abs((q - line.point).dot(nrm)) <= gate) kept.push_back(q);
    if (kept.size() < 4) return std::nullopt;
    line = fit_line(kept, &rms);
    for (const auto& q : kept) {
      const double r = (q - line.point).dot(Eigen::Vector2d(-line.direction.y(), line.direction.x()));
      sum_sq += r * r;
      ++n_sq;
    }
    lines[k] = line;
  }
  std::vector<cv::Point2d> orig(corners.begin(), corners.end());
  const std::vector<cv::Point2d> orig_ideal = camera.undistort_pixels(orig);
  RefinedCorners out;
  std::vector<cv::Point2d> ideal_pts;
  for (int k = 0; k < 4; ++k) {
    const std::optional<Eigen::Vector2d> c = intersect(lines[(k + 3) % 4], lines[k]);
    if (!c) return std::nullopt;
    out.ideal[k] = cv::Point2d(c->x(), c->y());
    if (cv::norm(out.ideal[k] - orig_ideal[k]) > 1.5) return std::nullopt;  // refinement wandered off
    ideal_pts.push_back(out.ideal[k]);
  }
  const std::vector<cv::Point2d> distorted = camera.distort_pixels(ideal_pts);
  for (int k = 0; k < 4; ++k)
    out.distorted[k] = distorted[k];
  out.edge_rms = n_sq > 0 ? std::sqrt(sum_sq / n_sq) : 0.0;
  return out;
}

}  // namespace hlt
