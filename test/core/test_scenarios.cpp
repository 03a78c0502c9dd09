// Scenario files: every shipped one loads; bad ones stop with one line naming file and key.
#include <gtest/gtest.h>

#include <cstdio>
#include <dirent.h>
#include <fstream>

#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/io/sample_csv.hpp"
#include "test_helpers.hpp"

using namespace pmsm_param_id;

TEST(Scenarios, EveryShippedScenarioLoads) {
  const std::string dir = test_helpers::sourcePath("config/scenarios");
  DIR* d = opendir(dir.c_str());
  ASSERT_NE(d, nullptr);
  int n = 0;
  while (dirent* e = readdir(d)) {
    const std::string name = e->d_name;
    if (name.size() < 5 || name.substr(name.size() - 5) != ".yaml") continue;
    EXPECT_NO_THROW(loadScenario(dir + "/" + name)) << name;
    ++n;
  }
  closedir(d);
  EXPECT_GE(n, 6);
  const Scenario wc2 = test_helpers::scenario("wc2.yaml");
  EXPECT_DOUBLE_EQ(wc2.motor.L_q, 0.0135);
  EXPECT_DOUBLE_EQ(wc2.drive.sample_period, 1e-6);
  EXPECT_DOUBLE_EQ(wc2.speed_reference_rpm(1.0), 1200.0);
  EXPECT_DOUBLE_EQ(wc2.load_torque(0.3), 20.0);
  const Scenario drive = test_helpers::scenario("wc1_drive.yaml");
  EXPECT_DOUBLE_EQ(drive.sensors.current_noise_sigma, 0.03);
  EXPECT_EQ(drive.sensors.adc_bits, 12);
}

namespace {
std::string base() {
  std::ifstream in(test_helpers::sourcePath("config/scenarios/wc1_drive.yaml"));
  return std::string(std::istreambuf_iterator<char>(in), {});
}
std::string replaceLine(std::string text, const std::string& starts, const std::string& with) {
  const auto p = text.find(starts);
  EXPECT_NE(p, std::string::npos) << starts;
  const auto e = text.find('\n', p);
  return text.replace(p, e - p, with);
}
std::string errorOf(const std::string& text) {
  const std::string path = test_helpers::writeTemp("bad_scenario.yaml", text);
  try {
    loadScenario(path);
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
    EXPECT_EQ(msg.rfind(path, 0), 0u) << "names the file: " << msg;
    return msg;
  }
  ADD_FAILURE() << "no error for bad scenario";
  return "";
}
}  // namespace

TEST(Scenarios, MissingKeyIsNamed) {
  const std::string msg = errorOf(replaceLine(base(), "  L_d:", ""));
  EXPECT_NE(msg.find("key 'motor.L_d': missing"), std::string::npos) << msg;
}
TEST(Scenarios, NegativeInductanceIsRefused) {
  const std::string msg = errorOf(replaceLine(base(), "  L_q:", "  L_q: -0.0135"));
  EXPECT_NE(msg.find("key 'motor.L_q': must be > 0"), std::string::npos) << msg;
}
TEST(Scenarios, NonPositiveSamplePeriodIsRefused) {
  const std::string msg = errorOf(replaceLine(base(), "  sample_period:", "  sample_period: 0"));
  EXPECT_NE(msg.find("key 'drive.sample_period': must be > 0"), std::string::npos) << msg;
}
TEST(Scenarios, UnknownProfileTypeIsRefused) {
  const std::string msg =
      errorOf(replaceLine(base(), "  load_torque:", "  load_torque: {type: wobble, value: 3}"));
  EXPECT_NE(msg.find("key 'profiles.load_torque.type': unknown profile type 'wobble'"), std::string::npos) << msg;
}
TEST(Scenarios, NonNumericTextIsRefused) {
  const std::string msg = errorOf(replaceLine(base(), "  R_s:", "  R_s: three ohms"));
  EXPECT_NE(msg.find("key 'motor.R_s': expected a number, got 'three ohms'"), std::string::npos) << msg;
}
TEST(Scenarios, UnreadableYamlIsOneLine) {
  const std::string msg = errorOf("motor: [unclosed\n");
  EXPECT_NE(msg.find("not valid YAML"), std::string::npos) << msg;
}

TEST(SampleCsv, RoundTripIsExactAndWriteIsAllOrNothing) {
  Scenario s = test_helpers::scenario("wc1_drive.yaml");
  s.duration = 0.01;
  const auto data = test_helpers::run(s);
  const std::string path = ::testing::TempDir() + "roundtrip.csv";
  writeSampleCsv(path, data);
  const SampleLog log = readSampleCsv(path);
  ASSERT_EQ(log.samples.size(), data.size());
  ASSERT_TRUE(log.has_truth);
  for (std::size_t k = 0; k < data.size(); ++k) {
    EXPECT_EQ(log.samples[k].u_q, data[k].sample.u_q);
    EXPECT_EQ(log.samples[k].i_d, data[k].sample.i_d);
    EXPECT_EQ(log.truth[k][kRs], data[k].truth[kRs]);
  }
  EXPECT_EQ(log.line_numbers[0], 2u);
  const std::string bad = ::testing::TempDir() + "no_such_dir/out.csv";
  EXPECT_THROW(writeSampleCsv(bad, data), std::runtime_error);
  EXPECT_FALSE(std::ifstream(bad).good());
}
