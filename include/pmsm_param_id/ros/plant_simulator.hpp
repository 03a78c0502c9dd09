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
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

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
  /// Advertises the topics (run() does so itself). Before the first advance(), on the thread that
  /// loads the nodelets: advertising from the pacer's thread while other nodelets subscribe let
  /// roscpp link one subscriber to a publisher twice (an identifier received every batch twice in
  /// one of six 64-motor runs).
  void advertise();
  /// One step of the same for a pacer (the nodelet: PlantPacer runs every plant of its process):
  /// waits for the subscribers, then publishes the batches due by now. Returns the seconds until
  /// it has more to do, or a negative number once the scenario has ended (or stop() was called).
  /// Never throws: an error ends this plant with one message.
  double advance();
  void stop() { stop_ = true; }
  double linger() const { return linger_; }

 private:
  /// True once ~wait_for_subscribers listen (or 20 s passed: then with a warning).
  bool subscribersReady();
  void begin();
  /// Builds and publishes the next batch.
  void publishBatch();
  /// Wall time after the start when the next batch's last sample exists [s].
  double nextDue() const;
  void finish();
  /// advance() without its catch (run() lets an error end the node).
  double step();

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
};

/// Paces every PlantSimulator of one process (the plant nodelets of a manager) from one thread:
/// it sleeps until the earliest plant's next batch falls due and runs the batches due by then of
/// every plant. A fleet's plants then cost one wake-up per batch period between them, not a
/// timer, a queue dispatch and a worker's wake-up each (doc/performance.md, "Fleet").
class PlantPacer {
 public:
  /// The process's pacer, started by its first user and stopped when the last one lets it go.
  static std::shared_ptr<PlantPacer> shared();
  ~PlantPacer();
  /// Paces `plant` from now on, until its advance() says it has ended or remove() is called.
  void add(PlantSimulator* plant);
  /// Stops pacing `plant`; returns once no batch of it is being published.
  void remove(PlantSimulator* plant);

 private:
  PlantPacer();
  void loop();
  using Clock = std::chrono::steady_clock;
  struct Entry {
    PlantSimulator* plant;
    Clock::time_point due;
  };
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Entry> plants_;
  PlantSimulator* running_ = nullptr;  // the plant whose advance() runs (outside the lock)
  bool quit_ = false;
  std::thread thread_;
};

}  // namespace pmsm_param_id
