#include "envs/perception/tabletop_scene.h"

#include <cmath>

#include <opencv2/imgproc.hpp>

#include "envs/perception/pose_math.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

// Printed paper is neither perfectly black nor white; keeping off 0 and 255 also leaves room for noise.
constexpr uint8_t kInk = 25, kPaper = 235;
// Tags float this far above their surface so depth resolves decal over face without a visible offset.
constexpr double kDecalLift = 5e-5;

cv::Mat wood_texture(uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat coarse(12, 24, CV_32F), fine(256, 512, CV_32F);
  rng.fill(coarse, cv::RNG::NORMAL, 0.0, 1.0);
  cv::Mat warp;
  cv::resize(coarse, warp, cv::Size(512, 256), 0, 0, cv::INTER_CUBIC);
  rng.fill(fine, cv::RNG::NORMAL, 0.0, 1.0);
  cv::GaussianBlur(fine, fine, cv::Size(0, 0), 0.8);
  cv::Mat out(256, 512, CV_8UC3);
  const cv::Vec3f base(95, 145, 190);  // BGR light oak
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      const float grain =
          std::sin(2.0f * static_cast<float>(M_PI) * (y / 9.0f + 0.25f * warp.at<float>(y, x)));
      const float f = 0.9f + 0.06f * grain + 0.025f * fine.at<float>(y, x);
      const cv::Vec3f c = base * f;
      out.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uint8_t>(c[0]), cv::saturate_cast<uint8_t>(c[1]),
                                          cv::saturate_cast<uint8_t>(c[2]));
    }
  return out;
}

}  // namespace

TabletopScene::TabletopScene(const TagConfig& tags, TabletopLayout layout)
    : tags_(tags), layout_(std::move(layout)), family_(std::make_shared<TagFamily>(tags.family())) {
  check(layout_.table_x1 > layout_.table_x0 && layout_.table_y1 > layout_.table_y0,
        "TabletopLayout: empty table");
  check((layout_.block_size.array() > 0).all() && (layout_.target_size.array() > 0).all() &&
            (layout_.end_effector_size.array() > 0).all(),
        "TabletopLayout: object sizes must be positive");
  table_texture_ = wood_texture(layout_.texture_seed);
}

TabletopPoses TabletopScene::example_poses() {
  TabletopPoses p;
  p.block = pose_from_xyz_rpy(0.20, 0.05, 0.025, 0, 0, 0.3);
  p.target = pose_from_xyz_rpy(0.36, 0.22, 0.0015, 0, 0, -0.2);
  p.end_effector = pose_from_xyz_rpy(0.06, 0.02, 0.01, 0, 0, 0.1);
  return p;
}

Eigen::Isometry3d TabletopScene::default_camera_pose() {
  return look_at(Eigen::Vector3d(0.2, -0.42, 0.58), Eigen::Vector3d(0.18, 0.08, 0.0));
}

TexturedQuad TabletopScene::tag_quad(const TagFamily& family, int id, double size,
                                     const Eigen::Isometry3d& world_from_tag) {
  check(size > 0 && std::isfinite(size), "tag_quad: size must be positive, got {}", size);
  cv::Mat image = family.image(id);
  image.setTo(kPaper, image == 255);
  image.setTo(kInk, image == 0);
  const double h = 0.5 * size * family.total_width() / family.width_at_border();
  TexturedQuad q;
  q.corners = {world_from_tag * Eigen::Vector3d(-h, h, 0), world_from_tag * Eigen::Vector3d(h, h, 0),
               world_from_tag * Eigen::Vector3d(h, -h, 0), world_from_tag * Eigen::Vector3d(-h, -h, 0)};
  q.texture = image;
  q.colour = cv::Vec3b(kPaper, kPaper, kPaper);
  return q;
}

std::vector<Eigen::Isometry3d> TabletopScene::checkerboard_calibration_poses(double scale) {
  std::vector<Eigen::Isometry3d> poses;
  int i = 0;
  for (double tilt_x : {-30.0, 0.0, 30.0}) {
    for (double tilt_y : {-25.0, 25.0}) {
      for (double shift : {-0.06, 0.06}) {
        poses.push_back(
            Eigen::Translation3d(shift * scale, 0.5 * shift * scale, (0.45 + 0.05 * (i % 3)) * scale) *
            Eigen::AngleAxisd(tilt_x * M_PI / 180, Eigen::Vector3d::UnitX()) *
            Eigen::AngleAxisd(tilt_y * M_PI / 180, Eigen::Vector3d::UnitY()) *
            Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d::UnitZ()));
        ++i;
      }
    }
  }
  return poses;
}

TexturedQuad TabletopScene::checkerboard_quad(cv::Size inner, double square,
                                              const Eigen::Isometry3d& world_from_board) {
  check(inner.width >= 2 && inner.height >= 2 && square > 0,
        "checkerboard_quad: need >= 2x2 corners and square > 0");
  const int sq_x = inner.width + 1, sq_y = inner.height + 1, px = 4;  // texels per square
  cv::Mat tex((sq_y + 2) * px, (sq_x + 2) * px, CV_8UC1, cv::Scalar(kPaper));
  for (int r = 0; r < sq_y; ++r)
    for (int c = 0; c < sq_x; ++c)
      if ((r + c) % 2 == 0) tex(cv::Rect((c + 1) * px, (r + 1) * px, px, px)).setTo(kInk);
  const double w = (sq_x + 2) * square / 2, h = (sq_y + 2) * square / 2;
  TexturedQuad q;
  q.corners = {world_from_board * Eigen::Vector3d(-w, -h, 0), world_from_board * Eigen::Vector3d(w, -h, 0),
               world_from_board * Eigen::Vector3d(w, h, 0), world_from_board * Eigen::Vector3d(-w, h, 0)};
  q.texture = tex;
  q.colour = cv::Vec3b(kPaper, kPaper, kPaper);
  q.lit = false;
  return q;
}

