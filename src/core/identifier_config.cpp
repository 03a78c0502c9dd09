#include "pmsm_param_id/identifier_config.hpp"

#include "pmsm_param_id/yaml_reader.hpp"

namespace pmsm_param_id {

const std::string& methodList() {
  static const std::string list = "fbdapso, sapso, pso, ekf, rls";
  return list;
}
bool isKnownMethod(const std::string& m) {
  return m == "fbdapso" || m == "sapso" || m == "pso" || m == "ekf" || m == "rls";
}

void validate(const IdentifierConfig& c, const std::string& source) {
  const auto fail = [&](const std::string& key, const std::string& msg) {
    throw ConfigError(source + ": key '" + key + "': " + msg);
  };
  if (!isKnownMethod(c.method)) fail("method", "unknown method '" + c.method + "' (expected " + methodList() + ")");
  for (int p = 0; p < kParameterCount; ++p) {
    const std::string name = parameterNames()[p];
    if (!(c.lower[p] > 0)) fail("bounds." + name, "lower bound must be > 0");
    if (!(c.lower[p] < c.upper[p])) fail("bounds." + name, "lower bound must be < upper bound");
    if (!(c.initial[p] >= c.lower[p] && c.initial[p] <= c.upper[p]))
      fail("initial." + name, "must lie inside bounds." + name);
  }
  if (c.swarm.particles < 2) fail("swarm.particles", "population must be >= 2");
  if (c.swarm.reset_iterations < 1) fail("swarm.reset_iterations", "must be >= 1");
  if (!(c.swarm.v_max > 0 && c.swarm.v_max <= 1)) fail("swarm.v_max", "must be in (0, 1]");
  if (!(c.swarm.restart_velocity >= 0 && c.swarm.restart_velocity <= c.swarm.v_max))
    fail("swarm.restart_velocity", "must be in [0, v_max]");
  if (!(c.swarm.w_min >= 0 && c.swarm.w_min <= c.swarm.w_max)) fail("swarm.w_min", "must be in [0, w_max]");
  if (!(c.sapso_C1 > 0 && c.sapso_C1 < 1)) fail("sapso.C1", "must be in (0, 1)");
  if (!(c.fbdapso_C1 > 0 && c.fbdapso_C1 < 1)) fail("fbdapso.C1", "must be in (0, 1)");
  if (!(c.fbdapso_C2 > 0 && c.fbdapso_C2 < 1)) fail("fbdapso.C2", "must be in (0, 1)");
  if (!(c.sapso_T1 > 0)) fail("sapso.T1", "must be > 0");
  if (!(c.fbdapso_T1 > 0)) fail("fbdapso.T1", "must be > 0");
  if (!(c.fbdapso_T2 >= 0)) fail("fbdapso.T2", "must be >= 0");
  if (c.iterations_per_sample < 1) fail("swarm.iterations_per_sample", "must be >= 1");
  if (!(c.horizon.horizon > 0)) fail("window.horizon", "must be > 0");
  if (!(c.horizon.time_constant > 0)) fail("window.time_constant", "must be > 0");
  if (!(c.max_gap_periods > 1)) fail("time.max_gap_periods", "must be > 1");
}

IdentifierConfig loadIdentifierConfig(const std::string& path) {
  const YamlReader y = YamlReader::fromFile(path);
  IdentifierConfig c;
  c.method = y.text("method", c.method);
  const long seed = y.integer("seed", 1);
  if (seed < 0) y.fail("seed", "must be >= 0");
  c.seed = static_cast<std::uint64_t>(seed);
  for (int p = 0; p < kParameterCount; ++p) {
    const std::string name = parameterNames()[p];
    if (y.has("bounds." + name)) {
      const std::vector<double> b = y.numbers("bounds." + name);
      if (b.size() != 2) y.fail("bounds." + name, "expected [lower, upper]");
      c.lower[p] = b[0];
      c.upper[p] = b[1];
    }
    c.initial[p] = y.number("initial." + name, c.initial[p]);
  }
  c.horizon.horizon = y.number("window.horizon", c.horizon.horizon);
  c.horizon.time_constant = y.number("window.time_constant", c.horizon.time_constant);
  c.swarm.particles = static_cast<int>(y.integer("swarm.particles", c.swarm.particles));
  c.swarm.c1 = y.number("swarm.c1", c.swarm.c1);
  c.swarm.c2 = y.number("swarm.c2", c.swarm.c2);
  c.swarm.w_max = y.number("swarm.w_max", c.swarm.w_max);
  c.swarm.w_min = y.number("swarm.w_min", c.swarm.w_min);
  c.swarm.reset_iterations = static_cast<int>(y.integer("swarm.reset_iterations", c.swarm.reset_iterations));
  c.swarm.v_max = y.number("swarm.v_max", c.swarm.v_max);
  c.swarm.restart_velocity = y.number("swarm.restart_velocity", c.swarm.restart_velocity);
  c.iterations_per_sample = static_cast<int>(y.integer("swarm.iterations_per_sample", c.iterations_per_sample));
  c.sapso_T1 = y.number("sapso.T1", c.sapso_T1);
  c.sapso_C1 = y.number("sapso.C1", c.sapso_C1);
  c.fbdapso_T1 = y.number("fbdapso.T1", c.fbdapso_T1);
  c.fbdapso_T2 = y.number("fbdapso.T2", c.fbdapso_T2);
  c.fbdapso_C1 = y.number("fbdapso.C1", c.fbdapso_C1);
  c.fbdapso_C2 = y.number("fbdapso.C2", c.fbdapso_C2);
  c.fbdapso_zero_delta = y.positive("fbdapso.zero_delta", c.fbdapso_zero_delta);
  c.ekf.measurement_sigma = y.positive("ekf.measurement_sigma", c.ekf.measurement_sigma);
  c.ekf.process_current_sigma = y.positive("ekf.process_current_sigma", c.ekf.process_current_sigma);
  c.ekf.parameter_drift = y.positive("ekf.parameter_drift", c.ekf.parameter_drift);
  c.ekf.initial_relative_std = y.positive("ekf.initial_relative_std", c.ekf.initial_relative_std);
  c.rls.time_constant = y.positive("rls.time_constant", c.rls.time_constant);
  c.rls.initial_covariance = y.positive("rls.initial_covariance", c.rls.initial_covariance);
  c.current_noise = y.positive("observability.current_noise", c.current_noise);
  c.max_relative_std = y.positive("observability.max_relative_std", c.max_relative_std);
  c.max_gap_periods = y.number("time.max_gap_periods", c.max_gap_periods);
  validate(c, path);
  return c;
}

}  // namespace pmsm_param_id
