#include "envs/perception/synthetic_camera.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "hlt/util/error.h"

namespace hlt {
namespace {

constexpr double kNear = 1e-3;  // metres; geometry closer than this to the camera centre is clipped

// Clips a convex polygon (camera frame) to z >= kNear.
std::vector<Eigen::Vector3d> clip_near(const std::array<Eigen::Vector3d, 4>& poly) {
  std::vector<Eigen::Vector3d> out;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector3d& a = poly[i];
    const Eigen::Vector3d& b = poly[(i + 1) % poly.size()];
    const bool ina = a.z() >= kNear, inb = b.z() >= kNear;
    if (ina) out.push_back(a);
    if (ina != inb) out.push_back(a + (b - a) * ((kNear - a.z()) / (b.z() - a.z())));
  }
  return out;
}

cv::Vec3f texel(const cv::Mat& tex, int x, int y) {
  if (tex.type() == CV_8UC1) {
    const float g = tex.at<uint8_t>(y, x);
    return {g, g, g};
  }
  const cv::Vec3b c = tex.at<cv::Vec3b>(y, x);
  return {static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2])};
}

// Area of the convex polygon `p` inside the square [x0, x0+1] x [y0, y0+1].
double area_in_cell(const std::array<Eigen::Vector2d, 4>& p, double x0, double y0) {
  std::vector<Eigen::Vector2d> poly(p.begin(), p.end()), next;
  auto clip = [&](int axis, double bound, bool keep_greater) {
    next.clear();
    for (size_t i = 0; i < poly.size(); ++i) {
      const Eigen::Vector2d& a = poly[i];
      const Eigen::Vector2d& b = poly[(i + 1) % poly.size()];
      const bool ina = keep_greater ? a(axis) >= bound : a(axis) <= bound;
      const bool inb = keep_greater ? b(axis) >= bound : b(axis) <= bound;
      if (ina) next.push_back(a);
      if (ina != inb) next.push_back(a + (b - a) * ((bound - a(axis)) / (b(axis) - a(axis))));
    }
    poly.swap(next);
  };
  clip(0, x0, true);
  clip(0, x0 + 1, false);
  clip(1, y0, true);
  clip(1, y0 + 1, false);
  double area = 0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[(i + 1) % poly.size()];
    area += a.x() * b.y() - a.y() * b.x();
  }
  return std::abs(area) / 2;
}

// Mean of a piecewise-constant texture over the parallelogram centre +- a/2 +- b/2 (texel units); the part
// outside the texture takes `outside`.
cv::Vec3f box_average(const cv::Mat& tex, const Eigen::Vector2d& c, const Eigen::Vector2d& a,
                      const Eigen::Vector2d& b, const cv::Vec3f& outside) {
  const std::array<Eigen::Vector2d, 4> p = {c - a / 2 - b / 2, c + a / 2 - b / 2, c + a / 2 + b / 2,
                                            c - a / 2 + b / 2};
  double x0 = p[0].x(), x1 = x0, y0 = p[0].y(), y1 = y0;
  for (const auto& q : p) {
    x0 = std::min(x0, q.x());
    x1 = std::max(x1, q.x());
    y0 = std::min(y0, q.y());
    y1 = std::max(y1, q.y());
  }
  const int ix0 = static_cast<int>(std::floor(x0)), ix1 = static_cast<int>(std::floor(x1));
  const int iy0 = static_cast<int>(std::floor(y0)), iy1 = static_cast<int>(std::floor(y1));
  const bool inside = ix0 >= 0 && iy0 >= 0 && ix1 < tex.cols && iy1 < tex.rows;
  if (ix0 == ix1 && iy0 == iy1) return inside ? texel(tex, ix0, iy0) : outside;
  const double total = std::abs(a.x() * b.y() - a.y() * b.x());
  if (total <= 0 || (ix1 - ix0 + 1) * (iy1 - iy0 + 1) > 256) {  // degenerate or hugely minified: point sample
    const int ix = static_cast<int>(std::floor(c.x())), iy = static_cast<int>(std::floor(c.y()));
    return ix >= 0 && iy >= 0 && ix < tex.cols && iy < tex.rows ? texel(tex, ix, iy) : outside;
  }
  cv::Vec3f acc(0, 0, 0);
  double covered = 0;
  for (int iy = std::max(iy0, 0); iy <= std::min(iy1, tex.rows - 1); ++iy)
    for (int ix = std::max(ix0, 0); ix <= std::min(ix1, tex.cols - 1); ++ix) {
      const double w = area_in_cell(p, ix, iy);
      if (w <= 0) continue;
      acc += texel(tex, ix, iy) * static_cast<float>(w);
      covered += w;
    }
  acc += outside * static_cast<float>(std::max(0.0, total - covered));
  return acc * static_cast<float>(1.0 / total);
}

