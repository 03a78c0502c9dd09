// The five online identifiers on simulated drives, observability flags and bad input.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <cmath>
#include <limits>

#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/identification/metrics.hpp"
#include "pmsm_param_id/identification/online_identifier.hpp"
#include "pmsm_param_id/identification/output_error.hpp"
#include "pmsm_param_id/io/sample_csv.hpp"
#include "test_helpers.hpp"

using namespace pmsm_param_id;

namespace {
// wc1 at 10 kHz without noise: the paper's condition at a real drive's rate.
std::vector<SimulatedSample> cleanDrive(const char* file = "wc1_drive.yaml", double duration = 0.3) {
  Scenario s = test_helpers::scenario(file);
  s.sensors = {};
  s.duration = duration;
  return test_helpers::run(s);
}
Estimate identify(const std::vector<SimulatedSample>& data, const std::string& method, std::uint64_t seed = 1,
                  IdentifierConfig c = {}) {
  c.method = method;
  c.seed = seed;
  auto id = makeIdentifier(c);
  for (const auto& s : data) id->process(s.sample);
  return id->estimate();
}
}  // namespace

struct MethodTolerance {
  const char* method;
  double tolerance_percent;  // every parameter, noise-free wc1 at 10 kHz
};
class EachMethod : public ::testing::TestWithParam<MethodTolerance> {};

TEST_P(EachMethod, RecoversTheParametersOfANoiseFreeRun) {
  static const auto data = cleanDrive();
  const auto [method, tol] = GetParam();
  const Estimate e = identify(data, method);
  EXPECT_EQ(e.method, method);
  for (int p = 0; p < kParameterCount; ++p)
    EXPECT_NEAR(errorPercent(e.parameters[p], data.back().truth[p]), 0.0, tol)
        << method << " " << parameterNames()[p] << " = " << e.parameters[p];
  EXPECT_EQ(e.counters.used, data.size());
  if (std::string(method) != "ekf") {
    for (int p = 0; p < kParameterCount; ++p) EXPECT_TRUE(e.identifiable[p]) << method << " " << e.reason[p];
  }
}
// Tolerances from this setup over seeds 1-30 (largest |error| of the four parameters, worst seed):
// FBDAPSO 0.069-0.088 %, SAPSO 0.24-0.32 % (its hot start of every cycle leaves the last cycle's
// best less refined), PSO 0.017 %, RLS 0.014 %, EKF 2.55 % (it keeps the paper's forward-Euler
// model, Eq. 11: its error at 10 kHz is the discretisation's). Ranges: two swarm engine versions.
INSTANTIATE_TEST_SUITE_P(Methods, EachMethod,
                         // the swarms' tolerances: the worst of seeds 1-30 (doc/algorithm.md section 1)
                         ::testing::Values(MethodTolerance{"fbdapso", 0.25}, MethodTolerance{"sapso", 0.7},
                                           MethodTolerance{"pso", 0.1}, MethodTolerance{"rls", 0.1},
                                           MethodTolerance{"ekf", 3.0}));

TEST(OnlineIdentifier, SameSeedSameResult) {
  const auto data = cleanDrive("wc1_drive.yaml", 0.1);
  const Estimate a = identify(data, "fbdapso", 5), b = identify(data, "fbdapso", 5);
  EXPECT_EQ(a.parameters, b.parameters);
  EXPECT_EQ(a.fitness, b.fitness);
}

TEST(OnlineIdentifier, LdIsFlaggedOnIdZeroDataOthersAreNot) {
  Scenario s = test_helpers::scenario("wc1_no_injection.yaml");
  s.drive.sample_period = 1e-4;
  s.drive.integration_substeps = 10;
  s.sensors.current_noise_sigma = 0.03;  // with noise-free data even the tiny i_d transients determine L_d
  const auto data = test_helpers::run(s);
  for (const char* m : {"fbdapso", "rls"}) {
    const Estimate e = identify(data, m);
    EXPECT_EQ(e.status[kLd], ParameterStatus::NotExcited) << m << " " << e.reason[kLd];
    EXPECT_TRUE(e.identifiable[kLq]) << m << " " << e.reason[kLq];
  }
  // With the injection the same data determine all four.
  const Estimate injected = identify(cleanDrive("wc1_drive.yaml", 0.5), "fbdapso");
  for (int p = 0; p < kParameterCount; ++p) EXPECT_TRUE(injected.identifiable[p]) << parameterNames()[p];
}

