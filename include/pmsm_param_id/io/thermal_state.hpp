// The thermal state file: the references a cold start learnt (thermal.hpp, LearntReferences),
// kept across restarts of an identifier. A small YAML mapping, written whole to a temporary file
// and renamed over the old one, so that a reader never sees half a file:
//   reference_temperature: 20          # [degC], the config's at the cold start
//   R_s_at_reference: 3.6012           # [ohm]   (absent: not learnt)
//   R_s_relative_uncertainty: 0.0041   # [-]
//   R_s_learnt_at_stamp: 1.52          # stamp of the data it came from [s]
//   psi_f_at_reference: 0.5503         # [Wb]
//   psi_f_relative_uncertainty: 0.002  # [-]
//   psi_f_learnt_at_stamp: 0.61        # [s]
//   written: 2026-11-25T18:02:11Z      # wall clock (UTC) when the file was written
//   method: fbdapso                    # the identifier that wrote it (the values are the data's, not the method's)
#pragma once
#include <string>

#include "pmsm_param_id/identification/thermal.hpp"

namespace pmsm_param_id {

/// Reads a state file. ConfigError (naming the file and key) when it cannot be read, is not such
/// a mapping, holds an unknown key or a value out of range.
LearntReferences readThermalState(const std::string& path);

/// Writes it (to path + ".tmp", then renamed). UserError when the folder cannot be written.
void writeThermalState(const std::string& path, const LearntReferences& refs, const std::string& method);

/// The references to start from: none where the file does not exist (a first cold start), the
/// file's where it does. ConfigError where it exists but was learnt at another reference
/// temperature than reference_temperature (the config changed: its values would be read at the
/// wrong temperature), or cannot be read.
LearntReferences loadThermalStateFor(const std::string& path, double reference_temperature);

}  // namespace pmsm_param_id
