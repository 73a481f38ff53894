#include "hlt/util/config.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <regex>
#include <sstream>

#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace {

const char* type_name(const Config::Value& v) {
  switch (v.index()) {
    case 0:
      return "bool";
    case 1:
      return "int";
    case 2:
      return "float";
    case 3:
      return "string";
    default:
      return "int list";
  }
}

std::string format_value(const Config::Value& v) {
  return std::visit(
      [](const auto& x) -> std::string {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, bool>) {
          return x ? "true" : "false";
        } else if constexpr (std::is_same_v<T, std::string>) {
          return x;
        } else if constexpr (std::is_same_v<T, Config::IntList>) {
          return fmt::format("[{}]", fmt::join(x, ", "));
        } else if constexpr (std::is_same_v<T, double>) {
          return fmt::format("{}", x);
        } else {
          return std::to_string(x);
        }
      },
      v);
}

size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j)
    row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diag = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

// Flattens nested maps into dotted keys; sequences and scalars are leaves.
// Keys are a few levels deep; an alias that refers to its own anchor would otherwise recurse forever.
constexpr int kMaxDepth = 16;

void flatten(const YAML::Node& node, const std::string& prefix,
             std::vector<std::pair<std::string, YAML::Node>>& out, const std::string& source, int depth = 0) {
  check(depth < kMaxDepth,
        "{}: settings nested more than {} levels deep at '{}' (an alias that refers to itself?)", source,
        kMaxDepth, prefix.substr(0, 120));
  if (node.IsMap()) {
    for (const auto& kv : node) {
      const std::string k = kv.first.as<std::string>();
      flatten(kv.second, prefix.empty() ? k : prefix + "." + k, out, source, depth + 1);
    }
  } else if (node.IsNull() && prefix.empty()) {
    // An empty document sets nothing.
  } else {
    out.emplace_back(prefix, node);
  }
}

}  // namespace

std::string Config::allowed(const Field& f) {
  switch (f.value.index()) {
    case 0:
      return "true or false";
    case 1:
      return fmt::format("an integer in [{}, {}]", static_cast<int64_t>(f.min), static_cast<int64_t>(f.max));
    case 2:
      return fmt::format("a number in [{}, {}]", f.min, f.max);
    case 3:
      return f.choices.empty() ? std::string("a string")
                               : fmt::format("one of: {}", fmt::join(f.choices, ", "));
    default:
      return fmt::format("a list of integers in [{}, {}] such as [128, 64]", static_cast<int64_t>(f.min),
                         static_cast<int64_t>(f.max));
  }
}

Config& Config::declare(const std::string& key, Field field) {
  static const std::regex key_pattern("[a-z0-9_]+(\\.[a-z0-9_]+)*");
  check(std::regex_match(key, key_pattern), "config key '{}' is not a dotted lower-case name", key);
  check(!fields_.count(key), "config key '{}' declared twice", key);
  field.default_value = field.value;
  fields_.emplace(key, std::move(field));
  return *this;
}

Config& Config::add_bool(const std::string& key, bool default_value, const std::string& doc) {
  return declare(key, Field{default_value, {}, doc, 0, 0, {}});
}

Config& Config::add_int(const std::string& key, int64_t default_value, const std::string& doc, int64_t min,
                        int64_t max) {
  check(min <= default_value && default_value <= max, "default of '{}' outside its range", key);
  return declare(key, Field{default_value, {}, doc, static_cast<double>(min), static_cast<double>(max), {}});
}

Config& Config::add_double(const std::string& key, double default_value, const std::string& doc, double min,
                           double max) {
  check(min <= default_value && default_value <= max, "default of '{}' outside its range", key);
  return declare(key, Field{default_value, {}, doc, min, max, {}});
}

Config& Config::add_string(const std::string& key, const std::string& default_value, const std::string& doc,
                           std::vector<std::string> choices) {
  check(choices.empty() || std::count(choices.begin(), choices.end(), default_value),
        "default of '{}' is not one of its choices", key);
  return declare(key, Field{default_value, {}, doc, 0, 0, std::move(choices)});
}

Config& Config::add_int_list(const std::string& key, IntList default_value, const std::string& doc,
                             int64_t min, int64_t max) {
  return declare(
      key, Field{std::move(default_value), {}, doc, static_cast<double>(min), static_cast<double>(max), {}});
}

