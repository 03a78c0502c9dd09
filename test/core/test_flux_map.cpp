// Flux maps in the simulator (model/flux_map.hpp) and the identifier's online map of the motor
// (identification/motor_map.hpp).
#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <memory>

#include "pmsm_param_id/identification/identifiers.hpp"
#include "pmsm_param_id/identification/motor_map.hpp"
#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/model/flux_map.hpp"
#include "test_helpers.hpp"

using namespace pmsm_param_id;
using namespace test_helpers;

namespace {
std::string loadError(const std::string& text) {
  try {
    loadFluxTable(writeTemp("flux_map_bad.csv", text));
  } catch (const InputError& e) {
    return e.what();
  }
  return "(accepted)";
}

}  // namespace

TEST(FluxMap, LoaderNamesWhatIsWrongAndWhere) {
  EXPECT_NE(loadError("i_d,i_q,psi_d\n0,0,0.5\n").find("missing 'psi_q'"), std::string::npos);
  EXPECT_NE(loadError("i_d,i_q,psi_d,psi_q\n0,0,0.5,0\n1,0,abc,0\n").find(":3: 'psi_d' is not a finite number: 'abc'"),
            std::string::npos);
  EXPECT_NE(loadError("i_d,i_q,psi_d,psi_q\n0,0,0.5,0\n0,0,0.5,0\n").find("given twice"), std::string::npos);
  EXPECT_NE(loadError("i_d,i_q,psi_d,psi_q\n0,0,0.5,0\n1,0,0.51,0\n0,1,0.5,0.1\n").find("node i_d = 1 A, i_q = 1 A is missing"),
            std::string::npos);
  EXPECT_NE(loadError("i_d,i_q,psi_d,psi_q\n0,0,0.5,0\n1,0,0.49,0\n0,1,0.5,0.1\n1,1,0.51,0.1\n").find("psi_d must increase with i_d"),
            std::string::npos);
  EXPECT_NE(loadError("i_d,i_q,psi_d,psi_q\n0,0,0.5,0\n1,0,0.51,0\n").find("at least two i_d and two i_q"), std::string::npos);
  EXPECT_NE(loadError("").find("empty flux map"), std::string::npos);
  // psi_d rising steeply with i_q and psi_q with i_d: det(L) = 0.01 * 0.01 - 0.1 * 0.1 < 0.
  EXPECT_NE(loadError("i_d,i_q,psi_d,psi_q\n0,0,0.5,0\n1,0,0.51,0.1\n0,1,0.6,0.01\n1,1,0.61,0.11\n").find("not positive definite"),
            std::string::npos);
  // Columns in any order, comments and blank lines allowed.
  EXPECT_EQ(loadError("# from a dyno\npsi_q,psi_d,i_q,i_d\n0,0.5,0,0\n0,0.51,0,1\n\n0.1,0.5,1,0\n0.1,0.51,1,1\n"), "(accepted)");
}

TEST(FluxMap, BilinearIsExactOnABilinearMachineInsideAndOutsideTheGrid) {
  // psi_d = 0.4 + 0.02 i_d - 0.001 i_d i_q, psi_q = 0.05 i_q - 0.001 i_d i_q + 0.003 i_d: bilinear.
  const auto pd = [](double d, double q) { return 0.4 + 0.02 * d - 0.001 * d * q; };
  const auto pq = [](double d, double q) { return 0.05 * q - 0.001 * d * q + 0.003 * d; };
  std::vector<double> i_d{-2, 0, 1.5}, i_q{0, 4, 10}, psi_d, psi_q;
  for (double q : i_q)
    for (double d : i_d) {
      psi_d.push_back(pd(d, q));
      psi_q.push_back(pq(d, q));
    }
  const FluxTable t(i_d, i_q, psi_d, psi_q);
  for (double d : {-3.0, -1.0, 0.7, 2.5})
    for (double q : {-1.0, 2.0, 7.0, 12.0}) {
      const FluxLinkage f = t.at(d, q);
      EXPECT_NEAR(f.psi_d, pd(d, q), 1e-12);
      EXPECT_NEAR(f.psi_q, pq(d, q), 1e-12);
      EXPECT_NEAR(f.dpsi_d_di_d, 0.02 - 0.001 * q, 1e-12);
      EXPECT_NEAR(f.dpsi_d_di_q, -0.001 * d, 1e-12);
      EXPECT_NEAR(f.dpsi_q_di_d, -0.001 * q + 0.003, 1e-12);
      EXPECT_NEAR(f.dpsi_q_di_q, 0.05 - 0.001 * d, 1e-12);
    }
}

