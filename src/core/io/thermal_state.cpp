#include "pmsm_param_id/io/thermal_state.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>

#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/io/yaml_reader.hpp"

namespace pmsm_param_id {

LearntReferences readThermalState(const std::string& path) {
  const YamlReader y = YamlReader::fromFile(path);
  LearntReferences r;
  r.reference_temperature = y.number("reference_temperature");
  const auto one = [&](const std::string& name, double& value, double& uncertainty, double& stamp) {
    if (!y.has(name + "_at_reference")) return;
    value = y.positive(name + "_at_reference");
    uncertainty = y.nonNegative(name + "_relative_uncertainty", 0.0, " [-]");
    if (!(uncertainty < 1.0)) y.fail(name + "_relative_uncertainty", "must be below 1 (a relative uncertainty)");
    stamp = y.number(name + "_learnt_at_stamp", std::numeric_limits<double>::quiet_NaN());
  };
  one("R_s", r.R_s, r.R_s_relative_uncertainty, r.R_s_learnt_at);
  one("psi_f", r.psi_f, r.psi_f_relative_uncertainty, r.psi_f_learnt_at);
  y.text("written", "");
  y.text("method", "");
  y.rejectUnknownKeys();
  return r;
}

void writeThermalState(const std::string& path, const LearntReferences& refs, const std::string& method) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::trunc);
    if (!f) throw UserError(tmp + ": cannot write the thermal state (" + std::strerror(errno) + ")");
    char stamp[32] = "";
    const std::time_t now = std::time(nullptr);
    std::tm utc{};
    if (gmtime_r(&now, &utc)) std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", &utc);
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "# pmsm_param_id thermal state: the references a cold start learnt (doc/algorithm.md section 9).\n"
                  "# Delete this file before a run that starts cold again after the motor was changed.\n"
                  "reference_temperature: %.17g  # [degC]\n",
                  refs.reference_temperature);
    f << buf;
    const auto one = [&](const char* name, double value, double uncertainty, double at, const char* unit) {
      if (!(value > 0)) return;
      std::snprintf(buf, sizeof buf,
                    "%s_at_reference: %.17g  # [%s]\n%s_relative_uncertainty: %.6g  # [-]\n", name, value, unit, name,
                    uncertainty);
      f << buf;
      if (std::isfinite(at)) {
        std::snprintf(buf, sizeof buf, "%s_learnt_at_stamp: %.17g  # stamp of the data it came from [s]\n", name, at);
        f << buf;
      }
    };
    one("R_s", refs.R_s, refs.R_s_relative_uncertainty, refs.R_s_learnt_at, "ohm");
    one("psi_f", refs.psi_f, refs.psi_f_relative_uncertainty, refs.psi_f_learnt_at, "Wb");
    f << "written: " << stamp << "  # wall clock, UTC\n";
    f << "method: " << (method.empty() ? std::string("unknown") : method) << "\n";
    f.flush();
    if (!f) throw UserError(tmp + ": cannot write the thermal state (disk full?)");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw UserError(path + ": cannot replace the thermal state (" + ec.message() + ")");
}

LearntReferences loadThermalStateFor(const std::string& path, double reference_temperature) {
  std::error_code ec;
  if (path.empty() || !std::filesystem::exists(path, ec)) return LearntReferences{};
  LearntReferences r = readThermalState(path);
  if (!(std::abs(r.reference_temperature - reference_temperature) <= 1e-9)) {
    char buf[160];
    std::snprintf(buf, sizeof buf, ": learnt at reference_temperature %.6g degC, the config says %.6g degC",
                  r.reference_temperature, reference_temperature);
    throw ConfigError(path + buf + " (delete the file to learn anew at a cold start)");
  }
  return r;
}

}  // namespace pmsm_param_id
