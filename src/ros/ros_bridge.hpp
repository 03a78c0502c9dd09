// The only place where ROS types meet the core's types.
#pragma once
#include <ros/ros.h>

#include <string>
#include <vector>

#include "pmsm_param_id/DriveSample.h"
#include "pmsm_param_id/DriveSampleBatch.h"
#include "pmsm_param_id/ElectricalParameters.h"
#include "pmsm_param_id/ParameterEstimate.h"
#include "pmsm_param_id/online_identifier.hpp"
#include "pmsm_param_id/sample.hpp"

namespace pmsm_param_id {

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
    return (stamp - origin_).toSec() + static_cast<double>(k) * period;
  }
  ros::Time stampOf(double seconds) const { return origin_ + ros::Duration(seconds); }
  void reset() { has_origin_ = false; }

 private:
  ros::Time origin_;
  bool has_origin_ = false;
};

inline Sample toSample(const DriveSampleBatch& b, std::size_t k, double t) {
  return Sample{t, b.u_d[k], b.u_q[k], b.i_d[k], b.i_q[k], b.omega_e[k]};
}
inline Sample toSample(const DriveSample& m, double t) { return Sample{t, m.u_d, m.u_q, m.i_d, m.i_q, m.omega_e}; }

/// Empty string when the batch is well formed, else what is wrong with it.
inline std::string checkBatch(const DriveSampleBatch& b) {
  const std::size_t n = b.u_d.size();
  if (b.u_q.size() != n || b.i_d.size() != n || b.i_q.size() != n || b.omega_e.size() != n)
    return "arrays of different lengths";
  if (n > 1 && !(b.sample_period > 0)) return "sample_period must be > 0";
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
    m.identifiable[p] = e.identifiable[p];
    m.relative_std[p] = e.relative_std[p];
  }
  m.fitness = e.fitness;
  m.iteration = e.iteration;
  m.temperature = e.temperature;
  m.samples_used = e.counters.used;
  m.samples_skipped = e.counters.skipped();
  return m;
}

inline ElectricalParameters toMessage(const ParameterVector& p, const ros::Time& stamp) {
  ElectricalParameters m;
  m.header.stamp = stamp;
  m.R_s = p[kRs];
  m.L_d = p[kLd];
  m.L_q = p[kLq];
  m.psi_f = p[kPsiF];
  return m;
}

}  // namespace pmsm_param_id
