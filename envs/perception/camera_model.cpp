#include "envs/perception/camera_model.h"

#include <cmath>

#include <opencv2/calib3d.hpp>

#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace {

bool valid_distortion_count(size_t n) {
  return n == 0 || n == 4 || n == 5 || n == 8 || n == 12 || n == 14;
}

// Reads a matrix field written either as an OpenCV `!!opencv-matrix` or as a ROS-style {rows, cols, data}
// map, and checks its shape. An absent field gives std::nullopt.
std::optional<cv::Mat> read_matrix(const cv::FileStorage& fs, const char* field, const std::string& source) {
  const cv::FileNode node = fs[field];
  if (node.empty() || node.isNone()) return std::nullopt;
  cv::Mat m;
  if (node.isMap()) {
    const cv::FileNode rows = node["rows"], cols = node["cols"], data = node["data"];
    check(rows.isInt() && cols.isInt(), "{}: field '{}' needs integer 'rows' and 'cols'", source, field);
    check(data.isSeq(), "{}: field '{}' needs a 'data' list", source, field);
    const int r = static_cast<int>(rows), c = static_cast<int>(cols);
    check(r >= 0 && c >= 0 && static_cast<size_t>(r) * c == data.size(),
          "{}: field '{}' says {}x{} but its data has {} numbers", source, field, r, c, data.size());
    m.create(r, c, CV_64F);
    int i = 0;
    for (cv::FileNodeIterator it = data.begin(); it != data.end(); ++it, ++i) {
      check((*it).isReal() || (*it).isInt(), "{}: field '{}' has a non-numeric entry at index {}", source,
            field, i);
      m.at<double>(i / std::max(c, 1), i % std::max(c, 1)) = static_cast<double>(*it);
    }
  } else {
    try {
      node >> m;
    } catch (const cv::Exception&) {
      m.release();
    }
    check(!m.empty() || node.isSeq(),
          "{}: field '{}' is not a matrix (expected !!opencv-matrix or {{rows, cols, data}})", source, field);
    if (m.empty() && node.isSeq()) {  // a plain list of numbers, e.g. distortion: [k1, k2, p1, p2, k3]
      std::vector<double> v;
      for (cv::FileNodeIterator it = node.begin(); it != node.end(); ++it) {
        check((*it).isReal() || (*it).isInt(), "{}: field '{}' has a non-numeric entry", source, field);
        v.push_back(static_cast<double>(*it));
      }
      m = cv::Mat(v, true).reshape(1, 1);
    }
    m.convertTo(m, CV_64F);
  }
  check(cv::checkRange(m), "{}: field '{}' contains a non-finite number", source, field);
  return m;
}

int read_positive_int(const cv::FileStorage& fs, const char* field, const std::string& source) {
  const cv::FileNode node = fs[field];
  check(!node.empty() && !node.isNone(), "{}: field '{}' is missing", source, field);
  check(node.isInt(), "{}: field '{}' must be an integer", source, field);
  const int v = static_cast<int>(node);
  check(v > 0 && v <= 100000, "{}: field '{}' must be in [1, 100000], got {}", source, field, v);
  return v;
}

}  // namespace

CameraModel::CameraModel() : CameraModel(640, 480, 600.0, 600.0, 319.5, 239.5) {}

CameraModel::CameraModel(int width, int height, double fx, double fy, double cx, double cy,
                         std::vector<double> distortion)
    : width_(width), height_(height), fx_(fx), fy_(fy), cx_(cx), cy_(cy), distortion_(std::move(distortion)) {
  validate("camera model");
}

