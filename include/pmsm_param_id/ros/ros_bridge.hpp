// The only place where ROS types meet the core's types.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <ros/ros.h>

#include <limits>
#include <type_traits>
#include <string>
#include <vector>

#include "pmsm_param_id/DriveSample.h"
#include "pmsm_param_id/DriveSampleBatch.h"
#include "pmsm_param_id/ElectricalParameters.h"
#include "pmsm_param_id/ParameterEstimate.h"
#include "pmsm_param_id/ParameterMap.h"
#include "pmsm_param_id/identification/motor_map.hpp"
#include "pmsm_param_id/identification/online_identifier.hpp"
#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/model/sample.hpp"

namespace pmsm_param_id {

/// Private parameter `name` of the node, checked for its type: missing -> fallback; present with
/// another type (`_seed:=abc`, `_method:=7`) -> ConfigError "parameter ~name: expected ..., got ...".
template <class T>
T typedParam(const ros::NodeHandle& pnh, const std::string& name, const T& fallback) {
  XmlRpc::XmlRpcValue v;
  if (!pnh.getParam(name, v)) return fallback;
  const auto got = [&]() -> std::string {
    switch (v.getType()) {
      case XmlRpc::XmlRpcValue::TypeString: return "the text '" + static_cast<std::string>(v) + "'";
      case XmlRpc::XmlRpcValue::TypeInt: return "the integer " + std::to_string(static_cast<int>(v));
      case XmlRpc::XmlRpcValue::TypeDouble: return "the number " + std::to_string(static_cast<double>(v));
      case XmlRpc::XmlRpcValue::TypeBoolean: return static_cast<bool>(v) ? "true" : "false";
      default: return "a value of another type";
    }
  };
  const auto fail = [&](const char* expected) {
    throw ConfigError("parameter ~" + name + ": expected " + expected + ", got " + got());
  };
  if constexpr (std::is_same_v<T, std::string>) {
    if (v.getType() != XmlRpc::XmlRpcValue::TypeString) fail("a text");
    return static_cast<std::string>(v);
  } else if constexpr (std::is_same_v<T, bool>) {
    if (v.getType() != XmlRpc::XmlRpcValue::TypeBoolean) fail("true or false");
    return static_cast<bool>(v);
  } else if constexpr (std::is_integral_v<T>) {
    if (v.getType() != XmlRpc::XmlRpcValue::TypeInt) fail("an integer");
    return static_cast<T>(static_cast<int>(v));
  } else {
    if (v.getType() == XmlRpc::XmlRpcValue::TypeInt) return static_cast<T>(static_cast<int>(v));
    if (v.getType() != XmlRpc::XmlRpcValue::TypeDouble) fail("a number");
    return static_cast<T>(static_cast<double>(v));
  }
}

/// Turns ROS stamps into the core's double seconds relative to the first stamp of the stream.
/// (Absolute stamps are ~1.7e9 s: as doubles they resolve only 0.24 us, too coarse for 1 MHz.)
class StreamClock {
 public:
  /// Seconds since the origin for a sample k periods after `stamp`.
  double seconds(const ros::Time& stamp, std::size_t k = 0, double period = 0.0) {
    if (!has_origin_ || stamp < origin_) {  // first stamp, or the stream restarted before it
      origin_ = stamp;
      has_origin_ = true;
    }
    // In nanoseconds, not ros::Duration: a stamp more than 2^31 s after the origin (a clock jump)
    // would throw "Duration is out of dual 32-bit range" there.
    const std::int64_t ns = static_cast<std::int64_t>(stamp.toNSec() - origin_.toNSec());
    return static_cast<double>(ns) * 1e-9 + static_cast<double>(k) * period;
  }
  ros::Time stampOf(double seconds) const {
    const double ns = std::round(seconds * 1e9);
    ros::Time t;
    t.fromNSec(origin_.toNSec() + static_cast<std::uint64_t>(std::max(0.0, ns)));
    return t;
  }
  void reset() { has_origin_ = false; }