TEST(OnlineIdentifier, NonFiniteSampleIsSkippedAndCountedEstimateUnchanged) {
  const auto data = cleanDrive("wc1_drive.yaml", 0.1);
  IdentifierConfig c;
  auto id = makeIdentifier(c);
  for (std::size_t k = 0; k < 800; ++k) id->process(data[k].sample);
  const ParameterVector before = id->parameters();
  Sample bad = data[800].sample;
  bad.i_q = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(id->process(bad), SampleStatus::SkippedNonFinite);
  bad.i_q = data[800].sample.i_q;
  bad.u_d = std::numeric_limits<double>::infinity();
  EXPECT_EQ(id->process(bad), SampleStatus::SkippedNonFinite);
  EXPECT_EQ(id->parameters(), before);
  const Estimate e = id->estimate();
  EXPECT_EQ(e.counters.skipped_nonfinite, 2u);
  EXPECT_TRUE(std::isfinite(e.fitness));
  for (std::size_t k = 801; k < data.size(); ++k) EXPECT_EQ(id->process(data[k].sample), SampleStatus::Used);
}

TEST(OnlineIdentifier, TimeGoingBackwardsResetsCleanly) {
  const auto data = cleanDrive("wc1_drive.yaml", 0.1);
  IdentifierConfig c;
  auto fresh = makeIdentifier(c), looped = makeIdentifier(c);
  for (const auto& s : data) looped->process(s.sample);
  // The bag loops: the same samples again. After the reset it must behave like a fresh one.
  EXPECT_EQ(looped->process(data[0].sample), SampleStatus::TimeReset);
  fresh->process(data[0].sample);
  for (std::size_t k = 1; k < data.size(); ++k) {
    looped->process(data[k].sample);
    fresh->process(data[k].sample);
  }
  EXPECT_EQ(looped->parameters(), fresh->parameters());
  EXPECT_EQ(looped->counters().time_resets, 1u);
}

TEST(OnlineIdentifier, GapIsCountedAndDuplicateSkipped) {
  const auto data = cleanDrive("wc1_drive.yaml", 0.1);
  IdentifierConfig c;
  auto id = makeIdentifier(c);
  for (std::size_t k = 0; k < 300; ++k) id->process(data[k].sample);
  EXPECT_EQ(id->process(data[299].sample), SampleStatus::SkippedDuplicate);
  EXPECT_EQ(id->process(data[400].sample), SampleStatus::Gap);
  for (std::size_t k = 401; k < data.size(); ++k) id->process(data[k].sample);
  EXPECT_EQ(id->counters().gaps, 1u);
  EXPECT_EQ(id->counters().skipped_duplicate, 1u);
}

TEST(OnlineIdentifier, FollowsTheStatorResistanceRamp) {
  Scenario s = test_helpers::scenario("rs_drift.yaml");
  const auto data = test_helpers::run(s);
  IdentifierConfig c;
  auto id = makeIdentifier(c);
  double worst = 0;
  for (const auto& x : data) {
    id->process(x.sample);
    if (x.sample.t >= 1.2) worst = std::max(worst, std::abs(errorPercent(id->parameters()[kRs], x.truth[kRs])));
  }
  EXPECT_LT(worst, 1.0);
}

TEST(IdentifierConfig, BadValuesNameTheKey) {
  auto message = [](IdentifierConfig c) {
    try {
      validate(c, "cfg.yaml");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  IdentifierConfig c;
  c.method = "gradient";
  EXPECT_EQ(message(c), "cfg.yaml: key 'method': unknown method 'gradient' (expected fbdapso, sapso, pso, ekf, rls, wls)");
  c = {};
  c.search.fixed_bounds = true;
  c.search.lower = {1, 1e-3, 2e-3, 0.1};
  c.search.upper = {2, 2e-3, 2e-3, 0.2};
  EXPECT_EQ(message(c), "cfg.yaml: key 'bounds.L_q': lower bound must be < upper bound");
  c = {};
  c.swarm.particles = 1;
  EXPECT_EQ(message(c), "cfg.yaml: key 'swarm.particles': population must be >= 2");
  c = {};
  c.window.sensor_gains = true;
  EXPECT_EQ(message(c), "cfg.yaml: key 'current_sensors.gains': estimate needs current_sensors.offsets: estimate "
                        "(the same projection)");
  const std::string path = test_helpers::writeTemp(
      "bad_id.yaml", "bounds:\n  R_s: [3.0, 1.0]\n  L_d: [1e-3, 2e-3]\n  L_q: [1e-3, 2e-3]\n  psi_f: [0.1, 0.2]\n");
  try {
    loadIdentifierConfig(path);
    ADD_FAILURE();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), path + ": key 'bounds.R_s': lower bound must be < upper bound");
  }
  const std::string gain = test_helpers::writeTemp("bad_gain.yaml", "inverter:\n  shape_observer_gain: 2\n");
  try {
    loadIdentifierConfig(gain);
    ADD_FAILURE();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), gain + ": key 'inverter.shape_observer_gain': must be in [0, 1] (0 or 1 = the shape "
                                            "from the measured currents)");
  }
  EXPECT_NO_THROW(loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/default.yaml")));
}

