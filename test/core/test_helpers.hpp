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

/// Expects load() to throw Error whose message names key (a refused config key, a bad input's field).
template <class Error, class Load>
void expectRefusedNaming(Load load, const std::string& key, const std::string& what_was_accepted) {
  try {
    load();
    ADD_FAILURE() << what_was_accepted << " was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
  }
}

}  // namespace test_helpers
