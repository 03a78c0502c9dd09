// Errors raised by configuration and input readers. One message, one line, naming where.
#pragma once
#include <stdexcept>
#include <string>

namespace pmsm_param_id {

/// A bad or missing configuration value. what() is one line: "FILE: key 'a.b': what is wrong".
class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(const std::string& message) : std::runtime_error(message) {}
};

/// Bad data in an input log (CSV). what() names the file and line number.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace pmsm_param_id