std::string Config::unknown_key_message(const std::string& key, const std::string& source) const {
  std::string best;
  size_t best_distance = 4;  // only suggest near misses
  for (const auto& kv : fields_) {
    const size_t d = edit_distance(key, kv.first);
    if (d < best_distance) {
      best_distance = d;
      best = kv.first;
    }
  }
  std::string message = fmt::format("unknown config key '{}' in {}", key, source);
  if (!best.empty()) message += fmt::format(" (did you mean '{}'?)", best);
  message += fmt::format("; known keys: {}", fmt::join(keys(), ", "));
  return message;
}

namespace {

// Converts one YAML leaf to the declared type of `current`, or returns an empty optional.
std::optional<Config::Value> convert(const YAML::Node& node, const Config::Value& current) {
  try {
    switch (current.index()) {
      case 0:
        if (!node.IsScalar()) return std::nullopt;
        return Config::Value(node.as<bool>());
      case 1: {
        if (!node.IsScalar()) return std::nullopt;
        return Config::Value(node.as<int64_t>());
      }
      case 2: {
        if (!node.IsScalar()) return std::nullopt;
        const double v = node.as<double>();
        return Config::Value(v);
      }
      case 3:
        if (!node.IsScalar()) return std::nullopt;
        return Config::Value(node.as<std::string>());
      default: {
        Config::IntList list;
        if (node.IsSequence()) {
          for (const auto& item : node)
            list.push_back(item.as<int64_t>());
        } else if (node.IsScalar()) {
          // Accept "128,64" and "128x64" on the command line.
          std::string text = node.as<std::string>();
          std::replace(text.begin(), text.end(), 'x', ',');
          std::stringstream ss(text);
          std::string item;
          while (std::getline(ss, item, ','))
            list.push_back(YAML::Load(item).as<int64_t>());
        } else {
          return std::nullopt;
        }
        return Config::Value(list);
      }
    }
  } catch (const YAML::Exception&) {
    return std::nullopt;
  }
}

}  // namespace

void Config::merge_yaml(const std::string& yaml_text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw Error(fmt::format("malformed YAML in {}: {}", source, e.what()));
  }
  check(root.IsMap() || root.IsNull(), "{} must hold a map of settings at its top level", source);
  std::vector<std::pair<std::string, YAML::Node>> leaves;
  flatten(root, "", leaves, source);
  for (const auto& [key, node] : leaves) {
    auto it = fields_.find(key);
    if (it == fields_.end()) throw Error(unknown_key_message(key, source));
    Field& f = it->second;
    const std::string shown = node.IsScalar() ? node.Scalar() : YAML::Dump(node);
    auto converted = convert(node, f.value);
    if (!converted) {
      throw Error(
          fmt::format("config key '{}' in {}: expected {}, got '{}'", key, source, allowed(f), shown));
    }
    const Value& v = *converted;
    bool ok = true;
    if (v.index() == 1) {
      const auto x = std::get<int64_t>(v);
      ok = x >= f.min && x <= f.max;
    } else if (v.index() == 2) {
      const double x = std::get<double>(v);
      ok = std::isfinite(x) && x >= f.min && x <= f.max;
    } else if (v.index() == 3 && !f.choices.empty()) {
      ok = std::count(f.choices.begin(), f.choices.end(), std::get<std::string>(v)) > 0;
    } else if (v.index() == 4) {
      const auto& list = std::get<IntList>(v);
      ok = !list.empty() &&
           std::all_of(list.begin(), list.end(), [&](int64_t x) { return x >= f.min && x <= f.max; });
    }
    if (!ok)
      throw Error(
          fmt::format("config key '{}' in {}: expected {}, got '{}'", key, source, allowed(f), shown));
    f.value = v;
  }
}

void Config::load_file(const std::string& path) {
  merge_yaml(read_file(path), path);
}