TEST(IdentifierConfig, ADirectoryOrAListIsRefusedWithItsName) {
  const std::string list = test_helpers::writeTemp("list_root.yaml", "- method: pso\n- seed: 3\n");
  const auto message = [](const std::string& path) {
    try {
      loadIdentifierConfig(path);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message(list), list + ": expected a mapping of keys at the top level, got a list");
  const std::string dir = test_helpers::sourcePath("config/identifiers");
  EXPECT_EQ(message(dir), dir + ": is a directory, not a YAML file");
  EXPECT_EQ(message(dir + "/missing.yaml"), dir + "/missing.yaml: cannot open file");
  const std::string empty = test_helpers::writeTemp("empty.yaml", "");
  EXPECT_EQ(message(empty), "no error");  // every key at its default
}

TEST(SampleCsvReader, AByteOrderMarkBeforeTheHeaderIsNotPartOfItsFirstName) {
  const std::string path = test_helpers::writeTemp("bom.csv", "\xEF\xBB\xBFt,u_d,u_q,i_d,i_q,omega_e\n0,1,2,3,4,5\n1e-4,1,2,3,4,5\n");
  const SampleLog log = readSampleCsv(path);
  ASSERT_EQ(log.samples.size(), 2u);
  EXPECT_DOUBLE_EQ(log.samples[1].t, 1e-4);
  EXPECT_DOUBLE_EQ(log.samples[1].omega_e, 5.0);
}

TEST(SampleCsvReader, AFileWithoutLineBreaksIsRefusedWithoutReadingItWhole) {
  // 3 MiB of NULs (a binary file, a disk image): one clear message at the first MiB.
  const std::string path = test_helpers::writeTemp("nul.csv", std::string(3u << 20, '\0'));
  try {
    readSampleCsv(path);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), path + ":1: a line longer than 1 MiB: not a CSV drive log");
  }
  // A last line without a newline is read.
  const std::string last = test_helpers::writeTemp("last.csv", "t,u_d,u_q,i_d,i_q,omega_e\n0,1,2,3,4,5\n1e-4,1,2,3,4,6");
  const SampleLog log = readSampleCsv(last);
  ASSERT_EQ(log.samples.size(), 2u);
  EXPECT_DOUBLE_EQ(log.samples[1].omega_e, 6.0);
  EXPECT_EQ(log.line_numbers[1], 3u);
}

TEST(SampleCsvWriter, APipeOrDeviceIsWrittenInPlaceNotReplaced) {
  // `simulate --csv /dev/null` once put a regular file where /dev/null was (written to a temporary
  // name, then renamed over it). A FIFO stands in for the device: it must still be one afterwards,
  // and its reader gets the log.
  const std::string dir = test_helpers::writeTemp("fifo_dir_marker", "");
  const std::string path = dir + ".fifo";
  ::unlink(path.c_str());
  ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0) << std::strerror(errno);
  const int reader = ::open(path.c_str(), O_RDONLY | O_NONBLOCK);  // so that the writer's open does not wait
  ASSERT_GE(reader, 0);
  SimulatedSample x;
  x.sample = Sample{0.0, 1.0, 2.0, 3.0, 4.0, 5.0};
  writeSampleCsv(path, {x});
  struct stat st{};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode)) << "the FIFO was replaced";
  char buf[256] = {};
  const ssize_t n = ::read(reader, buf, sizeof buf - 1);
  ::close(reader);
  ::unlink(path.c_str());
  ASSERT_GT(n, 0);
  EXPECT_EQ(std::string(buf).rfind("t,u_d,u_q,i_d,i_q,omega_e", 0), 0u) << buf;
}

