// Strict YAML access that names the file and key in every error (yaml-cpp underneath).
#pragma once
#include <yaml-cpp/yaml.h>

#include <set>
#include <string>
#include <vector>

#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/simulation/profile.hpp"

namespace pmsm_param_id {

class YamlReader {
 public:
  /// Loads a file; ConfigError if it cannot be read or parsed.
  static YamlReader fromFile(const std::string& path);
  YamlReader(YAML::Node root, std::string source) : root_(std::move(root)), source_(std::move(source)) {}

  bool has(const std::string& key) const;
  /// Required number; ConfigError if missing or not a finite number.
  double number(const std::string& key) const;
  double number(const std::string& key, double fallback) const;
  double positive(const std::string& key) const;
  double positive(const std::string& key, double fallback) const;
  /// Optional number >= 0; ConfigError "must be >= 0" + hint (e.g. " [V]", " (0 = automatic)").
  double nonNegative(const std::string& key, double fallback, const std::string& hint = "") const;
  /// Integer in [min, max]; ConfigError naming the range otherwise.
  long integer(const std::string& key, long fallback, long min, long max) const;
  std::string text(const std::string& key, const std::string& fallback) const;
  /// Optional text that must be one of options; ConfigError "expected a, b or c, got 'x'".
  std::string oneOf(const std::string& key, const std::string& fallback, const std::vector<std::string>& options) const;
  bool flag(const std::string& key, bool fallback) const;
  std::vector<double> numbers(const std::string& key) const;
  /// A profile mapping {type: constant|step|ramp|sine|square|piecewise, ...}.
  Profile profile(const std::string& key) const;
  Profile profile(const std::string& key, const Profile& fallback) const;

  /// ConfigError "SOURCE: key 'key': message".
  [[noreturn]] void fail(const std::string& key, const std::string& message) const;
  const std::string& source() const { return source_; }
  /// ConfigError for the first key in the file that no reader call asked for, naming the nearest
  /// key that was asked for (a typo must not silently fall back to a default).
  void rejectUnknownKeys() const;

 private:
  YAML::Node find(const std::string& dotted_key) const;
  YAML::Node root_;
  std::string source_;
  mutable std::set<std::string> asked_;  // every key looked up: the keys this reader knows
};

}  // namespace pmsm_param_id