void Config::set(const std::string& key, const std::string& value_text, const std::string& source) {
  if (!fields_.count(key)) throw Error(unknown_key_message(key, source));
  // Quote-free scalars go through the YAML parser so "3", "0.1", "true" and "[128, 64]" all work.
  YAML::Node node;
  try {
    node = YAML::Load(value_text);
  } catch (const YAML::Exception&) {
    node = YAML::Node(value_text);
  }
  if (node.IsNull()) node = YAML::Node(value_text);
  YAML::Node root;
  // Build a nested map so merge_yaml performs every check in one place.
  std::vector<std::string> parts;
  std::stringstream ss(key);
  std::string part;
  while (std::getline(ss, part, '.'))
    parts.push_back(part);
  YAML::Node leaf = node;
  for (auto it = parts.rbegin(); it != parts.rend(); ++it) {
    YAML::Node parent;
    parent[*it] = leaf;
    leaf = parent;
  }
  merge_yaml(YAML::Dump(leaf), source);
}

void Config::apply_override(const std::string& key_equals_value) {
  const auto eq = key_equals_value.find('=');
  check(eq != std::string::npos && eq > 0, "override '{}' is not of the form key=value", key_equals_value);
  set(key_equals_value.substr(0, eq), key_equals_value.substr(eq + 1), "override '" + key_equals_value + "'");
}

const Config::Field& Config::field(const std::string& key, const char* type) const {
  auto it = fields_.find(key);
  check(it != fields_.end(), "config key '{}' is not declared", key);
  check(std::string(type_name(it->second.value)) == type, "config key '{}' is a {}, not a {}", key,
        type_name(it->second.value), type);
  return it->second;
}

bool Config::get_bool(const std::string& key) const {
  return std::get<bool>(field(key, "bool").value);
}
int64_t Config::get_int(const std::string& key) const {
  return std::get<int64_t>(field(key, "int").value);
}
double Config::get_double(const std::string& key) const {
  return std::get<double>(field(key, "float").value);
}
const std::string& Config::get_string(const std::string& key) const {
  return std::get<std::string>(field(key, "string").value);
}
const Config::IntList& Config::get_int_list(const std::string& key) const {
  return std::get<IntList>(field(key, "int list").value);
}

std::vector<std::string> Config::keys() const {
  std::vector<std::string> out;
  for (const auto& kv : fields_)
    out.push_back(kv.first);
  return out;
}

namespace {

// The dotted keys as a tree, for nested YAML output.
struct KeyTree {
  std::map<std::string, KeyTree> children;
  const Config::Value* value = nullptr;
};

void emit(YAML::Emitter& out, const KeyTree& tree) {
  out << YAML::BeginMap;
  for (const auto& [name, child] : tree.children) {
    out << YAML::Key << name << YAML::Value;
    if (!child.value) {
      emit(out, child);
      continue;
    }
    std::visit(
        [&](const auto& x) {
          using T = std::decay_t<decltype(x)>;
          if constexpr (std::is_same_v<T, Config::IntList>) {
            out << YAML::Flow << YAML::BeginSeq;
            for (auto v : x)
              out << v;
            out << YAML::EndSeq;
          } else if constexpr (std::is_same_v<T, std::string>) {
            out << YAML::DoubleQuoted << x;
          } else if constexpr (std::is_same_v<T, double>) {
            // Shortest text that reads back to the same double; keep a '.' so it reads as a float.
            std::string text = fmt::format("{}", x);
            if (text.find_first_of(".e") == std::string::npos) text += ".0";
            out << text;
          } else {
            out << x;
          }
        },
        *child.value);
  }
  out << YAML::EndMap;
}

}  // namespace

std::string Config::to_yaml() const {
  KeyTree root;
  for (const auto& [key, f] : fields_) {
    KeyTree* node = &root;
    std::stringstream ss(key);
    std::string part;
    while (std::getline(ss, part, '.'))
      node = &node->children[part];
    node->value = &f.value;
  }
  YAML::Emitter out;
  emit(out, root);
  return std::string(out.c_str()) + "\n";
}

void Config::save(const std::string& path, const std::string& header) const {
  std::string comments;
  std::stringstream lines(header);
  for (std::string line; std::getline(lines, line);)
    comments += "# " + line + "\n";
  write_file_atomic(path, comments + to_yaml());
}

std::string Config::describe() const {
  std::string out;
  for (const auto& [key, f] : fields_) {
    out +=
        fmt::format("  {:<28} {} (default {}; {})\n", key, f.doc, format_value(f.default_value), allowed(f));
  }
  return out;
}

}  // namespace hlt