TEST(SampleCsvReader, MissingColumnAndNonNumericCellNameTheLine) {
  const std::string a = test_helpers::writeTemp("a.csv", "t,u_d,u_q,i_d,omega_e\n0,1,2,3,4\n");
  try {
    readSampleCsv(a);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), a + ":1: missing column 'i_q' for i_q (name the columns with --column or a --format file)");
  }
  const std::string b = test_helpers::writeTemp("b.csv", "t,u_d,u_q,i_d,i_q,omega_e\n0,1,2,3,4,5\n1e-4,1,2,x3,4,5\n");
  try {
    readSampleCsv(b);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), b + ":3: column 'i_d': not a number: 'x3'");
  }
  const std::string c = test_helpers::writeTemp("c.csv", "t,u_d,u_q,i_d,i_q,omega_e,extra\n0,1,2,nan,4,5,z\n1e-4,1,inf,3,4,5,z\n");
  const SampleLog log = readSampleCsv(c);  // extra columns ignored, non-finite kept for the identifier
  ASSERT_EQ(log.samples.size(), 2u);
  EXPECT_TRUE(std::isnan(log.samples[0].i_d));
  EXPECT_TRUE(std::isinf(log.samples[1].u_q));
  EXPECT_FALSE(log.has_truth);
}

TEST(Metrics, RecognitionTimeIsTheLastEntryIntoTheBand) {
  std::vector<TracePoint> trace;
  const ParameterVector truth{1, 1, 1, 1};
  for (int k = 0; k < 10; ++k) {
    ParameterVector e = truth;
    e[kRs] = k == 3 ? 1.02 : (k < 2 ? 1.5 : 1.005);
    e[kLd] = k == 6 ? 1.5 : 1.0;  // L_d leaves the band at k = 6 but is not selected
    trace.push_back({0.1 * k, e, truth});
  }
  EXPECT_DOUBLE_EQ(recognitionTime(trace, {true, false, true, true}), 0.4);
  EXPECT_DOUBLE_EQ(recognitionTime(trace, {true, true, true, true}), 0.7000000000000001);
  trace.back().estimate[kRs] = 2.0;
  EXPECT_TRUE(std::isnan(recognitionTime(trace, {true, false, false, false})));
}

// ---------------------------------------------------------------------------------------------
// The paper's output-error fitness (doc/algorithm.md section 10).

namespace {
// Currents produced by Eq. (11) itself (forward Euler) from the voltages and speed of a simulated
// drive: data on which the paper's adjustable model is exact, so its fitness is zero at the truth.
std::vector<Sample> eulerData(const ParameterVector& p, const std::vector<SimulatedSample>& drive) {
  std::vector<Sample> out;
  double id = drive.front().sample.i_d, iq = drive.front().sample.i_q;
  for (std::size_t k = 0; k < drive.size(); ++k) {
    Sample s = drive[k].sample;
    s.i_d = id;
    s.i_q = iq;
    out.push_back(s);
    if (k + 1 == drive.size()) break;
    const double T = drive[k + 1].sample.t - s.t;
    const double did = (s.u_d - p[kRs] * id + s.omega_e * p[kLq] * iq) / p[kLd];
    const double diq = (s.u_q - p[kRs] * iq - s.omega_e * (p[kLd] * id + p[kPsiF])) / p[kLq];
    id += T * did;
    iq += T * diq;
  }
  return out;
}
}  // namespace