 private:
  ros::Time origin_;
  bool has_origin_ = false;
};

/// The sample times of a stream of batches. A batch that continues the stream's sample index
/// (first_index where the last one ended) at the same period takes its times from the index, counted
/// from the stamp of the batch that began the stretch: a drive that stamps its batches on arrival
/// jitters them by more than a period, the index does not. Where a continuing batch's stamp parts
/// from the index's time by more than half a batch (and 20 periods), the drive's clock and ROS's
/// have drifted apart: the stretch begins again at that stamp (one step in time, which the
/// identifier handles as a gap or a close sample). A batch that does not continue (a gap in the
/// index, a restarted drive, another period) begins a stretch at its own stamp.
class BatchTiming {
 public:
  /// The seconds on `clock` of the batch's sample 0 and the count of periods after the stretch's
  /// stamp: sample k is at clock.seconds(anchor(), offset + k, period).
  struct Start {
    ros::Time anchor;
    std::uint64_t offset = 0;
  };
  Start start(StreamClock& clock, const DriveSampleBatch& b) {
    (void)clock.seconds(b.header.stamp);  // the clock's origin follows the stamps (a restart)
    const std::uint64_t n = b.u_d.size();
    bool keep = anchored_ && b.first_index == next_index_ && b.sample_period == period_ && b.first_index >= anchor_index_;
    if (keep) {
      const double offset_s = static_cast<double>(b.first_index - anchor_index_) * period_;
      const double predicted_ns = static_cast<double>(anchor_.toNSec()) + 1e9 * offset_s;
      const double deviation = (static_cast<double>(b.header.stamp.toNSec()) - predicted_ns) * 1e-9;
      const double tolerance = std::max(0.5 * static_cast<double>(n) * period_, 20.0 * period_);
      keep = std::abs(deviation) <= tolerance;
      if (!keep) ++reanchored_;
    }
    if (!keep) {
      anchor_ = b.header.stamp;
      anchor_index_ = b.first_index;
      period_ = b.sample_period;
      anchored_ = true;
    }
    next_index_ = b.first_index + n;
    return {anchor_, b.first_index - anchor_index_};
  }
  void reset() { anchored_ = false; }
  /// Continuing batches whose stamps had drifted more than the tolerance from the index's time.
  std::uint64_t reanchored() const { return reanchored_; }

