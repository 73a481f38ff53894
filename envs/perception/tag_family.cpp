#include "envs/perception/tag_family.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagStandard41h12.h>

#include <fmt/ranges.h>

#include "hlt/util/error.h"

namespace hlt {
namespace {

struct FamilyEntry {
  const char* name;
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

const FamilyEntry kFamilies[] = {
    {"tag36h11", tag36h11_create, tag36h11_destroy},
    {"tag25h9", tag25h9_create, tag25h9_destroy},
    {"tag16h5", tag16h5_create, tag16h5_destroy},
    {"tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy},
};

}  // namespace

std::vector<std::string> TagFamily::supported() {
  std::vector<std::string> names;
  for (const FamilyEntry& f : kFamilies)
    names.emplace_back(f.name);
  return names;
}

TagFamily::TagFamily(const std::string& name) : name_(name) {
  for (const FamilyEntry& f : kFamilies) {
    if (name == f.name) {
      family_ = f.create();
      destroy_ = f.destroy;
    }
  }
  check(family_ != nullptr, "unknown AprilTag family '{}'; supported: {}", name,
        fmt::join(supported(), ", "));
}

TagFamily::~TagFamily() {
  if (family_) destroy_(family_);
}

int TagFamily::code_count() const {
  return static_cast<int>(family_->ncodes);
}
int TagFamily::width_at_border() const {
  return family_->width_at_border;
}
int TagFamily::total_width() const {
  return family_->total_width;
}

cv::Mat TagFamily::image(int id) const {
  check(id >= 0 && id < code_count(), "tag id {} is not in family {} (ids 0..{})", id, name_,
        code_count() - 1);
  image_u8_t* im = apriltag_to_image(family_, id);
  cv::Mat out(im->height, im->width, CV_8U);
  for (int y = 0; y < im->height; ++y)
    for (int x = 0; x < im->width; ++x)
      out.at<uint8_t>(y, x) = im->buf[y * im->stride + x] ? 255 : 0;
  image_u8_destroy(im);
  return out;
}

}  // namespace hlt