TEST(PaperFitness, IsEquationElevenAndTwelve) {
  const auto drive = cleanDrive("wc1_drive.yaml", 0.1);
  const ParameterVector truth = drive.back().truth;
  const std::vector<Sample> data = eulerData(truth, drive);
  OutputErrorWindow window(FitnessKind::Paper, 300, 0);
  for (const Sample& s : data) window.push(s);
  ASSERT_TRUE(window.ready());
  EXPECT_LT(window(truth), 1e-20);  // the model reproduces its own currents
  // A 1 % error in L_d: the model's currents drift away over the window; the fitness is the mean
  // of the squared current error over the N - 1 predicted samples, recomputed here by hand.
  ParameterVector off = truth;
  off[kLd] *= 1.01;
  const std::vector<Sample> w = window.samples();
  ASSERT_EQ(w.size(), 300u);
  EXPECT_DOUBLE_EQ(w.back().t, data.back().t);
  double id = w[0].i_d, iq = w[0].i_q, sum = 0;
  for (std::size_t k = 0; k + 1 < w.size(); ++k) {
    const double T = w[k + 1].t - w[k].t;
    const double did = (w[k].u_d - off[kRs] * id + w[k].omega_e * off[kLq] * iq) / off[kLd];
    const double diq = (w[k].u_q - off[kRs] * iq - w[k].omega_e * (off[kLd] * id + off[kPsiF])) / off[kLq];
    id += T * did;
    iq += T * diq;
    sum += std::pow(w[k + 1].i_d - id, 2) + std::pow(w[k + 1].i_q - iq, 2);
  }
  EXPECT_GT(window(off), 1e-8);
  EXPECT_NEAR(window(off), sum / 299.0, 1e-12 * sum);
  // All particles at once give the same numbers as one at a time, for more than one chunk of 32.
  std::vector<ParameterVector> many(45, truth);
  for (std::size_t k = 0; k < many.size(); ++k) many[k][k % 4] *= 1.0 + 0.003 * static_cast<double>(k);
  std::vector<double> batch(many.size());
  window.batch(many.data(), many.size(), batch.data());
  for (std::size_t k = 0; k < many.size(); ++k) EXPECT_DOUBLE_EQ(batch[k], window(many[k])) << k;
  // A model that diverges is the worst fitness, never NaN (the swarm compares fitness values).
  ParameterVector unstable = truth;
  unstable[kLd] = 1e-9;
  EXPECT_EQ(window(unstable), 1e300);
  // One step (Eq. 13): the newest sample only.
  OutputErrorWindow one(FitnessKind::PaperOneStep, 300, 0);
  for (const Sample& s : data) one.push(s);
  EXPECT_EQ(one.samples().size(), 2u);
  EXPECT_LT(one(truth), 1e-24);
}

TEST(PaperFitness, DeclaredVoltageDelayShiftsTheActingVoltage) {
  OutputErrorWindow window(FitnessKind::Paper, 3, 1);
  for (int k = 0; k < 4; ++k) window.push(Sample{1e-4 * k, 10.0 * k, -10.0 * k, 0, 0, 0});
  const std::vector<Sample> w = window.samples();
  ASSERT_EQ(w.size(), 3u);
  EXPECT_DOUBLE_EQ(w[0].t, 1e-4);
  EXPECT_DOUBLE_EQ(w[0].u_d, 0.0);   // the voltage logged at t = 0 acts from t = 1e-4 on
  EXPECT_DOUBLE_EQ(w[2].u_q, -20.0);
  window.clear();                    // after a break the first voltage has no predecessor
  window.push(Sample{1.0, 5, 5, 0, 0, 0});
  EXPECT_EQ(window.size(), 0u);
}

// The swarms on the paper fitness find its optimum where the adjustable model is exact.
TEST(PaperFitness, SwarmFindsTheOptimumWhereTheModelIsExact) {
  const auto drive = cleanDrive("wc1_drive.yaml", 0.3);
  const ParameterVector truth = drive.back().truth;
  const std::vector<Sample> data = eulerData(truth, drive);
  // FBDAPSO over seeds 1-12 (a swarm held with L_d on the box's face, fitness 1.5 A^2, in 2 of
  // them while its cycle's kick there was the small interior one), PSO on the default seed.
  for (int seed = 1; seed <= 13; ++seed) {
    const char* method = seed <= 12 ? "fbdapso" : "pso";
    IdentifierConfig c;
    c.method = method;
    c.seed = seed <= 12 ? static_cast<std::uint64_t>(seed) : IdentifierConfig{}.seed;
    c.fitness = FitnessKind::Paper;
    auto id = makeIdentifier(c);
    for (const Sample& s : data) id->process(s);
    const Estimate e = id->estimate();
    const std::string label = std::string(method) + " seed " + std::to_string(c.seed);
    for (int p = 0; p < kParameterCount; ++p)
      EXPECT_NEAR(e.parameters[p] / truth[p], 1.0, 0.01) << label << " " << parameterNames()[p];
    // The paper fitness at the estimate, not the block fitness. Measured: PSO 2e-10 - 8e-9 A^2,
    // FBDAPSO 5e-9 - 1.6e-7 A^2 over seeds 1-12.
    EXPECT_LT(e.fitness, std::string(method) == "pso" ? 1e-7 : 1e-4) << label;
  }
}

