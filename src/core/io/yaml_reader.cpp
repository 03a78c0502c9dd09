#include "pmsm_param_id/io/yaml_reader.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <functional>
#include <sstream>

namespace pmsm_param_id {

YamlReader YamlReader::fromFile(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw ConfigError(path + ": is a directory, not a YAML file");
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw ConfigError(path + ": cannot open file");
  } catch (const YAML::Exception& e) {
    throw ConfigError(path + ": not valid YAML (line " + std::to_string(e.mark.line + 1) + "): " + e.msg);
  }
  // An empty file is an empty mapping (every key at its default); anything but a mapping is an error.
  if (root.IsDefined() && !root.IsNull() && !root.IsMap())
    throw ConfigError(path + ": expected a mapping of keys at the top level, got " +
                      (root.IsSequence() ? std::string("a list") : std::string("a single value")));
  return YamlReader(root, path);
}

void YamlReader::fail(const std::string& key, const std::string& message) const {
  throw ConfigError(source_ + ": key '" + key + "': " + message);
}

YAML::Node YamlReader::find(const std::string& dotted_key) const {
  asked_.insert(dotted_key);
  YAML::Node node = YAML::Clone(root_);
  std::stringstream ss(dotted_key);
  std::string part;
  while (std::getline(ss, part, '.')) {
    if (node.IsSequence() && !part.empty() && part.find_first_not_of("0123456789") == std::string::npos) {
      const std::size_t i = std::stoul(part);
      if (i >= node.size()) return YAML::Node(YAML::NodeType::Undefined);
      node = node[i];
      continue;
    }
    if (!node.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
    node = node[part];
    if (!node.IsDefined()) return node;
  }
  return node;
}

bool YamlReader::has(const std::string& key) const {
  const YAML::Node n = find(key);
  return n.IsDefined() && !n.IsNull();
}

double YamlReader::number(const std::string& key) const {
  const YAML::Node n = find(key);
  if (!n.IsDefined() || n.IsNull()) fail(key, "missing");
  if (!n.IsScalar()) fail(key, "expected a number");
  double v = 0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    fail(key, "expected a number, got '" + n.Scalar() + "'");
  }
  if (!std::isfinite(v)) fail(key, "must be finite, got '" + n.Scalar() + "'");
  return v;
}
double YamlReader::number(const std::string& key, double fallback) const {
  return has(key) ? number(key) : fallback;
}
double YamlReader::positive(const std::string& key) const {
  const double v = number(key);
  if (!(v > 0)) fail(key, "must be > 0, got " + find(key).Scalar());
  return v;
}
double YamlReader::positive(const std::string& key, double fallback) const {
  return has(key) ? positive(key) : fallback;
}
double YamlReader::nonNegative(const std::string& key, double fallback, const std::string& hint) const {
  const double v = number(key, fallback);
  if (v < 0) fail(key, "must be >= 0" + hint);
  return v;
}
std::string YamlReader::oneOf(const std::string& key, const std::string& fallback,
                              const std::vector<std::string>& options) const {
  const std::string v = text(key, fallback);
  for (const std::string& o : options)
    if (v == o) return v;
  std::string expected;
  for (std::size_t k = 0; k < options.size(); ++k)
    expected += (k == 0 ? "" : k + 1 == options.size() ? " or " : ", ") + options[k];
  fail(key, "expected " + expected + ", got '" + v + "'");
}
long YamlReader::integer(const std::string& key, long fallback, long min, long max) const {
  if (!has(key)) return fallback;
  const double v = number(key);
  if (v != std::floor(v)) fail(key, "expected an integer, got " + find(key).Scalar());
  if (v < static_cast<double>(min) || v > static_cast<double>(max))
    fail(key, "must be an integer in [" + std::to_string(min) + ", " + std::to_string(max) + "], got " +
                  find(key).Scalar());
  return static_cast<long>(v);
}

namespace {
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}
}  // namespace