// The simulator against theory: the analytic machine's fluxes tabulated on a 0.5 A grid drive the
// flux-state plant as the model itself does (the same run, seed for seed).
TEST(FluxMap, TheModelTabulatedDrivesTheSimulatorAsTheModelDoes) {
  Scenario s = scenario("saturated_map.yaml");
  s.duration = 3.0;
  std::vector<double> i_d, i_q, psi_d, psi_q;
  for (int k = 0; k <= 12; ++k) i_d.push_back(-3.0 + 0.5 * k);
  for (int k = 0; k <= 30; ++k) i_q.push_back(-1.0 + 0.5 * k);
  for (double q : i_q)
    for (double d : i_d) {
      const MagneticState g = magneticState(s.motor, s.saturation, d, q);
      psi_d.push_back(g.psi_d);
      psi_q.push_back(g.psi_q);
    }
  const auto model = run(s);
  const auto table = run(withFluxMap(s, std::make_shared<const FluxTable>(i_d, i_q, psi_d, psi_q)));
  const CurrentDifference d = currentDifference(model, table);
  EXPECT_LT(d.relative_rms, 1e-3);
  EXPECT_LT(d.largest, 0.03);  // [A], against 6 A
  // And the truth it reports: the secant L_q and psi_d(0, i_q) of the table's cell.
  const MagneticState g = magneticState(s.motor, s.saturation, 0.0, 6.0);
  const SimulatedSample& last = table.back();
  EXPECT_NEAR(last.truth[kLq] / g.L_q_secant, 1.0, 2e-3);
  EXPECT_NEAR(last.truth[kPsiF] / g.psi_d_at_zero_i_d, 1.0, 2e-4);
}

