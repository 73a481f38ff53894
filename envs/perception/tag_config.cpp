#include "envs/perception/tag_config.h"

#include <cmath>
#include <set>

#include <yaml-cpp/yaml.h>

#include "envs/perception/pose_math.h"
#include "envs/perception/tag_family.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace {

std::vector<double> read_numbers(const YAML::Node& node, const std::string& where, size_t count) {
  check(node.IsSequence() && node.size() == count, "{} must be a list of {} numbers", where, count);
  std::vector<double> out;
  for (size_t i = 0; i < count; ++i) {
    double v = 0;
    try {
      v = node[i].as<double>();
    } catch (const YAML::Exception&) {
      throw Error(fmt::format("{}: entry {} is not a number", where, i));
    }
    check(std::isfinite(v), "{}: entry {} is not finite", where, i);
    out.push_back(v);
  }
  return out;
}

}  // namespace

TagConfig::TagConfig(std::string family, std::vector<TagSpec> tags)
    : family_(std::move(family)), tags_(std::move(tags)) {
  validate("tag config");
}

TagConfig TagConfig::load(const std::string& path) {
  return parse(read_file(path), path);
}

TagConfig TagConfig::parse(const std::string& yaml_text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw Error(fmt::format("{}: not valid YAML (line {}): {}", source, e.mark.line + 1, e.msg));
  }
  check(root.IsMap(), "{}: expected a map with 'family' and 'tags'", source);
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    check(key == "family" || key == "tags", "{}: unknown field '{}' (allowed: family, tags)", source, key);
  }
  TagConfig config;
  check(root["family"] && root["family"].IsScalar(), "{}: field 'family' is missing (e.g. family: tag36h11)",
        source);
  config.family_ = root["family"].as<std::string>();
  const YAML::Node tags = root["tags"];
  check(tags && tags.IsSequence() && tags.size() > 0, "{}: field 'tags' is missing or not a non-empty list",
        source);
  for (size_t i = 0; i < tags.size(); ++i) {
    const YAML::Node t = tags[i];
    const std::string where = fmt::format("{}: tags[{}]", source, i);
    check(t.IsMap(), "{} must be a map with id, name, size", where);
    for (const auto& kv : t) {
      const std::string key = kv.first.as<std::string>();
      check(key == "id" || key == "name" || key == "size" || key == "object_offset" || key == "table_pose",
            "{}: unknown field '{}' (allowed: id, name, size, object_offset, table_pose)", where, key);
    }
    TagSpec spec;
    check(t["id"].IsDefined(), "{}: field 'id' is missing", where);
    try {
      spec.id = t["id"].as<int>();
    } catch (const YAML::Exception&) {
      throw Error(fmt::format("{}: field 'id' must be an integer", where));
    }
    check(t["name"].IsDefined() && t["name"].IsScalar(), "{}: field 'name' is missing", where);
    spec.name = t["name"].as<std::string>();
    check(t["size"].IsDefined(), "{}: field 'size' is missing (metres, edge of the black border)", where);
    try {
      spec.size = t["size"].as<double>();
    } catch (const YAML::Exception&) {
      throw Error(fmt::format("{}: field 'size' must be a number (metres)", where));
    }
    if (t["object_offset"]) {
      const std::vector<double> o = read_numbers(t["object_offset"], where + ": field 'object_offset'", 3);
      spec.tag_from_object.translation() = Eigen::Vector3d(o[0], o[1], o[2]);
    }
    if (t["table_pose"]) {
      const std::vector<double> p =
          read_numbers(t["table_pose"], where + ": field 'table_pose' ([x, y, z, yaw_deg])", 4);
      spec.table_from_tag = pose_from_xyz_rpy(p[0], p[1], p[2], 0, 0, p[3] * M_PI / 180.0);
    }
    config.tags_.push_back(spec);
  }
  config.validate(source);
  return config;
}

void TagConfig::validate(const std::string& source) const {
  const TagFamily family(family_);  // throws for unknown families, naming the supported ones
  std::set<int> ids;
  std::set<std::string> names;
  int references = 0;
  for (size_t i = 0; i < tags_.size(); ++i) {
    const TagSpec& t = tags_[i];
    const std::string where = fmt::format("{}: tags[{}]", source, i);
    check(t.id >= 0 && t.id < family.code_count(), "{}: field 'id' is {}, but {} has ids 0..{}", where, t.id,
          family_, family.code_count() - 1);
    check(!t.name.empty(), "{}: field 'name' is empty", where);
    check(std::isfinite(t.size) && t.size > 0 && t.size < 10.0,
          "{}: field 'size' must be in (0, 10) metres, got {}", where, t.size);
    check(ids.insert(t.id).second, "{}: id {} appears twice", where, t.id);
    check(names.insert(t.name).second, "{}: name '{}' appears twice", where, t.name);
    check(is_finite(t.tag_from_object), "{}: field 'object_offset' is not finite", where);
    if (t.table_from_tag) ++references;
  }
  check(references <= 1, "{}: {} tags have a 'table_pose'; at most one reference tag is allowed", source,
        references);
}

const TagSpec* TagConfig::find(int id) const {
  for (const TagSpec& t : tags_)
    if (t.id == id) return &t;
  return nullptr;
}

const TagSpec& TagConfig::at(int id) const {
  const TagSpec* t = find(id);
  check(t != nullptr, "unknown tag id {}; configured: {}", id, describe_ids());
  return *t;
}

bool TagConfig::has_name(const std::string& name) const {
  for (const TagSpec& t : tags_)
    if (t.name == name) return true;
  return false;
}

const TagSpec& TagConfig::by_name(const std::string& name) const {
  for (const TagSpec& t : tags_)
    if (t.name == name) return t;
  throw Error(fmt::format("no tag named '{}' in the tag config; configured: {}", name, describe_ids()));
}

const TagSpec* TagConfig::reference() const {
  for (const TagSpec& t : tags_)
    if (t.table_from_tag) return &t;
  return nullptr;
}

std::string TagConfig::describe_ids() const {
  std::string s;
  for (const TagSpec& t : tags_)
    s += fmt::format("{}{} ({})", s.empty() ? "" : ", ", t.id, t.name);
  return s.empty() ? "none" : s;
}

}  // namespace hlt