 private:
  bool anchored_ = false;
  ros::Time anchor_;
  std::uint64_t anchor_index_ = 0, next_index_ = 0, reanchored_ = 0;
  double period_ = 0.0;
};

inline Sample toSample(const DriveSampleBatch& b, std::size_t k, double t) {
  Sample s{t, b.u_d[k], b.u_q[k], b.i_d[k], b.i_q[k], b.omega_e[k]};
  if (b.theta_e.size() == b.u_d.size()) s.theta_e = b.theta_e[k];
  if (b.v_dc.size() == b.u_d.size()) s.v_dc = b.v_dc[k];
  return s;
}
inline Sample toSample(const DriveSample& m, double t) {
  Sample s{t, m.u_d, m.u_q, m.i_d, m.i_q, m.omega_e};
  s.theta_e = m.theta_e;
  s.v_dc = m.v_dc;
  return s;
}

/// Empty string when the batch is well formed, else what is wrong with it.
inline std::string checkBatch(const DriveSampleBatch& b) {
  const std::size_t n = b.u_d.size();
  if (b.u_q.size() != n || b.i_d.size() != n || b.i_q.size() != n || b.omega_e.size() != n)
    return "arrays of different lengths";
  if (n > 1 && !(b.sample_period > 0)) return "sample_period must be > 0";
  if (!b.theta_e.empty() && b.theta_e.size() != n) return "theta_e must be empty or as long as the other arrays";
  if (!b.v_dc.empty() && b.v_dc.size() != n) return "v_dc must be empty or as long as the other arrays";
  return "";
}

inline ParameterEstimate toMessage(const Estimate& e, const ros::Time& stamp, const std::string& frame) {
  ParameterEstimate m;
  m.header.stamp = stamp;
  m.header.frame_id = frame;
  m.method = e.method;
  m.R_s = e.parameters[kRs];
  m.L_d = e.parameters[kLd];
  m.L_q = e.parameters[kLq];
  m.psi_f = e.parameters[kPsiF];
  for (int p = 0; p < kParameterCount; ++p) {
    m.status[p] = static_cast<std::uint8_t>(e.status[p]);
    m.status_reason[p] = e.reason[p];
    m.identifiable[p] = e.identifiable[p];
    m.relative_uncertainty[p] = e.relative_uncertainty[p];
    m.data_optimum[p] = e.fit.available ? e.fit.optimum[p] : std::numeric_limits<double>::quiet_NaN();
  }
  m.fit_consistent = e.fit.consistent;
  m.fit_ratio[0] = e.fit.fit_ratio_d;
  m.fit_ratio[1] = e.fit.fit_ratio_q;
  m.noise_std[0] = e.fit.noise_std_d;
  m.noise_std[1] = e.fit.noise_std_q;
  m.fit_likely_cause = e.fit.likely_cause;
  m.sample_period = e.sample_period;
  m.inverter_voltage = e.inverter_voltage;
  m.inverter_voltage_status = static_cast<std::uint8_t>(e.inverter_status);
  m.winding_temperature = e.winding_temperature.value;
  m.winding_temperature_uncertainty = e.winding_temperature.uncertainty;
  m.magnet_temperature = e.magnet_temperature.value;
  m.magnet_temperature_uncertainty = e.magnet_temperature.uncertainty;
  m.fitness = e.fitness;
  m.operating_i_d = e.operating_point.i_d;
  m.operating_i_q = e.operating_point.i_q;
  m.operating_omega_e = e.operating_point.omega_e;
  m.iteration = e.iteration;
  m.temperature = e.temperature;
  m.samples_used = e.counters.used;
  m.samples_skipped = e.counters.skipped();
  m.slow_R_s = e.slow.parameters[kRs];
  m.slow_psi_f = e.slow.parameters[kPsiF];
  for (int k = 0; k < 2; ++k) {
    const int p = k == 0 ? kRs : kPsiF;
    m.slow_status[k] = static_cast<std::uint8_t>(e.slow.status[p]);
    m.slow_status_reason[k] = e.slow.reason[p];
    m.slow_relative_uncertainty[k] = e.slow.relative_uncertainty[p];
  }
  m.slow_window_time_constant = e.slow.window_time_constant;
  m.torque_constant = e.torque_constant;
  m.speed_constant = e.speed_constant;
  m.motor_constant_relative_uncertainty = e.motor_constant_relative_uncertainty;
  return m;
}

/// The map of the motor as a message: stamps on the stream's clock, t = the last sample's time [s].
inline ParameterMap toMessage(const MotorMap& map, const std::string& method, const StreamClock& clock, double t,
                              const std::string& frame) {
  ParameterMap m;
  m.header.stamp = clock.stampOf(t);
  m.header.frame_id = frame;
  m.method = method;
  m.cell_fraction = map.settings().cell_fraction;
  m.transient_estimates = map.transientEstimates();
  for (const MotorMapCell& c : map.cells()) {
    ParameterMapCell cell;
    cell.i_d = c.i_d;
    cell.i_q = c.i_q;
    cell.operating_omega_e = c.latest_point.omega_e;
    for (int p = 0; p < kParameterCount; ++p) {
      const std::size_t k = static_cast<std::size_t>(p);
      cell.latest[k] = c.latest[p];
      cell.latest_status[k] = static_cast<std::uint8_t>(c.latest_status[p]);
      cell.identified[k] = c.identified[p];
      cell.identified_i_q[k] = c.hasIdentified(p) ? c.identified_point[p].i_q : std::nan("");
      if (c.hasIdentified(p)) cell.identified_stamp[k] = clock.stampOf(c.identified_t[p]);
      cell.identified_relative_uncertainty[k] = c.identified_uncertainty[p];
    }
    cell.L_dq = c.identified_L_dq;
    cell.first_seen = clock.stampOf(c.first_seen);
    cell.last_seen = clock.stampOf(c.last_seen);
    cell.estimates = c.estimates;
    m.cells.push_back(cell);
  }
  return m;
}

inline ElectricalParameters toMessage(const ParameterVector& p, const ros::Time& stamp,
                                      double winding_temperature = NAN, double magnet_temperature = NAN) {
  ElectricalParameters m;
  m.winding_temperature = winding_temperature;
  m.magnet_temperature = magnet_temperature;
  m.header.stamp = stamp;
  m.R_s = p[kRs];
  m.L_d = p[kLd];
  m.L_q = p[kLq];
  m.psi_f = p[kPsiF];
  return m;
}

}  // namespace pmsm_param_id
