// hlt::TabletopScene: the Sawyer pushing set-up (or any task's objects, as ScenePart boxes with tags) as
// flat patches for SyntheticCamera. A textured table top,
// the reference tag lying on it, a coloured block with its tag on the top face, a flat target plate with
// its tag, and the end-effector (a box whose tip is its origin) with its tag on top. Tag ids, sizes and where
// each tag sits on its object come from the TagConfig, so rendered scenes and the estimator agree by
// construction.
//
// Table frame: z up, the table top is z = 0. Object frames: the block's origin is its centre, the target's
// is the centre of the plate, the end-effector's is the centre of its tip (bottom face); all z up.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "envs/perception/synthetic_camera.h"
#include "envs/perception/tag_config.h"
#include "envs/perception/tag_family.h"

namespace hlt {

struct TabletopPoses {  // table frame
  Eigen::Isometry3d block = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d end_effector = Eigen::Isometry3d::Identity();
};

// A box-shaped piece of a moving object: its centre and axes in the object's frame, edge lengths, colour.
struct SceneBox {
  Eigen::Isometry3d object_from_box = Eigen::Isometry3d::Identity();
  Eigen::Vector3d size = Eigen::Vector3d::Constant(0.05);
  cv::Vec3b colour{128, 128, 128};
};

// A moving object of any task's scene: its pose (table frame), the boxes it is made of, and the tag-config
// names of the tags stuck on it (each drawn where the config's object_offset puts it).
struct ScenePart {
  Eigen::Isometry3d table_from_object = Eigen::Isometry3d::Identity();
  std::vector<SceneBox> boxes;
  std::vector<std::string> tags;
};

struct TabletopLayout {
  double table_x0 = -0.35, table_x1 = 0.85, table_y0 = -0.45, table_y1 = 0.60;  // table top extent, metres
  Eigen::Vector3d block_size{0.05, 0.05, 0.05};
  cv::Vec3b block_colour{200, 90, 30};  // BGR: a saturated blue, far in hue from the wooden table
  Eigen::Vector3d target_size{0.07, 0.07, 0.003};
  cv::Vec3b target_colour{225, 225, 225};
  Eigen::Vector3d end_effector_size{0.045, 0.045, 0.10};
  cv::Vec3b end_effector_colour{95, 95, 100};
  uint64_t texture_seed = 7;  // the table's wood grain
  bool show_block = true, show_target = true, show_end_effector = true, show_reference = true;
};

class TabletopScene {
 public:
  explicit TabletopScene(const TagConfig& tags, TabletopLayout layout = {});

  const TabletopLayout& layout() const { return layout_; }
  const TagConfig& tags() const { return tags_; }

  // Everything: static_quads() followed by object_quads(poses).
  std::vector<TexturedQuad> quads(const TabletopPoses& poses) const;
  // The parts that never move (table top, reference tag), for SyntheticCamera::set_static_quads.
  std::vector<TexturedQuad> static_quads() const;
  // Block, target and end-effector with their tags.
  std::vector<TexturedQuad> object_quads(const TabletopPoses& poses) const;
  // Any task's moving objects (the layout's object sizes and show_* flags do not apply).
  std::vector<TexturedQuad> part_quads(const std::vector<ScenePart>& parts) const;

  // Poses of a typical episode start: block, target and end-effector resting on the table.
  static TabletopPoses example_poses();
  // The camera of the default set-up: about 0.75 m from the workspace, looking down at about 50 degrees.
  static Eigen::Isometry3d default_camera_pose();

  // A printed tag (with its white quiet zone) whose centre and axes are `world_from_tag` (tag frame: x right,
  // y up, z out of the face). `size` is the black border's edge.
  static TexturedQuad tag_quad(const TagFamily& family, int id, double size,
                               const Eigen::Isometry3d& world_from_tag);
  // A printed checkerboard with `inner_corners` (columns x rows) of squares' corners, squares of `square`
  // metres and a one-square white margin, centred at `world_from_board` (x along the columns, y down the
  // rows, z into the board). Its inner corner (c, r) is at ((c - (cols - 1) / 2) * square, (r - (rows - 1) /
  // 2) * square, 0) in the board frame.
  static TexturedQuad checkerboard_quad(cv::Size inner_corners, double square,
                                        const Eigen::Isometry3d& world_from_board);
  // Twelve varied board poses in the camera frame for calibration from rendered views: 0.45-0.55 m away
  // (times `scale`), off-centre, tilted up to 30 degrees about x and 25 about y, rolled a little each.
  static std::vector<Eigen::Isometry3d> checkerboard_calibration_poses(double scale = 1.0);
  // The six faces of a box centred at `world_from_box` with edge lengths `size`.
  static std::vector<TexturedQuad> box(const Eigen::Isometry3d& world_from_box, const Eigen::Vector3d& size,
                                       cv::Vec3b colour);

 private:
  void add_tag(const std::string& name, const Eigen::Isometry3d& table_from_object,
               std::vector<TexturedQuad>& out) const;

  TagConfig tags_;
  TabletopLayout layout_;
  std::shared_ptr<TagFamily> family_;
  cv::Mat table_texture_;
};

}  // namespace hlt