TEST(IdentifierConfig, FitnessKindIsReadAndAnUnknownOneNamed) {
  const std::string good = test_helpers::writeTemp("paper_fitness.yaml", "fitness: paper\nfitness_window_samples: 500\n");
  const IdentifierConfig c = loadIdentifierConfig(good);
  EXPECT_EQ(c.fitness, FitnessKind::Paper);
  EXPECT_EQ(c.fitness_window_samples, 500);
  const std::string bad = test_helpers::writeTemp("bad_fitness.yaml", "fitness: papper\n");
  try {
    loadIdentifierConfig(bad);
    ADD_FAILURE();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), bad + ": key 'fitness': expected block, paper or paper_one_step, got 'papper'");
  }
}

// A saturated interior-PM machine at light, half and rated load: R_s absorbs the cross-saturation
// term omega L_dq (+32 / +66 / +133 %), psi_f stands for psi_d(0, i_q), L_q for psi_q / i_q, L_d for
// the incremental L_dd. Whatever is reported identified is within 2 % of the quantity it stands
// for; R_s never is (not_excited at light load, poor_fit above: doc/algorithm.md section 11).
TEST(Saturation, NoParameterIsConfidentlyWrongAtAnyLoad) {
  for (double load : {3.0, 6.0, 12.0}) {
    Scenario s = test_helpers::scenario("saturated_ipmsm.yaml");
    s.q_current_reference = Profile::constant(load);
    s.duration = 1.0;
    const auto data = test_helpers::run(s);
    for (const char* method : {"fbdapso", "rls"}) {
      const Estimate e = identify(data, method);
      EXPECT_FALSE(e.identifiable[kRs]) << load << " A " << method << ": R_s " << e.parameters[kRs];
      for (int p = 0; p < kParameterCount; ++p)
        if (e.identifiable[p]) {
          EXPECT_NEAR(e.parameters[p] / data.back().truth[p], 1.0, 0.02)
              << load << " A " << method << " " << parameterNames()[p];
        }
    }
  }
}

// The operating point travels with each estimate: the window's mean currents and speed.
TEST(Saturation, TheOperatingPointTravelsWithTheEstimate) {
  Scenario s = test_helpers::scenario("saturated_ipmsm.yaml");
  s.q_current_reference = Profile::constant(6.0);
  s.duration = 0.5;
  const auto data = test_helpers::run(s);
  const Estimate e = identify(data, "rls");
  EXPECT_NEAR(e.operating_point.i_q, 6.0, 0.05);
  EXPECT_NEAR(e.operating_point.i_d, 0.0, 0.1);  // a 1 A sine averages out over the window
  EXPECT_NEAR(e.operating_point.omega_e, 3 * 900.0 * 2 * M_PI / 60.0, 1e-6);
}

// Without the option the misfit is named (not a speed unit); with magnetics.cross_saturation the
// model fits, L_dq comes out of the q axis's response to the injection, and what is identified is
// within 2 % of the quantity it stands for (L_d incremental, L_q secant, psi_f = psi_d(0, i_q)).
TEST(Saturation, CrossSaturationIsNamedAndThenModelled) {
  for (double load : {6.0, 12.0}) {
    Scenario s = test_helpers::scenario("saturated_ipmsm.yaml");
    s.q_current_reference = Profile::constant(load);
    s.duration = 1.0;
    const auto data = test_helpers::run(s);
    const Estimate plain = identify(data, "wls");
    EXPECT_FALSE(plain.fit.consistent);
    EXPECT_NE(plain.fit.likely_cause.find("the machine saturates"), std::string::npos) << plain.fit.likely_cause;
    IdentifierConfig c;
    c.magnetics.cross_saturation = true;
    const Estimate e = identify(data, "wls", 1, c);
    EXPECT_TRUE(e.fit.consistent) << e.fit.likely_cause;
    EXPECT_NEAR(e.fit.L_dq / data.back().magnetics.L_dq, 1.0, 0.1) << load << " A";
    EXPECT_TRUE(e.identifiable[kLq]) << e.reason[kLq];
    // L_d: identified, or just short of the 1 % (the extended model's lines in i_q cost it some
    // certainty at this 1 A injection: measured +-1.0 % at 6 and 12 A), never a poor fit.
    EXPECT_TRUE(e.identifiable[kLd] || (e.status[kLd] == ParameterStatus::NotExcited && e.relative_uncertainty[kLd] < 0.015))
        << e.reason[kLd];
    for (int p = 0; p < kParameterCount; ++p)
      if (e.identifiable[p]) {
        EXPECT_NEAR(e.parameters[p] / data.back().truth[p], 1.0, 0.02) << load << " A " << parameterNames()[p];
      }
    for (const char* method : {"fbdapso", "rls", "ekf"}) {  // the others: nothing confidently wrong
      const Estimate m = identify(data, method, 1, c);
      for (int p = 0; p < kParameterCount; ++p)
        if (m.identifiable[p]) {
          EXPECT_NEAR(m.parameters[p] / data.back().truth[p], 1.0, 0.02) << load << " A " << method << " "
                                                                           << parameterNames()[p];
        }
    }
  }
}

