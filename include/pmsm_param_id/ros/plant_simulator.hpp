// PlantSimulator: runs a scenario of the core's DriveSimulator and publishes its samples (the
// plant_simulator node and the PlantSimulator nodelet). Parameters (private):
//   ~scenario (string, required)   scenario YAML
//   ~duration (double, s)          override run.duration (<= 0: the file's)
//   ~seed (int)                    override run.seed (< 0: the file's)
//   ~realtime_factor (double)      1 = real time, 10 = ten times faster, 0 = as fast as possible
//   ~batch_size (int)              samples per DriveSampleBatch message
//   ~decimation (int)              every N-th sample also goes to ~samples (for humans, rostopic echo)
//   ~linger (double, s)            the node stays up this long after the last sample (subscribers drain)
//   ~wait_for_subscribers (int)    wait (at most 20 s) until this many nodes listen to samples_batch
//   ~publish_clock (bool)          own /clock: simulated time = 1 s + drive time, published per batch
//                                  (set /use_sim_time true for the other nodes)
// Publishes ~samples_batch (DriveSampleBatch), ~samples (DriveSample), ~true_parameters
// (ElectricalParameters, once per batch). Stamps start at the node's start time. Messages go out as
// shared pointers: in a nodelet manager an identifier nodelet receives them without a copy.
#pragma once
#include <ros/ros.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "pmsm_param_id/simulation/drive_simulator.hpp"
#include "pmsm_param_id/simulation/scenario.hpp"

namespace pmsm_param_id {

class PlantSimulator {
 public:
  /// Reads the parameters and the scenario. Throws ConfigError (one line naming the parameter).
  explicit PlantSimulator(ros::NodeHandle pnh);
  /// Simulates and publishes until the scenario ends, ROS shuts down or stop() is called, sleeping
  /// between batches (the node); sets ~samples_published at the end. Returns the samples published.
  std::uint64_t run();
  /// The same driven by a wall timer on `nh`'s callback queue (the nodelet: no thread of its own;
  /// the manager's worker threads run every plant's batches as they fall due).
  void start(ros::NodeHandle nh);
  void stop() { stop_ = true; }
  double linger() const { return linger_; }

 private:
  void advertise();
  /// True once ~wait_for_subscribers listen (or 20 s passed: then with a warning).
  bool subscribersReady();
  void begin();
  /// Builds and publishes the next batch.
  void publishBatch();
  /// Wall time after the start when the next batch's last sample exists [s].
  double nextDue() const;
  void finish();
  void onTick(const ros::WallTimerEvent& event);
  void tick(const ros::WallTimerEvent&);

  ros::NodeHandle pnh_;
  Scenario scenario_;
  double realtime_ = 1.0, linger_ = 1.0;
  int batch_ = 100, decimation_ = 100, wait_for_ = 0;
  bool publish_clock_ = false;
  std::atomic<bool> stop_{false};
  ros::Publisher pub_batch_, pub_sample_, pub_truth_, pub_clock_;
  std::unique_ptr<DriveSimulator> sim_;
  ros::Time start_;
  ros::WallTime wait_start_, wall_start_, settle_until_;
  std::uint64_t published_ = 0;
  enum class Phase { Waiting, Settling, Running, Done } phase_ = Phase::Waiting;
  ros::WallTimer timer_;  // one-shot, armed for the next batch's due time
};

}  // namespace pmsm_param_id