TEST(FluxMap, ScenarioReadsTheMapBesideItAndRefusesWhatCannotApply) {
  writeTemp("flux_beside.csv", "i_d,i_q,psi_d,psi_q\n-2,0,0.45,0\n2,0,0.55,0\n-2,10,0.44,0.8\n2,10,0.54,0.8\n");
  const std::string base = std::string("name: m\nmotor: {pole_pairs: 3, R_s: 0.9, L_d: 0.025, L_q: 0.08, psi_f: 0.5, inertia: 0.02, friction: 0}\n") +
                           "drive: {mode: torque, sample_period: 1.0e-4, dc_bus_voltage: 560, max_current: 20, current_loop_bandwidth_hz: 300, speed_loop_bandwidth_hz: 10}\nrun: {duration: 0.01}\n" +
                           "profiles: {speed_rpm: {type: constant, value: 900}, load_torque: {type: constant, value: 0}, " +
                           "q_current_reference: {type: constant, value: 5}}\n";
  const Scenario s = loadScenario(writeTemp("flux_scenario.yaml", base + "saturation: {flux_map_csv: flux_beside.csv}\n"));
  ASSERT_TRUE(s.saturation.flux_map);
  EXPECT_NEAR(s.saturation.flux_map->at(0.0, 5.0).psi_q, 0.4, 1e-12);
  const auto refused = [&](const std::string& extra) {
    try {
      loadScenario(writeTemp("flux_scenario_bad.yaml", base + extra));
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  EXPECT_NE(refused("saturation: {flux_map_csv: flux_beside.csv, cross_saturation: 1e-4}\n").find("not both"), std::string::npos);
  EXPECT_NE(refused("saturation: {flux_map_csv: nowhere.csv}\n").find("cannot open the flux map"), std::string::npos);
  EXPECT_NE(refused("saturation: {flux_map_csv: flux_beside.csv}\nthermal: {ambient_temperature: 20}\n").find("at one temperature"),
            std::string::npos);
}

// Five load levels visited up and down: every cell's identified values within 2 % of the truth of
// its operating point, R_s never identified wrongly, and the exported map drives the simulator
// through the same run within 1 % of its currents (a map that ignores saturation does not).
TEST(MotorMap, FiveLoadLevelsMappedAndTheExportReproducesTheRun) {
  const Scenario s = scenario("saturated_map.yaml");
  const auto original = run(s);
  IdentifierConfig c = loadIdentifierConfig(sourcePath("config/identifiers/default.yaml"));
  c.method = "wls";
  c.magnetics.cross_saturation = true;
  auto id = makeIdentifier(c);
  MotorMap map;
  for (std::size_t k = 0; k < original.size(); ++k) {
    id->process(original[k].sample);
    if (k % 100 == 99) map.add(id->estimate());  // every 10 ms, as the node's map is fed
  }
  EXPECT_GT(map.transientEstimates(), 0u);  // the load steps
  int mapped = 0;
  for (const MotorMapCell& cell : map.cells()) {
    for (int p = 0; p < kParameterCount; ++p) {
      if (!cell.hasIdentified(p)) continue;
      const MagneticState g = magneticState(s.motor, s.saturation, 0.0, cell.identified_point[p].i_q);
      const double truth[kParameterCount] = {s.motor.R_s, g.L_dd, g.L_q_secant, g.psi_d_at_zero_i_d};
      EXPECT_NEAR(cell.identified[p] / truth[p], 1.0, 0.02) << parameterNames()[p] << " at i_q = " << cell.i_q;
    }
    mapped += cell.hasIdentified(kLd) && cell.hasIdentified(kLq) && cell.hasIdentified(kPsiF);
  }
  EXPECT_GE(mapped, 5);
  const std::string csv = ::testing::TempDir() + "learnt_map.csv";
  writeFluxTable(map.fluxTable(), csv, "learnt by the test");
  const CurrentDifference learnt = currentDifference(original, run(withFluxMap(s, std::make_shared<const FluxTable>(loadFluxTable(csv)))));
  EXPECT_LT(learnt.relative_rms, 0.01);
  // The same run with a map of the unsaturated machine (L_q0, psi_f, L_d0 everywhere).
  const std::vector<double> i_d{-3, 0, 3}, i_q{0, 5, 10, 15};
  std::vector<double> psi_d, psi_q;
  for (double q : i_q)
    for (double d : i_d) {
      psi_d.push_back(s.motor.psi_f + s.motor.L_d * d);
      psi_q.push_back(s.motor.L_q * q);
    }
  const CurrentDifference linear = currentDifference(original, run(withFluxMap(s, std::make_shared<const FluxTable>(i_d, i_q, psi_d, psi_q))));
  EXPECT_GT(linear.relative_rms, 0.05);
}

TEST(MotorMap, AFullMapReplacesTheCellSeenLongestAgo) {
  MotorMapSettings settings;
  settings.max_cells = 3;
  MotorMap map(settings);
  Estimate e;
  e.parameters = {0.9, 0.025, 0.09, 0.49};
  e.status.fill(ParameterStatus::Identified);
  const double currents[] = {16.0, 1.0, 2.0, 4.0, 8.0};  // five cells' worth (the largest first: fixed tolerances)
  for (int k = 0; k < 5; ++k) {
    e.t = k;
    e.operating_point = {0.0, currents[k], 280.0, 0.1, 0.01};
    EXPECT_GE(map.add(e), 0) << k;
  }
  ASSERT_EQ(map.cells().size(), 3u);
  EXPECT_EQ(map.replacedCells(), 2u);
  std::vector<double> kept;
  for (const MotorMapCell& c : map.cells()) kept.push_back(c.i_q);
  std::sort(kept.begin(), kept.end());
  EXPECT_EQ(kept, (std::vector<double>{2.0, 4.0, 8.0}));  // 16 A (t = 0) and 1 A (t = 1) made room
  EXPECT_NE(map.coverageNote().find("2 cell(s) replaced by newer operating points (map.max_cells = 3)"), std::string::npos)
      << map.coverageNote();
  MotorMapSettings none;
  none.max_cells = 0;
  EXPECT_THROW(MotorMap{none}, ConfigError);
}

TEST(MotorMap, AWindowAcrossALoadStepIsNotFiled) {
  MotorMap map;
  Estimate e;
  e.t = 1.0;
  e.parameters = {0.9, 0.025, 0.09, 0.49};
  e.status.fill(ParameterStatus::Identified);
  e.operating_point = {0.0, 6.0, 280.0, 0.7, 0.05};
  EXPECT_EQ(map.add(e), 0);
  e.operating_point = {0.0, 6.2, 280.0, 0.7, 0.05};  // same cell
  EXPECT_EQ(map.add(e), 0);
  e.operating_point = {0.0, 8.0, 280.0, 0.7, 1.0};  // the window spans 6 to 10 A
  EXPECT_EQ(map.add(e), -1);
  EXPECT_EQ(map.transientEstimates(), 1u);
  e.operating_point = {0.0, 8.0, 280.0, 0.7, 0.05};
  EXPECT_EQ(map.add(e), 1);
  e.operating_point = {NAN, 8.0, 280.0, 0.7, 0.05};
  EXPECT_EQ(map.add(e), -1);
  ASSERT_EQ(map.cells().size(), 2u);
  EXPECT_EQ(map.cells()[0].estimates, 2u);
  EXPECT_NEAR(map.cells()[0].identified[kLq], 0.09, 0);
  EXPECT_THROW(MotorMap(MotorMapSettings{1.5}), ConfigError);
}