// Under a speed loop the injection's torque ripple moves i_q, and on a saturating machine
// psi_q(0, i_q) and psi_d(0, i_q) then move along their slopes L_qq and L_dq: the extended model's
// lines in i_q (section 11). Before them every fit here was poor (the exact fit ran off to
// L_qq = 3e10 H); now L_q and psi_f are identified within 2 % of what they stand for, and nothing
// identified is wrong.
TEST(Saturation, UnderASpeedLoopTheLinesInIqKeepTheEstimatesRight) {
  Scenario s = test_helpers::scenario("saturated_map.yaml");
  s.drive.torque_control = false;          // the speed loop holds 900 rpm against the load
  s.load_torque = Profile::constant(10.0);  // [N m]: i_q about 4.5 A
  s.duration = 1.5;
  const auto data = test_helpers::run(s);
  double spread = 0.0;  // the speed loop does move i_q
  for (std::size_t k = data.size() / 2; k < data.size(); ++k)
    spread = std::max(spread, std::abs(data[k].i_q_true - data.back().i_q_true));
  EXPECT_GT(spread, 0.05);
  IdentifierConfig c;
  c.magnetics.cross_saturation = true;
  const Estimate e = identify(data, "wls", 1, c);
  EXPECT_TRUE(e.fit.consistent) << e.fit.likely_cause;
  EXPECT_NEAR(e.fit.L_qq / data.back().magnetics.L_qq, 1.0, 0.15);
  EXPECT_TRUE(e.identifiable[kLq] && e.identifiable[kPsiF]) << e.reason[kLq] << " / " << e.reason[kPsiF];
  for (const char* method : {"wls", "fbdapso", "rls"}) {
    const Estimate m = identify(data, method, 1, c);
    for (int p = 0; p < kParameterCount; ++p) {
      if (!m.identifiable[p]) continue;
      EXPECT_NEAR(m.parameters[p] / data.back().truth[p], 1.0, 0.02) << method << " " << parameterNames()[p];
    }
  }
}

TEST(Assessment, ZeroCurrentIsNotExcitedNotImplausible) {
  // A motor at standstill with the inverter on: voltages, no current, no speed. Nothing can be
  // identified, and the method never starts (the data never fix the scale): every parameter is
  // not_excited with the reason, not "nan is outside every PMSM's range".
  std::vector<Sample> samples;
  for (int k = 0; k < 5000; ++k) samples.push_back(Sample{k * 1e-4, 1.0, 2.0, 0.0, 0.0, 0.0});
  for (const char* method : {"fbdapso", "rls"}) {
    IdentifierConfig c;
    c.method = method;
    auto id = makeIdentifier(c);
    for (const Sample& s : samples) id->process(s);
    const Estimate e = id->estimate();
    for (int p = 0; p < kParameterCount; ++p) {
      EXPECT_EQ(e.status[p], ParameterStatus::NotExcited) << method << " " << parameterNames()[p] << ": " << e.reason[p];
      EXPECT_NE(e.reason[p].find("do not fix the motor's scale"), std::string::npos) << e.reason[p];
      EXPECT_FALSE(e.identifiable[p]);
    }
  }
}
