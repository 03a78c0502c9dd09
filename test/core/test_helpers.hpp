#pragma once
#include <fstream>
#include <string>
#include <vector>

#include "pmsm_param_id/simulation/drive_simulator.hpp"
#include "pmsm_param_id/simulation/scenario.hpp"

namespace test_helpers {

inline std::string sourcePath(const std::string& relative) { return std::string(PMSM_SOURCE_DIR) + "/" + relative; }

inline pmsm_param_id::Scenario scenario(const std::string& name) {
  return pmsm_param_id::loadScenario(sourcePath("config/scenarios/" + name));
}

inline std::vector<pmsm_param_id::SimulatedSample> run(const pmsm_param_id::Scenario& s) {
  pmsm_param_id::DriveSimulator sim(s);
  std::vector<pmsm_param_id::SimulatedSample> out;
  while (!sim.done()) out.push_back(sim.step());
  return out;
}

/// Writes text to a fresh file under the test's temporary folder and returns its path.
inline std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

}  // namespace test_helpers
