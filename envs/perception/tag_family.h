// hlt::TagFamily: one AprilTag family from libapriltag (owning its apriltag_family_t), and the tag images
// libapriltag itself generates. A family's tag "size" is the edge of its black border: width_at_border()
// of the total_width() cells of a tag image (the rest is the white quiet zone).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

struct apriltag_family;

namespace hlt {

class TagFamily {
 public:
  // Names as in libapriltag: tag36h11, tag25h9, tag16h5, tagStandard41h12. Unknown names throw, listing
  // these.
  explicit TagFamily(const std::string& name);
  ~TagFamily();
  TagFamily(const TagFamily&) = delete;
  TagFamily& operator=(const TagFamily&) = delete;

  static std::vector<std::string> supported();

  const std::string& name() const { return name_; }
  int code_count() const;
  int width_at_border() const;
  int total_width() const;
  // The tag's image, total_width() x total_width() pixels of 0 (black) or 255 (white), row 0 at the top.
  cv::Mat image(int id) const;
  apriltag_family* raw() const { return family_; }

 private:
  std::string name_;
  apriltag_family* family_ = nullptr;
  void (*destroy_)(apriltag_family*) = nullptr;
};

}  // namespace hlt
