// The pmsm_tool subcommands, one file each (simulate.cpp, identify.cpp, bench.cpp, perf.cpp);
// main() in pmsm_tool.cpp parses the command line. Each returns the process's exit status.
#pragma once
#include <string>

#include "pmsm_param_id/io/log_format.hpp"

namespace pmsm_param_id::tool {

int runSimulate(const std::string& scenario_path, const std::string& csv, long seed, double duration,
                double telemetry_period, const std::string& format, double clock_start);
int runIdentify(const std::string& csv, const std::string& method, const std::string& config_path, long seed,
                const std::string& json_out, const LogFormat& format, const std::string& map_csv,
                const std::string& thermal_state, const std::string& data_kind, const std::string& trace_csv);
int runBench(const std::string& scenario_path, int seeds, const std::string& methods_arg, const std::string& config_path,
             const std::string& json_out, const std::string& reference, int threads, bool monitor, bool map_roundtrip);
int runPerf(const std::string& scenario_path, const std::string& methods_arg, const std::string& config_path,
            int repeat, const std::string& json_out, const std::string& paper_scenario_path,
            const std::string& drive_scenario_path);

}  // namespace pmsm_param_id::tool
