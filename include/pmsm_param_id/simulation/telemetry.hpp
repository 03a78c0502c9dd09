// What a drive streams instead of its current loop's samples: means over intervals far longer than
// a control period (a VESC's avg_id, avg_iq, avg_vd, avg_vq at 50-1000 Hz; the 2 Hz motor-
// temperature data set).
#pragma once
#include <vector>

#include "pmsm_param_id/simulation/drive_simulator.hpp"

namespace pmsm_param_id {

/// The samples averaged over consecutive intervals of `period` [s]: u_d, u_q, i_d, i_q, omega_e and
/// v_dc as their means over the interval, stamped at its end, the truth at its end; no angle
/// (theta_e NaN: telemetry carries none). A last, incomplete interval is dropped. period must be
/// at least the samples' own spacing.
std::vector<SimulatedSample> averageToTelemetry(const std::vector<SimulatedSample>& samples, double period);

}  // namespace pmsm_param_id