// Bilinear texture value at texture coordinates (u, v) in [0, 1)^2.
cv::Vec3f bilinear_sample(const cv::Mat& tex, double u, double v) {
  const int w = tex.cols, h = tex.rows;
  const double fx = u * w - 0.5, fy = v * h - 0.5;
  const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
  const float ax = static_cast<float>(fx - x0), ay = static_cast<float>(fy - y0);
  auto at = [&](int x, int y) { return texel(tex, std::clamp(x, 0, w - 1), std::clamp(y, 0, h - 1)); };
  return (at(x0, y0) * (1 - ax) + at(x0 + 1, y0) * ax) * (1 - ay) +
         (at(x0, y0 + 1) * (1 - ax) + at(x0 + 1, y0 + 1) * ax) * ay;
}

cv::Mat effects_on_float(cv::Mat img, const ImageEffects& e) {
  check(std::isfinite(e.gain) && e.gain >= 0, "ImageEffects: gain must be finite and >= 0, got {}", e.gain);
  check(std::isfinite(e.offset), "ImageEffects: offset must be finite");
  check(std::isfinite(e.blur_sigma) && e.blur_sigma >= 0, "ImageEffects: blur_sigma must be >= 0, got {}",
        e.blur_sigma);
  check(std::isfinite(e.noise_sigma) && e.noise_sigma >= 0, "ImageEffects: noise_sigma must be >= 0, got {}",
        e.noise_sigma);
  if (e.gain != 1.0 || e.offset != 0.0) img.convertTo(img, CV_32F, e.gain, e.offset);
  if (e.blur_sigma > 0)
    cv::GaussianBlur(img, img, cv::Size(0, 0), e.blur_sigma, e.blur_sigma, cv::BORDER_REPLICATE);
  if (e.noise_sigma > 0) {
    cv::Mat noise(img.size(), img.type());
    cv::RNG rng(e.seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, e.noise_sigma);
    img += noise;
  }
  cv::Mat out;
  img.convertTo(out, CV_8U);  // rounds and saturates
  return out;
}

}  // namespace

