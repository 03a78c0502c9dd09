// plant_simulator node: runs a scenario of the core's DriveSimulator and publishes its samples.
//   ~scenario (string, required)   scenario YAML
//   ~duration (double, s)          override run.duration (<= 0: the file's)
//   ~seed (int)                    override run.seed (< 0: the file's)
//   ~realtime_factor (double)      1 = real time, 10 = ten times faster, 0 = as fast as possible
//   ~batch_size (int)              samples per DriveSampleBatch message
//   ~decimation (int)              every N-th sample also goes to ~samples (for humans, rostopic echo)
//   ~linger (double, s)            stay up this long after the last sample (subscribers drain)
//   ~wait_for_subscribers (int)    wait (at most 20 s) until this many nodes listen to samples_batch
//   ~publish_clock (bool)          own /clock: simulated time = 1 s + drive time, published per batch
//                                  (set /use_sim_time true for the other nodes)
// Publishes ~samples_batch (DriveSampleBatch), ~samples (DriveSample), ~true_parameters
// (ElectricalParameters, once per batch). Stamps start at the node's start time.
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>

#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/simulation/drive_simulator.hpp"
#include "ros_bridge.hpp"

using namespace pmsm_param_id;

int main(int argc, char** argv) {
  ros::init(argc, argv, "plant_simulator");
  ros::NodeHandle pnh("~");
  std::string path;
  double duration = 0, realtime = 1, linger = 1;
  int seed = -1, batch = 100, decimation = 100, wait_for = 0;
  bool publish_clock = false;
  try {
    path = typedParam<std::string>(pnh, "scenario", "");
    duration = typedParam<double>(pnh, "duration", 0.0);
    realtime = typedParam<double>(pnh, "realtime_factor", 1.0);
    linger = typedParam<double>(pnh, "linger", 1.0);
    seed = typedParam<int>(pnh, "seed", -1);
    batch = typedParam<int>(pnh, "batch_size", 100);
    decimation = typedParam<int>(pnh, "decimation", 100);
    wait_for = typedParam<int>(pnh, "wait_for_subscribers", 0);
    publish_clock = typedParam<bool>(pnh, "publish_clock", false);
  } catch (const ConfigError& e) {
    ROS_FATAL("%s", e.what());
    return 1;
  }
  if (path.empty()) {
    ROS_FATAL("parameter ~scenario: missing (path of a scenario YAML)");
    return 1;
  }
  if (batch < 1) { ROS_FATAL("parameter ~batch_size: must be >= 1"); return 1; }
  if (decimation < 1) { ROS_FATAL("parameter ~decimation: must be >= 1"); return 1; }
  if (realtime < 0) { ROS_FATAL("parameter ~realtime_factor: must be >= 0"); return 1; }
  Scenario scenario;
  try {
    scenario = loadScenario(path);
  } catch (const ConfigError& e) {
    ROS_FATAL("parameter ~scenario: %s", e.what());
    return 1;
  }
  if (duration > 0) scenario.duration = duration;
  if (seed >= 0) scenario.seed = static_cast<std::uint64_t>(seed);

  ros::Publisher pub_batch = pnh.advertise<DriveSampleBatch>("samples_batch", 1000);
  ros::Publisher pub_sample = pnh.advertise<DriveSample>("samples", 1000);
  ros::Publisher pub_truth = pnh.advertise<ElectricalParameters>("true_parameters", 100, true);
  ros::Publisher pub_clock;
  if (publish_clock) pub_clock = ros::NodeHandle().advertise<rosgraph_msgs::Clock>("/clock", 10);
  const ros::WallTime wait_start = ros::WallTime::now();
  while (ros::ok() && static_cast<int>(pub_batch.getNumSubscribers()) < wait_for &&
         (ros::WallTime::now() - wait_start).toSec() < 20.0)
    ros::WallDuration(0.05).sleep();
  if (static_cast<int>(pub_batch.getNumSubscribers()) < wait_for)
    ROS_WARN("only %u of %d subscribers after 20 s; starting anyway", pub_batch.getNumSubscribers(), wait_for);
  ros::WallDuration(0.5).sleep();  // let the remaining connections (estimates -> recorder) settle

  DriveSimulator sim(scenario);
  const double Ts = scenario.drive.sample_period;
  // Owning /clock, time starts at 1 s (ros::Time(0) means "unset" to many tools).
  const ros::Time start = publish_clock ? ros::Time(1.0) : ros::Time::now();
  const ros::WallTime wall_start = ros::WallTime::now();
  ROS_INFO("simulating '%s': %.3g s at T_s = %.3g s, batches of %d, real-time factor %g", scenario.name.c_str(),
           scenario.duration, Ts, batch, realtime);
  std::uint64_t published = 0;
  while (ros::ok() && !sim.done()) {
    DriveSampleBatch msg;
    std::vector<DriveSample> singles;  // the decimated per-sample topic, sent with the batch
    msg.sample_period = Ts;
    msg.first_index = sim.sampleIndex();
    ParameterVector truth{};
    double winding_temperature = NAN, magnet_temperature = NAN;
    for (int k = 0; k < batch && !sim.done(); ++k) {
      const SimulatedSample s = sim.step();
      if (k == 0) {
        msg.header.stamp = start + ros::Duration(static_cast<double>(msg.first_index) * Ts);
        truth = s.truth;
        winding_temperature = s.winding_temperature;
        magnet_temperature = s.magnet_temperature;
      }
      msg.u_d.push_back(s.sample.u_d);
      msg.u_q.push_back(s.sample.u_q);
      msg.i_d.push_back(s.sample.i_d);
      msg.i_q.push_back(s.sample.i_q);
      msg.omega_e.push_back(s.sample.omega_e);
      msg.theta_e.push_back(s.sample.theta_e);
      msg.v_dc.push_back(s.sample.v_dc);
      if ((msg.first_index + static_cast<std::uint64_t>(k)) % static_cast<std::uint64_t>(decimation) == 0) {
        DriveSample one;
        one.header.stamp = msg.header.stamp + ros::Duration(k * Ts);
        one.u_d = s.sample.u_d;
        one.u_q = s.sample.u_q;
        one.i_d = s.sample.i_d;
        one.i_q = s.sample.i_q;
        one.omega_e = s.sample.omega_e;
        one.theta_e = s.sample.theta_e;
        one.v_dc = s.sample.v_dc;
        singles.push_back(one);
      }
    }
    // Publish when the batch's last sample exists, as a real drive must: wait until wall time
    // reaches its stamp (scaled by the real-time factor).
    if (realtime > 0) {
      const double due = static_cast<double>(sim.sampleIndex() - 1) * Ts / realtime;
      const double ahead = due - (ros::WallTime::now() - wall_start).toSec();
      if (ahead > 0) ros::WallDuration(ahead).sleep();
    }
    published += msg.u_d.size();
    for (const DriveSample& one : singles) pub_sample.publish(one);
    pub_batch.publish(msg);
    pub_truth.publish(toMessage(truth, msg.header.stamp, winding_temperature, magnet_temperature));
    if (publish_clock) {
      rosgraph_msgs::Clock clock;
      clock.clock = start + ros::Duration(static_cast<double>(sim.sampleIndex()) * Ts);
      pub_clock.publish(clock);
    }
  }
  ROS_INFO("published %llu samples (%.3g s of drive time) in %.3g s of wall time",
           static_cast<unsigned long long>(published), static_cast<double>(published) * Ts,
           (ros::WallTime::now() - wall_start).toSec());
  pnh.setParam("samples_published", static_cast<int>(published));
  ros::WallDuration(linger).sleep();
  return 0;
}
