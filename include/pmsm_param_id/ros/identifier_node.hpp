// IdentifierNode: one ROS wrapper for every method of the core (the method is a parameter).
#pragma once
#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include <map>
#include <memory>
#include <string>

#include "pmsm_param_id/identification/monitor.hpp"
#include "pmsm_param_id/identification/motor_map.hpp"
#include "pmsm_param_id/identification/online_identifier.hpp"
#include "pmsm_param_id/identification/steady_state.hpp"
#include "pmsm_param_id/SetPublishPeriod.h"
#include "pmsm_param_id/ros/ros_bridge.hpp"

namespace pmsm_param_id {

class IdentifierNode {
 public:
  /// Reads parameters and subscribes. Throws ConfigError (one line naming the parameter).
  IdentifierNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  const OnlineIdentifier& identifier() const { return *identifier_; }

 private:
  void onBatch(const DriveSampleBatch::ConstPtr& msg);
  void onSample(const DriveSample::ConstPtr& msg);
  void consume(const Sample& s);
  /// Telemetry or the current loop's samples, from the first samples' spacing (~data: auto).
  void decideDataKind();
  void consumeCurrentLoop(const Sample& s);
  void consumeTelemetry(const Sample& s);
  /// The estimate of the path the data take.
  Estimate currentEstimate();
  void publish();
  void publishMap();
  void publishActiveAlarms(double t);
  /// The condition monitor on an estimate: its events published, the active alarms kept and published.
  void raiseAlarms(const Estimate& e);
  /// The condition monitor's history, its alarms and the map start again (a time reset, ~reset):
  /// estimates from before are not compared with those after.
  void restartHistory();
  /// Writes the learnt thermal references to thermal_state_ where they changed.
  void saveThermalState();
  void onTimer(const ros::WallTimerEvent&);
  /// ~reset: everything learnt from the stream goes (estimates, alarms, map, the data kind); the
  /// thermal references stay.
  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res);
  /// ~set_publish_period: ~publish_period while running.
  bool onSetPublishPeriod(SetPublishPeriod::Request& req, SetPublishPeriod::Response& res);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);

  ros::NodeHandle nh_, pnh_;
  IdentifierConfig config_;  // as validated at start (a reset builds the identifiers from it again)
  std::unique_ptr<OnlineIdentifier> identifier_;
  // ~data: the current loop's own samples (the identifier above), telemetry (the steady-state fit,
  // telemetry_), or undecided until kDecisionSamples samples show the spacing (held in pending_).
  enum class DataKind { Undecided, CurrentLoop, Telemetry };
  static constexpr std::size_t kDecisionSamples = 5;
  DataKind data_kind_ = DataKind::Undecided;
  DataKind configured_data_kind_ = DataKind::Undecided;  // ~data (Undecided: auto)
  std::vector<Sample> pending_;
  std::unique_ptr<TelemetryIdentifier> telemetry_;
  double telemetry_publish_period_ = 1.0;  // [s] of stamp time between steady-state fits
  ros::WallTime telemetry_fit_allowed_;     // the next fit no earlier (fits take at most a tenth of the wall time)
  StreamClock clock_;
  BatchTiming batch_timing_;
  ros::Subscriber sub_;
  ros::Publisher pub_estimate_;
  ros::Publisher pub_events_;
  ros::Publisher pub_active_;
  ros::Publisher pub_map_;
  MotorMap map_;
  double map_publish_period_ = 1.0;  // [s] of stamp time
  double next_map_publish_ = 0.0;
  std::string map_csv_;              // written with every map publication when set
  bool map_changed_ = false;
  ConditionMonitor monitor_;
  std::map<AlarmKind, AlarmEvent> active_alarms_;  // raised and not cleared, as raised
  std::string thermal_state_;                      // ~thermal_state: the file, or empty
  LearntReferences saved_references_;              // as last read or written
  ros::WallTimer timer_;
  ros::ServiceServer reset_service_, publish_period_service_;
  std::uint64_t resets_ = 0, history_restarts_ = 0;
  diagnostic_updater::Updater updater_;
  std::string frame_id_;
  double publish_period_ = 1e-2;   // [s] of stamp time
  double timeout_ = 1.0;           // [s] of wall time without samples -> WARN
  double bad_input_hold_ = 10.0;   // [s] of wall time a bad input keeps the diagnostics at WARN
  std::uint64_t bad_input_seen_ = 0;  // bad inputs counted at the last diagnosis
  ros::WallTime last_bad_input_;      // when the count last grew
  double next_publish_ = 0.0;
  double last_t_ = 0.0;
  bool unpublished_ = false;
  std::uint64_t received_ = 0, dropped_ = 0, bad_messages_ = 0, nonfinite_estimates_ = 0, published_ = 0;
  std::uint64_t expected_index_ = 0;
  bool have_index_ = false;
  ros::WallTime last_receive_;
  ros::WallTime rate_window_start_;
  std::uint64_t rate_window_count_ = 0;
  double rate_ = 0.0;
};

}  // namespace pmsm_param_id