SyntheticCamera::SyntheticCamera(CameraModel camera, SyntheticCameraOptions options)
    : camera_(std::move(camera)), options_(std::move(options)) {
  const int s = options_.supersample;
  check(s >= 1 && s <= 8, "SyntheticCamera: supersample must be in [1, 8], got {}", s);
  check(options_.ambient >= 0 && options_.diffuse >= 0, "SyntheticCamera: ambient and diffuse must be >= 0");
  check(options_.light_direction.norm() > 0, "SyntheticCamera: light_direction must be non-zero");
  W_ = camera_.width() * s;
  H_ = camera_.height() * s;
  // Supersampled pixel U belongs to output pixel floor(U / s). The s*s samples of one output pixel are
  // placed by "n-rooks" sampling: every sample has its own column and its own row of an s^2 x s^2 grid, so a
  // straight edge's coverage is resolved to 1/s^2 of a pixel rather than 1/s, and the pattern is shuffled per
  // pixel (fixed seed) so that the remaining quantisation averages out along an edge instead of biasing it.
  std::mt19937 rng(0x5eed);
  std::vector<int> px_order(static_cast<size_t>(s) * s), py_order(px_order.size());
  std::vector<cv::Point2d> pix(static_cast<size_t>(W_) * H_);
  const double cell = 1.0 / (s * s);
  for (int y = 0; y < camera_.height(); ++y) {
    for (int x = 0; x < camera_.width(); ++x) {
      std::iota(px_order.begin(), px_order.end(), 0);
      std::iota(py_order.begin(), py_order.end(), 0);
      std::shuffle(px_order.begin(), px_order.end(), rng);
      std::shuffle(py_order.begin(), py_order.end(), rng);
      for (int j = 0; j < s; ++j)
        for (int i = 0; i < s; ++i) {
          const int k = j * s + i;
          pix[static_cast<size_t>(y * s + j) * W_ + (x * s + i)] =
              cv::Point2d(x - 0.5 + (px_order[k] + 0.5) * cell, y - 0.5 + (py_order[k] + 0.5) * cell);
        }
    }
  }
  const std::vector<cv::Point2d> ideal = camera_.undistort_pixels(pix);
  const double fx = camera_.fx(), fy = camera_.fy(), cx = camera_.cx(), cy = camera_.cy();
  rays_.create(H_, W_, CV_32FC2);
  ray_x0_ = ray_y0_ = 1e300;
  ray_x1_ = ray_y1_ = -1e300;
  for (int V = 0; V < H_; ++V) {
    cv::Vec2f* row = rays_.ptr<cv::Vec2f>(V);
    for (int U = 0; U < W_; ++U) {
      const cv::Point2d& p = ideal[static_cast<size_t>(V) * W_ + U];
      const double rx = (p.x - cx) / fx, ry = (p.y - cy) / fy;
      row[U] = cv::Vec2f(static_cast<float>(rx), static_cast<float>(ry));
      ray_x0_ = std::min(ray_x0_, rx);
      ray_x1_ = std::max(ray_x1_, rx);
      ray_y0_ = std::min(ray_y0_, ry);
      ray_y1_ = std::max(ray_y1_, ry);
    }
  }
  // Per output pixel: the ray through its centre and how rays change across it, for box-filtering textures
  // over the pixel's exact footprint.
  const int w = camera_.width(), h = camera_.height();
  std::vector<cv::Point2d> probes;
  probes.reserve(static_cast<size_t>(w) * h * 5);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      probes.emplace_back(x, y);
      probes.emplace_back(x - 0.5, y);
      probes.emplace_back(x + 0.5, y);
      probes.emplace_back(x, y - 0.5);
      probes.emplace_back(x, y + 0.5);
    }
  const std::vector<cv::Point2d> ip = camera_.undistort_pixels(probes);
  pixel_rays_.create(h, w, CV_32FC2);
  pixel_jacobians_.create(h, w, CV_32FC4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const cv::Point2d* q = &ip[(static_cast<size_t>(y) * w + x) * 5];
      pixel_rays_.at<cv::Vec2f>(y, x) =
          cv::Vec2f(static_cast<float>((q[0].x - cx) / fx), static_cast<float>((q[0].y - cy) / fy));
      pixel_jacobians_.at<cv::Vec4f>(y, x) =
          cv::Vec4f(static_cast<float>((q[2].x - q[1].x) / fx), static_cast<float>((q[4].x - q[3].x) / fx),
                    static_cast<float>((q[2].y - q[1].y) / fy), static_cast<float>((q[4].y - q[3].y) / fy));
    }
}

cv::Mat SyntheticCamera::render(const std::vector<TexturedQuad>& quads, const ImageEffects& effects) const {
  check(camera_.has_extrinsics(), "SyntheticCamera::render: the camera model has no extrinsics; pass a pose");
  return render(quads, camera_.world_from_camera(), effects);
}

