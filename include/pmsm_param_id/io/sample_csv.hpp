// Drive logs as CSV: header t,u_d,u_q,i_d,i_q,omega_e (SI, omega_e electrical) [,theta_e] [,v_dc] [,R_s,L_d,L_q,psi_f].
#pragma once
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "pmsm_param_id/io/log_format.hpp"
#include "pmsm_param_id/simulation/drive_simulator.hpp"
#include "pmsm_param_id/model/sample.hpp"

namespace pmsm_param_id {

struct SampleLog {
  std::vector<Sample> samples;
  std::vector<std::size_t> line_numbers;  ///< 1-based line in the file of each sample
  bool has_truth = false;                 ///< columns R_s,L_d,L_q,psi_f present
  std::vector<ParameterVector> truth;     ///< per sample when has_truth
};

/// Writes through `body` to a temporary name in the same folder, then renames: the file appears
/// complete or not at all. A device or a pipe (/dev/null, /dev/stdout) is written in place.
/// std::runtime_error naming the path where it cannot be written.
void writeFileAtomically(const std::string& path, const std::function<void(std::FILE*)>& body);

/// Writes every sample with full double precision. The file appears complete or not at all
/// (written to a temporary name in the same folder, then renamed). Throws std::runtime_error.
void writeSampleCsv(const std::string& path, const std::vector<SimulatedSample>& samples);

/// The same in another drive's layout (`format`: its column names, units, separator, dq scaling and
/// clock; a quantity without a column is left out), the truth columns R_s,L_d,L_q,psi_f appended.
/// clock_start: the clock's reading at t = 0, in s (a ms_today clock: the seconds since midnight).
void writeSampleCsv(const std::string& path, const std::vector<SimulatedSample>& samples, const LogFormat& format,
                    double clock_start = 0.0);

/// Reads a log. Extra columns are ignored. A missing column, a row with the wrong number of cells
/// or a non-numeric cell throws InputError naming the file and line. "nan"/"inf" cells are kept
/// as non-finite values so that the identifier can skip and count them.
/// `format` names and scales the columns (default: SI names t,u_d,u_q,i_d,i_q,omega_e[,theta_e][,v_dc]).
SampleLog readSampleCsv(const std::string& path, const LogFormat& format = {});

}  // namespace pmsm_param_id