void CameraModel::validate(const std::string& source) const {
  check(width_ > 0 && height_ > 0, "{}: image size must be positive, got {}x{}", source, width_, height_);
  check(std::isfinite(fx_) && std::isfinite(fy_) && fx_ > 0 && fy_ > 0,
        "{}: focal lengths fx, fy must be positive and finite, got {}, {}", source, fx_, fy_);
  check(std::isfinite(cx_) && std::isfinite(cy_), "{}: principal point must be finite", source);
  // Beyond these no lens exists, and libapriltag's pose solver aborts on such intrinsics instead of failing.
  const double size = std::max(width_, height_);
  check(fx_ >= 0.01 * size && fy_ >= 0.01 * size && fx_ <= 1000 * size && fy_ <= 1000 * size,
        "{}: focal lengths fx, fy = {}, {} px are outside [{}, {}] (0.01 to 1000 times the image size)",
        source, fx_, fy_, 0.01 * size, 1000 * size);
  check(cx_ >= -0.5 * width_ && cx_ <= 1.5 * width_ && cy_ >= -0.5 * height_ && cy_ <= 1.5 * height_,
        "{}: principal point ({}, {}) is far outside the {}x{} image", source, cx_, cy_, width_, height_);
  check(valid_distortion_count(distortion_.size()),
        "{}: distortion_coefficients must have 0, 4, 5, 8, 12 or 14 entries, got {}", source,
        distortion_.size());
  for (double d : distortion_)
    check(std::isfinite(d), "{}: distortion coefficients must be finite", source);
}

cv::Matx33d CameraModel::camera_matrix() const {
  return {fx_, 0, cx_, 0, fy_, cy_, 0, 0, 1};
}

bool CameraModel::has_distortion() const {
  for (double d : distortion_)
    if (d != 0.0) return true;
  return false;
}

const Eigen::Isometry3d& CameraModel::world_from_camera() const {
  check(world_from_camera_.has_value(), "camera model has no extrinsics (world_from_camera)");
  return *world_from_camera_;
}