cv::Mat SyntheticCamera::render(const std::vector<TexturedQuad>& quads,
                                const Eigen::Isometry3d& world_from_camera,
                                const ImageEffects& effects) const {
  check(world_from_camera.matrix().allFinite(), "SyntheticCamera::render: camera pose is not finite");
  const Eigen::Isometry3d camera_from_world = world_from_camera.inverse();
  cv::Mat colour, depth;
  if (!static_quads_.empty() && world_from_camera.isApprox(static_pose_, 1e-12)) {
    static_colour_.copyTo(colour);
    static_depth_.copyTo(depth);
  } else {
    const cv::Vec3b bg = options_.background;
    colour.create(H_, W_, CV_32FC3);
    colour.setTo(cv::Scalar(bg[0], bg[1], bg[2]));
    depth.create(H_, W_, CV_32F);
    depth.setTo(cv::Scalar(std::numeric_limits<float>::infinity()));
    for (const TexturedQuad& q : static_quads_)
      draw(q, camera_from_world, colour, depth);
  }
  for (const TexturedQuad& q : quads)
    draw(q, camera_from_world, colour, depth);
  cv::Mat small;
  if (options_.supersample > 1) {
    cv::resize(colour, small, camera_.size(), 0, 0, cv::INTER_AREA);
  } else {
    small = colour;
  }
  return effects_on_float(small, effects);
}

void SyntheticCamera::set_static_quads(std::vector<TexturedQuad> quads) {
  static_quads_.clear();
  static_colour_.release();
  static_depth_.release();
  if (quads.empty()) return;
  check(camera_.has_extrinsics(), "SyntheticCamera::set_static_quads: the camera model has no extrinsics");
  static_pose_ = camera_.world_from_camera();
  const Eigen::Isometry3d camera_from_world = static_pose_.inverse();
  const cv::Vec3b bg = options_.background;
  static_colour_.create(H_, W_, CV_32FC3);
  static_colour_.setTo(cv::Scalar(bg[0], bg[1], bg[2]));
  static_depth_.create(H_, W_, CV_32F);
  static_depth_.setTo(cv::Scalar(std::numeric_limits<float>::infinity()));
  for (const TexturedQuad& q : quads)
    draw(q, camera_from_world, static_colour_, static_depth_);
  static_quads_ = std::move(quads);
}

cv::Mat SyntheticCamera::apply_effects(const cv::Mat& image_bgr, const ImageEffects& effects) {
  check(!image_bgr.empty(), "apply_effects: empty image");
  check(image_bgr.depth() == CV_8U, "apply_effects: expected an 8-bit image");
  cv::Mat f;
  image_bgr.convertTo(f, CV_32F);
  return effects_on_float(f, effects);
}

