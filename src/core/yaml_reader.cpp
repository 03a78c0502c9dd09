#include "pmsm_param_id/yaml_reader.hpp"

#include <cmath>
#include <sstream>

namespace pmsm_param_id {

YamlReader YamlReader::fromFile(const std::string& path) {
  try {
    return YamlReader(YAML::LoadFile(path), path);
  } catch (const YAML::BadFile&) {
    throw ConfigError(path + ": cannot open file");
  } catch (const YAML::Exception& e) {
    throw ConfigError(path + ": not valid YAML (line " + std::to_string(e.mark.line + 1) + "): " + e.msg);
  }
}

void YamlReader::fail(const std::string& key, const std::string& message) const {
  throw ConfigError(source_ + ": key '" + key + "': " + message);
}

YAML::Node YamlReader::find(const std::string& dotted_key) const {
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
long YamlReader::integer(const std::string& key, long fallback) const {
  if (!has(key)) return fallback;
  const double v = number(key);
  if (v != std::floor(v)) fail(key, "expected an integer, got " + find(key).Scalar());
  return static_cast<long>(v);
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
