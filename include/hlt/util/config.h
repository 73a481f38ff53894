// hlt::Config: a typed, declared set of settings loaded from YAML files and `key=value` overrides.
//
// Every key is declared up front with its type, default, documentation and allowed range or choices, so a
// typo, a wrong type or an out-of-range value is an error that names the key and what it accepts; nothing
// is silently ignored. Nested YAML maps are addressed with dotted keys ("planner.samples"). The resolved
// config is written back as YAML next to a run's results.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace hlt {

class Config {
 public:
  using IntList = std::vector<int64_t>;
  using Value = std::variant<bool, int64_t, double, std::string, IntList>;

  // Declarations. Keys are dotted paths of [a-z0-9_] segments. Redeclaring a key is a programming error.
  Config& add_bool(const std::string& key, bool default_value, const std::string& doc);
  Config& add_int(const std::string& key, int64_t default_value, const std::string& doc, int64_t min,
                  int64_t max);
  Config& add_double(const std::string& key, double default_value, const std::string& doc, double min,
                     double max);
  Config& add_string(const std::string& key, const std::string& default_value, const std::string& doc,
                     std::vector<std::string> choices = {});
  Config& add_int_list(const std::string& key, IntList default_value, const std::string& doc, int64_t min,
                       int64_t max);

  // Sources, applied in call order (later wins). `source` names the origin in error messages.
  void merge_yaml(const std::string& yaml_text, const std::string& source);
  void load_file(const std::string& path);
  // One "key=value" override; the value is parsed as a YAML scalar (or list) and checked like file values.
  void apply_override(const std::string& key_equals_value);
  void set(const std::string& key, const std::string& value_text, const std::string& source = "override");

  bool has(const std::string& key) const { return fields_.count(key) != 0; }
  bool get_bool(const std::string& key) const;
  int64_t get_int(const std::string& key) const;
  double get_double(const std::string& key) const;
  const std::string& get_string(const std::string& key) const;
  const IntList& get_int_list(const std::string& key) const;

  // Resolved values as nested YAML (every declared key, defaults included), and a written copy of it.
  std::string to_yaml() const;
  // Writes to_yaml() atomically; `header`, if given, goes first as '# ' comment lines (notes for the reader
  // that are not settings, such as the BLAS kernel a run used).
  void save(const std::string& path, const std::string& header = "") const;
  // One line per key: name, type, default, allowed values, documentation (for --help output).
  std::string describe() const;
  std::vector<std::string> keys() const;

 private:
  struct Field {
    Value value;
    Value default_value;
    std::string doc;
    double min = 0;
    double max = 0;
    std::vector<std::string> choices;
  };
  Config& declare(const std::string& key, Field field);
  const Field& field(const std::string& key, const char* type) const;
  std::string unknown_key_message(const std::string& key, const std::string& source) const;
  static std::string allowed(const Field& f);

  std::map<std::string, Field> fields_;
};

}  // namespace hlt