std::vector<TexturedQuad> TabletopScene::box(const Eigen::Isometry3d& world_from_box,
                                             const Eigen::Vector3d& size, cv::Vec3b colour) {
  // For each face: outward normal N and texture "right" R; "down" is R x N so the texture reads unmirrored
  // from outside.
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(),
                        Z = Eigen::Vector3d::UnitZ();
  const std::pair<Eigen::Vector3d, Eigen::Vector3d> faces[6] = {{Z, X},   {-Z, X}, {X, Y},
                                                                {-X, -Y}, {Y, -X}, {-Y, X}};
  const Eigen::Vector3d half = 0.5 * size;
  std::vector<TexturedQuad> out;
  for (const auto& [N, R] : faces) {
    const Eigen::Vector3d D = R.cross(N);
    const Eigen::Vector3d c = N.cwiseProduct(half);
    const Eigen::Vector3d r = R.cwiseProduct(half), d = D.cwiseProduct(half);
    TexturedQuad q;
    q.corners = {world_from_box * (c - r - d), world_from_box * (c + r - d), world_from_box * (c + r + d),
                 world_from_box * (c - r + d)};
    q.colour = colour;
    out.push_back(q);
  }
  return out;
}

void TabletopScene::add_tag(const std::string& name, const Eigen::Isometry3d& table_from_object,
                            std::vector<TexturedQuad>& out) const {
  if (!tags_.has_name(name)) return;
  const TagSpec& spec = tags_.by_name(name);
  Eigen::Isometry3d table_from_tag = table_from_object * spec.tag_from_object.inverse();
  table_from_tag.translation() += table_from_tag.linear().col(2) * kDecalLift;
  out.push_back(tag_quad(*family_, spec.id, spec.size, table_from_tag));
}

std::vector<TexturedQuad> TabletopScene::quads(const TabletopPoses& poses) const {
  std::vector<TexturedQuad> out = static_quads();
  for (TexturedQuad& q : object_quads(poses))
    out.push_back(std::move(q));
  return out;
}

std::vector<TexturedQuad> TabletopScene::static_quads() const {
  const TabletopLayout& L = layout_;
  std::vector<TexturedQuad> out;
  TexturedQuad table;
  table.corners = {Eigen::Vector3d(L.table_x0, L.table_y1, 0), Eigen::Vector3d(L.table_x1, L.table_y1, 0),
                   Eigen::Vector3d(L.table_x1, L.table_y0, 0), Eigen::Vector3d(L.table_x0, L.table_y0, 0)};
  table.texture = table_texture_;
  table.smooth_texture = true;
  out.push_back(table);
  if (L.show_reference) {
    if (const TagSpec* ref = tags_.reference()) {
      Eigen::Isometry3d table_from_tag = *ref->table_from_tag;
      table_from_tag.translation() += table_from_tag.linear().col(2) * kDecalLift;
      out.push_back(tag_quad(*family_, ref->id, ref->size, table_from_tag));
    }
  }
  return out;
}

std::vector<TexturedQuad> TabletopScene::object_quads(const TabletopPoses& poses) const {
  check(is_finite(poses.block) && is_finite(poses.target) && is_finite(poses.end_effector),
        "TabletopScene: object poses must be finite");
  const TabletopLayout& L = layout_;
  std::vector<ScenePart> parts;
  if (L.show_target)
    parts.push_back(
        {poses.target, {{Eigen::Isometry3d::Identity(), L.target_size, L.target_colour}}, {"target"}});
  if (L.show_block)
    parts.push_back(
        {poses.block, {{Eigen::Isometry3d::Identity(), L.block_size, L.block_colour}}, {"block"}});
  if (L.show_end_effector) {
    const Eigen::Isometry3d centre(Eigen::Translation3d(0, 0, 0.5 * L.end_effector_size.z()));
    parts.push_back(
        {poses.end_effector, {{centre, L.end_effector_size, L.end_effector_colour}}, {"end_effector"}});
  }
  return part_quads(parts);
}

std::vector<TexturedQuad> TabletopScene::part_quads(const std::vector<ScenePart>& parts) const {
  std::vector<TexturedQuad> out;
  for (const ScenePart& part : parts) {
    check(is_finite(part.table_from_object), "TabletopScene: object poses must be finite");
    for (const SceneBox& b : part.boxes) {
      check((b.size.array() > 0).all(), "TabletopScene: box sizes must be positive");
      for (TexturedQuad& q : box(part.table_from_object * b.object_from_box, b.size, b.colour))
        out.push_back(std::move(q));
    }
    for (const std::string& tag : part.tags)
      add_tag(tag, part.table_from_object, out);
  }
  return out;
}

}  // namespace hlt