void SyntheticCamera::draw(const TexturedQuad& q, const Eigen::Isometry3d& camera_from_world, cv::Mat& colour,
                           cv::Mat& depth) const {
  std::array<Eigen::Vector3d, 4> c;
  for (int i = 0; i < 4; ++i) {
    check(q.corners[i].allFinite(), "TexturedQuad: corner {} is not finite", i);
    c[i] = camera_from_world * q.corners[i];
  }
  const Eigen::Vector3d e1 = c[1] - c[0], e2 = c[3] - c[0];
  const double scale = std::max(e1.norm(), e2.norm());
  if (scale < 1e-12) return;
  check((c[2] - (c[0] + e1 + e2)).norm() <= 1e-6 * scale,
        "TexturedQuad: corners do not form a parallelogram");
  const Eigen::Vector3d n = e1.cross(e2);
  if (n.norm() < 1e-12 * scale * scale) return;  // degenerate
  const double nc0 = n.dot(c[0]);
  if (nc0 <= 0) return;  // seen from behind (or edge-on)
  if (!q.texture.empty())
    check(q.texture.type() == CV_8UC1 || q.texture.type() == CV_8UC3,
          "TexturedQuad: texture must be CV_8UC1 or CV_8UC3");

  // Dual basis in the plane: s = (X - c0) . d1, t = (X - c0) . d2.
  const double g11 = e1.dot(e1), g12 = e1.dot(e2), g22 = e2.dot(e2), det = g11 * g22 - g12 * g12;
  const Eigen::Vector3d d1 = (g22 * e1 - g12 * e2) / det, d2 = (g11 * e2 - g12 * e1) / det;
  const double s0 = c[0].dot(d1), t0 = c[0].dot(d2);

  // Bounding box: the clipped polygon's extent in normalised image coordinates, limited to what the camera
  // sees, mapped to (possibly distorted) supersampled pixels.
  const std::vector<Eigen::Vector3d> poly = clip_near(c);
  if (poly.size() < 3) return;
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const Eigen::Vector3d& p : poly) {
    x0 = std::min(x0, p.x() / p.z());
    x1 = std::max(x1, p.x() / p.z());
    y0 = std::min(y0, p.y() / p.z());
    y1 = std::max(y1, p.y() / p.z());
  }
  const int ss = options_.supersample;
  const double pad = 2.0 / std::min(camera_.fx(), camera_.fy());
  double u0, u1, v0, v1;
  if (!camera_.has_distortion()) {
    u0 = camera_.fx() * x0 + camera_.cx();
    u1 = camera_.fx() * x1 + camera_.cx();
    v0 = camera_.fy() * y0 + camera_.cy();
    v1 = camera_.fy() * y1 + camera_.cy();
  } else {
    // Limit to the normalised extent the image covers, so the distortion polynomial is only evaluated where
    // it is a valid bijection, then map the rectangle's outline (which bounds its image) through the lens.
    x0 = std::max(x0 - pad, ray_x0_ - pad);
    x1 = std::min(x1 + pad, ray_x1_ + pad);
    y0 = std::max(y0 - pad, ray_y0_ - pad);
    y1 = std::min(y1 + pad, ray_y1_ + pad);
    if (x0 >= x1 || y0 >= y1) return;
    std::vector<cv::Point3d> outline;
    const int k = 32;
    for (int i = 0; i <= k; ++i) {
      const double a = static_cast<double>(i) / k;
      outline.emplace_back(x0 + a * (x1 - x0), y0, 1.0);
      outline.emplace_back(x0 + a * (x1 - x0), y1, 1.0);
      outline.emplace_back(x0, y0 + a * (y1 - y0), 1.0);
      outline.emplace_back(x1, y0 + a * (y1 - y0), 1.0);
    }
    std::vector<cv::Point2d> px;
    cv::projectPoints(outline, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera_.camera_matrix(),
                      camera_.distortion(), px);
    u0 = v0 = 1e300;
    u1 = v1 = -1e300;
    for (const cv::Point2d& p : px) {
      u0 = std::min(u0, p.x);
      u1 = std::max(u1, p.x);
      v0 = std::min(v0, p.y);
      v1 = std::max(v1, p.y);
    }
  }
  auto to_hi = [&](double u) { return ss * u + (ss - 1) / 2.0; };
  const double lo = -1e6, hi = 1e6;  // keeps the int conversion defined for far-off boxes
  const int U0 = std::max(0, static_cast<int>(std::floor(std::clamp(to_hi(u0), lo, hi))) - 2 * ss);
  const int U1 = std::min(W_ - 1, static_cast<int>(std::ceil(std::clamp(to_hi(u1), lo, hi))) + 2 * ss);
  const int V0 = std::max(0, static_cast<int>(std::floor(std::clamp(to_hi(v0), lo, hi))) - 2 * ss);
  const int V1 = std::min(H_ - 1, static_cast<int>(std::ceil(std::clamp(to_hi(v1), lo, hi))) + 2 * ss);
  if (U0 > U1 || V0 > V1) return;

  float shade = 1.0f;
  if (q.lit) {
    const Eigen::Vector3d n_out = -(camera_from_world.linear().transpose() * n).normalized();  // world frame
    shade = static_cast<float>(options_.ambient +
                               options_.diffuse *
                                   std::max(0.0, n_out.dot(options_.light_direction.normalized())));
  }
  const cv::Vec3f base = cv::Vec3f(q.colour[0], q.colour[1], q.colour[2]) * shade;
  const bool textured = !q.texture.empty();

  const int x0p = U0 / ss, x1p = U1 / ss, y0p = V0 / ss, y1p = V1 / ss;
  for (int y = y0p; y <= y1p; ++y) {
    for (int x = x0p; x <= x1p; ++x) {
      // A texture's contribution is computed once per pixel, over the pixel's footprint; the samples only
      // decide which patch covers which part of the pixel.
      bool have_pixel_colour = false;
      cv::Vec3f pixel_colour;
      for (int j = 0; j < ss; ++j) {
        const int V = y * ss + j;
        const cv::Vec2f* ray = rays_.ptr<cv::Vec2f>(V);
        float* zrow = depth.ptr<float>(V);
        cv::Vec3f* crow = colour.ptr<cv::Vec3f>(V);
        for (int i = 0; i < ss; ++i) {
          const int U = x * ss + i;
          const double rx = ray[U][0], ry = ray[U][1];
          const double nd = n.x() * rx + n.y() * ry + n.z();
          if (nd <= 0) continue;
          const double z = nc0 / nd;
          if (z < kNear || z >= zrow[U]) continue;
          const double s = z * (d1.x() * rx + d1.y() * ry + d1.z()) - s0;
          const double t = z * (d2.x() * rx + d2.y() * ry + d2.z()) - t0;
          if (s < 0 || s > 1 || t < 0 || t > 1) continue;
          zrow[U] = static_cast<float>(z);
          if (!textured) {
            crow[U] = base;
            continue;
          }
          if (!have_pixel_colour) {
            pixel_colour = footprint_colour(q, n, nc0, d1, d2, s0, t0, x, y) * shade;
            have_pixel_colour = true;
          }
          crow[U] = pixel_colour;
        }
      }
    }
  }
}

