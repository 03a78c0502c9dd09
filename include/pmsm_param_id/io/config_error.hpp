// Errors raised by configuration and input readers. One message, one line, naming where.
#pragma once
#include <stdexcept>
#include <string>

namespace pmsm_param_id {

/// Something the user gave us is wrong (tools exit with status 2 and print what()).
class UserError : public std::runtime_error {
 public:
  explicit UserError(const std::string& message) : std::runtime_error(message) {}
};

/// A bad or missing configuration value. what() is one line: "FILE: key 'a.b': what is wrong".
class ConfigError : public UserError {
 public:
  explicit ConfigError(const std::string& message) : UserError(message) {}
};

/// Bad data in an input log (CSV). what() names the file and line number.
class InputError : public UserError {
 public:
  explicit InputError(const std::string& message) : UserError(message) {}
};

}  // namespace pmsm_param_id
