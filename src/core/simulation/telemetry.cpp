#include "pmsm_param_id/simulation/telemetry.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace pmsm_param_id {

std::vector<SimulatedSample> averageToTelemetry(const std::vector<SimulatedSample>& samples, double period) {
  if (!(period > 0) || !std::isfinite(period)) throw std::invalid_argument("averageToTelemetry: period must be > 0");
  std::vector<SimulatedSample> out;
  if (samples.empty()) return out;
  const double start = samples.front().sample.t;
  const double spacing = samples.size() > 1 ? samples[1].sample.t - samples[0].sample.t : period;
  // Interval j holds the samples with start + j period <= t < start + (j + 1) period; it is kept
  // where its samples span the whole of it (the run's last, cut-off interval is not).
  SimulatedSample sum{};
  std::size_t count = 0;
  long current = 0;
  double first_t = 0.0, last_t = 0.0;
  const auto close = [&]() {
    if (count > 0 && last_t - first_t >= period - 1.5 * spacing) out.push_back(sum);
    sum = SimulatedSample{};
    count = 0;
  };
  for (const SimulatedSample& s : samples) {
    const long j = static_cast<long>(std::floor((s.sample.t - start) / period + 1e-9));
    if (j != current) {
      close();
      current = j;
    }
    if (count == 0) first_t = s.sample.t;
    last_t = s.sample.t;
    const double w = 1.0 / static_cast<double>(count + 1);  // running means
    Sample& m = sum.sample;
    m.u_d += w * (s.sample.u_d - m.u_d);
    m.u_q += w * (s.sample.u_q - m.u_q);
    m.i_d += w * (s.sample.i_d - m.i_d);
    m.i_q += w * (s.sample.i_q - m.i_q);
    m.omega_e += w * (s.sample.omega_e - m.omega_e);
    m.v_dc = count == 0 ? s.sample.v_dc : m.v_dc + w * (s.sample.v_dc - m.v_dc);
    m.t = start + static_cast<double>(j + 1) * period;
    m.theta_e = std::numeric_limits<double>::quiet_NaN();
    sum.truth = s.truth;
    sum.winding_temperature = s.winding_temperature;
    sum.magnet_temperature = s.magnet_temperature;
    ++count;
  }
  close();
  return out;
}

}  // namespace pmsm_param_id
