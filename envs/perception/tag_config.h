// hlt::TagConfig: which AprilTags are in the scene, in the spirit of apriltag_ros's tag list. Each tag has
// an id, the name of the object it is stuck on, its printed size (the black border's edge, metres) and
// where that object's origin sits in the tag frame. One tag may be the reference tag: it lies on the table
// at a known pose and so fixes the camera-to-table transform.
//
// Tag frame (used throughout hlt perception): origin at the tag centre, x to the right of the printed tag,
// y towards its top edge, z out of the printed face towards the viewer.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

namespace hlt {

struct TagSpec {
  int id = 0;
  std::string name;
  double size = 0.0;  // metres, outer edge of the black border
  Eigen::Isometry3d tag_from_object = Eigen::Isometry3d::Identity();  // object origin in the tag frame
  std::optional<Eigen::Isometry3d> table_from_tag;                    // set for the reference tag only
};

class TagConfig {
 public:
  // Reads YAML of the form
  //   family: tag36h11
  //   tags:
  //     - {id: 0, name: table, size: 0.048, table_pose: [x, y, z, yaw_deg]}
  //     - {id: 1, name: block, size: 0.033, object_offset: [0, 0, -0.025]}
  // (object_offset: the object's origin in the tag frame, metres; default [0, 0, 0]). Every error names the
  // file, the tag entry and the field.
  static TagConfig load(const std::string& path);
  static TagConfig parse(const std::string& yaml_text, const std::string& source);
  // Built in code; validated like a file.
  TagConfig(std::string family, std::vector<TagSpec> tags);

  const std::string& family() const { return family_; }
  const std::vector<TagSpec>& tags() const { return tags_; }
  // nullptr for an id that is not configured.
  const TagSpec* find(int id) const;
  // Throws hlt::Error naming the id and the configured ones.
  const TagSpec& at(int id) const;
  const TagSpec& by_name(const std::string& name) const;
  bool has_name(const std::string& name) const;
  // The reference tag, if one is configured.
  const TagSpec* reference() const;

  std::string describe_ids() const;  // "0 (table), 1 (block), ..."

 private:
  TagConfig() = default;
  void validate(const std::string& source) const;

  std::string family_;
  std::vector<TagSpec> tags_;
};

}  // namespace hlt