cv::Vec3f SyntheticCamera::footprint_colour(const TexturedQuad& q, const Eigen::Vector3d& n, double nc0,
                                            const Eigen::Vector3d& d1, const Eigen::Vector3d& d2, double s0,
                                            double t0, int x, int y) const {
  const cv::Vec2f rc = pixel_rays_.at<cv::Vec2f>(y, x);
  const cv::Vec4f jr = pixel_jacobians_.at<cv::Vec4f>(y, x);
  const Eigen::Vector3d r(rc[0], rc[1], 1.0);
  const double nd = n.dot(r);
  const cv::Vec3f outside(q.colour[0], q.colour[1], q.colour[2]);
  if (nd <= 1e-12) return outside;
  const double z = nc0 / nd;
  const double sd = d1.dot(r), td = d2.dot(r);
  const double s = z * sd - s0, t = z * td - t0;
  // d(s,t)/d(rx,ry) from s = z (d1 . r) - s0 with z = nc0 / (n . r); then chained with d(rx,ry)/d(pixel).
  const double ds_rx = z * (d1.x() - n.x() * sd / nd), ds_ry = z * (d1.y() - n.y() * sd / nd);
  const double dt_rx = z * (d2.x() - n.x() * td / nd), dt_ry = z * (d2.y() - n.y() * td / nd);
  const double ds_du = ds_rx * jr[0] + ds_ry * jr[2], ds_dv = ds_rx * jr[1] + ds_ry * jr[3];
  const double dt_du = dt_rx * jr[0] + dt_ry * jr[2], dt_dv = dt_rx * jr[1] + dt_ry * jr[3];
  const cv::Rect2d& area = q.texture_area;
  const double kx = q.texture.cols / area.width, ky = q.texture.rows / area.height;
  const Eigen::Vector2d centre((s - area.x) * kx, (t - area.y) * ky);
  if (q.smooth_texture) {
    const double u = centre.x() / q.texture.cols, v = centre.y() / q.texture.rows;
    return u >= 0 && u < 1 && v >= 0 && v < 1 ? bilinear_sample(q.texture, u, v) : outside;
  }
  // Printed patterns: the exact mean of the texture over the pixel's footprint, so their edges are placed
  // as precisely as a real sensor integrates them.
  const Eigen::Vector2d a(ds_du * kx, dt_du * ky), b(ds_dv * kx, dt_dv * ky);
  return box_average(q.texture, centre, a, b, outside);
}

}  // namespace hlt