void CameraModel::set_world_from_camera(const Eigen::Isometry3d& world_from_camera) {
  check(world_from_camera.matrix().allFinite(), "camera extrinsics must be finite");
  const Eigen::Matrix3d R = world_from_camera.linear();
  check((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-6 && R.determinant() > 0,
        "camera extrinsics: world_from_camera's rotation is not a proper rotation");
  world_from_camera_ = world_from_camera;
}

CameraModel CameraModel::load(const std::string& path) {
  return parse(read_file(path), path);
}

CameraModel CameraModel::parse(const std::string& yaml_text, const std::string& source) {
  // FileStorage insists on the %YAML directive that ROS's calibration files leave out.
  std::string text = yaml_text;
  if (text.rfind("%YAML", 0) != 0) text = "%YAML:1.0\n---\n" + text;
  cv::FileStorage fs;
  try {
    fs.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  } catch (const cv::Exception& e) {
    throw Error(fmt::format("{}: not a readable YAML calibration file: {}", source, e.err));
  }
  check(fs.isOpened(), "{}: not a readable YAML calibration file", source);

  const int width = read_positive_int(fs, "image_width", source);
  const int height = read_positive_int(fs, "image_height", source);

  const std::optional<cv::Mat> K = read_matrix(fs, "camera_matrix", source);
  check(K.has_value(), "{}: field 'camera_matrix' is missing", source);
  check(K->rows == 3 && K->cols == 3, "{}: field 'camera_matrix' must be 3x3, got {}x{}", source, K->rows,
        K->cols);
  const cv::Matx33d k(*K);
  check(k(1, 0) == 0 && k(2, 0) == 0 && k(2, 1) == 0 && k(2, 2) == 1,
        "{}: field 'camera_matrix' must have the form [fx 0 cx; 0 fy cy; 0 0 1]", source);
  check(std::abs(k(0, 1)) < 1e-9 * std::abs(k(0, 0)) + 1e-12,
        "{}: field 'camera_matrix' has a skew term ({}); skewed pixels are not supported", source, k(0, 1));

  const cv::FileNode model = fs["distortion_model"];
  if (!model.empty() && !model.isNone()) {
    check(model.isString(), "{}: field 'distortion_model' must be a string", source);
    const std::string name = static_cast<std::string>(model);
    check(name == "plumb_bob" || name == "rational_polynomial",
          "{}: field 'distortion_model' is '{}'; supported: plumb_bob, rational_polynomial (OpenCV's model)",
          source, name);
  }
  const std::optional<cv::Mat> D = read_matrix(fs, "distortion_coefficients", source);
  check(D.has_value(), "{}: field 'distortion_coefficients' is missing", source);
  check(D->empty() || D->rows == 1 || D->cols == 1,
        "{}: field 'distortion_coefficients' must be a row or column vector, got {}x{}", source, D->rows,
        D->cols);
  std::vector<double> distortion;
  if (!D->empty()) distortion.assign(D->begin<double>(), D->end<double>());
  check(valid_distortion_count(distortion.size()),
        "{}: field 'distortion_coefficients' must have 4, 5, 8, 12 or 14 entries, got {}", source,
        distortion.size());

  // The constructor's checks would name "camera model", not the file at fault.
  CameraModel camera = [&] {
    try {
      return CameraModel(width, height, k(0, 0), k(1, 1), k(0, 2), k(1, 2), distortion);
    } catch (const Error& e) {
      throw Error(fmt::format("{}: {}", source, e.what()));
    }
  }();

  if (const std::optional<cv::Mat> T = read_matrix(fs, "world_from_camera", source)) {
    check(T->rows == 4 && T->cols == 4, "{}: field 'world_from_camera' must be 4x4, got {}x{}", source,
          T->rows, T->cols);
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        m(r, c) = T->at<double>(r, c);
    check((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() < 1e-9,
          "{}: field 'world_from_camera' must end in the row [0 0 0 1]", source);
    Eigen::Isometry3d pose(m);
    try {
      camera.set_world_from_camera(pose);
    } catch (const Error& e) {
      throw Error(fmt::format("{}: field 'world_from_camera': {}", source, e.what()));
    }
  }
  return camera;
}

void CameraModel::save(const std::string& path, std::optional<double> rms) const {
  cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  fs << "image_width" << width_;
  fs << "image_height" << height_;
  fs << "camera_matrix" << cv::Mat(camera_matrix());
  fs << "distortion_model" << (distortion_.size() > 5 ? "rational_polynomial" : "plumb_bob");
  std::vector<double> d = distortion_;
  if (d.empty()) d.assign(5, 0.0);
  fs << "distortion_coefficients" << cv::Mat(d, true).reshape(1, 1);
  if (rms) fs << "avg_reprojection_error" << *rms;
  if (world_from_camera_) {
    cv::Mat T(4, 4, CV_64F);
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        T.at<double>(r, c) = world_from_camera_->matrix()(r, c);
    fs << "world_from_camera" << T;
  }
  write_file_atomic(path, fs.releaseAndGetString());
}

cv::Point2d CameraModel::project_ideal(const Eigen::Vector3d& p) const {
  return {fx_ * p.x() / p.z() + cx_, fy_ * p.y() / p.z() + cy_};
}

cv::Point2d CameraModel::project(const Eigen::Vector3d& p) const {
  check(p.allFinite() && p.z() > 0, "CameraModel::project: point ({}, {}, {}) is not in front of the camera",
        p.x(), p.y(), p.z());
  if (!has_distortion()) return project_ideal(p);
  const std::vector<cv::Point3d> in{{p.x(), p.y(), p.z()}};
  std::vector<cv::Point2d> out;
  cv::projectPoints(in, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera_matrix(), distortion_, out);
  return out[0];
}

std::vector<cv::Point2d> CameraModel::undistort_pixels(const std::vector<cv::Point2d>& pixels) const {
  if (!has_distortion() || pixels.empty()) return pixels;
  std::vector<cv::Point2d> out;
  // More iterations than OpenCV's default 5, which leaves visible error at the image corners.
  cv::undistortPoints(pixels, out, camera_matrix(), distortion_, cv::noArray(), camera_matrix(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
  return out;
}

std::vector<cv::Point2d> CameraModel::distort_pixels(const std::vector<cv::Point2d>& ideal) const {
  if (!has_distortion() || ideal.empty()) return ideal;
  std::vector<cv::Point3d> rays;
  for (const cv::Point2d& p : ideal)
    rays.emplace_back((p.x - cx_) / fx_, (p.y - cy_) / fy_, 1.0);
  std::vector<cv::Point2d> out;
  cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera_matrix(), distortion_, out);
  return out;
}

Eigen::Vector3d CameraModel::pixel_ray(const cv::Point2d& pixel) const {
  const cv::Point2d u = undistort_pixels({pixel})[0];
  return {(u.x - cx_) / fx_, (u.y - cy_) / fy_, 1.0};
}

}  // namespace hlt