void YamlReader::rejectUnknownKeys() const {
  std::set<std::string> known;  // asked keys and every map on the way to them
  for (const std::string& k : asked_) {
    known.insert(k);
    for (std::size_t dot = k.find('.'); dot != std::string::npos; dot = k.find('.', dot + 1)) known.insert(k.substr(0, dot));
  }
  std::function<void(const YAML::Node&, const std::string&)> walk = [&](const YAML::Node& node, const std::string& prefix) {
    if (!node.IsMap()) return;
    for (const auto& kv : node) {
      const std::string key = prefix.empty() ? kv.first.as<std::string>() : prefix + "." + kv.first.as<std::string>();
      if (!known.count(key)) {
        std::string nearest;
        std::size_t best = std::string::npos;
        for (const std::string& k : asked_) {
          const std::string last = k.substr(k.rfind('.') == std::string::npos ? 0 : k.rfind('.') + 1);
          if (!last.empty() && last.find_first_not_of("0123456789") == std::string::npos) continue;  // list element
          const std::size_t d = editDistance(key, k);
          if (d < best) { best = d; nearest = k; }
        }
        fail(key, "unknown key" + (nearest.empty() ? std::string() : " (did you mean '" + nearest + "'?)"));
      }
      walk(kv.second, key);
    }
  };
  walk(root_, "");
}
std::string YamlReader::text(const std::string& key, const std::string& fallback) const {
  if (!has(key)) return fallback;
  const YAML::Node n = find(key);
  if (!n.IsScalar()) fail(key, "expected a text value");
  return n.Scalar();
}
bool YamlReader::flag(const std::string& key, bool fallback) const {
  if (!has(key)) return fallback;
  try {
    return find(key).as<bool>();
  } catch (const YAML::Exception&) {
    fail(key, "expected true or false, got '" + find(key).Scalar() + "'");
  }
}
std::vector<double> YamlReader::numbers(const std::string& key) const {
  const YAML::Node n = find(key);
  if (!n.IsDefined() || n.IsNull()) fail(key, "missing");
  if (!n.IsSequence()) fail(key, "expected a list of numbers");
  std::vector<double> out;
  for (size_t i = 0; i < n.size(); ++i) out.push_back(number(key + "." + std::to_string(i)));
  return out;
}

Profile YamlReader::profile(const std::string& key) const {
  if (!has(key)) fail(key, "missing");
  if (!find(key).IsMap()) fail(key, "expected a mapping with a 'type' key");
  const std::string type = text(key + ".type", "");
  if (type.empty()) fail(key + ".type", "missing");
  const auto k = [&](const char* sub) { return key + "." + sub; };
  try {
    if (type == "constant") return Profile::constant(number(k("value")));
    if (type == "step") return Profile::step(number(k("initial")), number(k("final")), number(k("time")));
    if (type == "ramp") {
      const double start = number(k("start")), end = number(k("end"));
      if (!(end > start)) fail(k("end"), "must be after start");
      return Profile::ramp(number(k("initial")), number(k("final")), start, end);
    }
    if (type == "sine")
      return Profile::sine(number(k("offset"), 0.0), number(k("amplitude")), positive(k("frequency")),
                           number(k("phase"), 0.0));
    if (type == "square")
      return Profile::square(number(k("offset"), 0.0), number(k("amplitude")), positive(k("frequency")));
    if (type == "piecewise") {
      std::vector<double> times = numbers(k("times")), values = numbers(k("values"));
      if (times.empty() || times.size() != values.size())
        fail(key, "'times' and 'values' must have the same, non-zero length");
      for (size_t i = 1; i < times.size(); ++i)
        if (!(times[i] > times[i - 1])) fail(k("times"), "must be strictly increasing");
      return Profile::piecewise(times, values);
    }
  } catch (const std::invalid_argument& e) {
    fail(key, e.what());
  }
  fail(k("type"), "unknown profile type '" + type + "' (expected constant, step, ramp, sine, square, piecewise)");
}
Profile YamlReader::profile(const std::string& key, const Profile& fallback) const {
  return has(key) ? profile(key) : fallback;
}

}  // namespace pmsm_param_id
