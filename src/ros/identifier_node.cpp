#include "pmsm_param_id/ros/identifier_node.hpp"

#include <cmath>

#include "pmsm_param_id/ActiveAlarms.h"
#include "pmsm_param_id/ConditionEvent.h"
#include "pmsm_param_id/io/thermal_state.hpp"
#include "pmsm_param_id/io/config_error.hpp"

namespace pmsm_param_id {

IdentifierNode::IdentifierNode(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh), pnh_(pnh), updater_(nh, pnh) {
  const std::string config_path = typedParam<std::string>(pnh_, "config", "");
  IdentifierConfig config = config_path.empty() ? IdentifierConfig{} : loadIdentifierConfig(config_path);
  config.method = typedParam<std::string>(pnh_, "method", config.method);
  const int seed = typedParam<int>(pnh_, "seed", -1);
  if (pnh_.hasParam("seed")) {
    if (seed < 0) throw ConfigError("parameter ~seed: must be >= 0");
    config.seed = static_cast<std::uint64_t>(seed);
  }
  if (!isKnownMethod(config.method))
    throw ConfigError("parameter ~method: unknown method '" + config.method + "' (expected " + methodList() + ")");
  if (pnh_.hasParam("pole_pairs")) {
    const int pole_pairs = typedParam<int>(pnh_, "pole_pairs", 0);
    if (pole_pairs < 0) throw ConfigError("parameter ~pole_pairs: must be >= 0 (0 = unknown)");
    config.pole_pairs = pole_pairs;
  }
  validate(config, config_path.empty() ? "parameters" : config_path);
  thermal_state_ = typedParam<std::string>(pnh_, "thermal_state", "");
  if (!thermal_state_.empty() && !config.thermal.enabled)
    throw ConfigError("parameter ~thermal_state: needs a thermal: block in the identifier config (~config)");
  publish_period_ = typedParam<double>(pnh_, "publish_period", 1e-2);
  if (!(publish_period_ > 0)) throw ConfigError("parameter ~publish_period: must be > 0 [s]");
  timeout_ = typedParam<double>(pnh_, "timeout", 1.0);
  if (!(timeout_ > 0)) throw ConfigError("parameter ~timeout: must be > 0 [s]");
  frame_id_ = typedParam<std::string>(pnh_, "frame_id", "");
  bad_input_hold_ = typedParam<double>(pnh_, "bad_input_hold", 10.0);
  if (!(bad_input_hold_ >= 0)) throw ConfigError("parameter ~bad_input_hold: must be >= 0 [s]");
  const std::string data = typedParam<std::string>(pnh_, "data", "auto");
  if (data == "current_loop") data_kind_ = DataKind::CurrentLoop;
  else if (data == "telemetry") data_kind_ = DataKind::Telemetry;
  else if (data != "auto")
    throw ConfigError("parameter ~data: must be 'auto', 'current_loop' or 'telemetry', got '" + data + "'");
  telemetry_publish_period_ = typedParam<double>(pnh_, "telemetry_publish_period", 1.0);
  if (!(telemetry_publish_period_ > 0)) throw ConfigError("parameter ~telemetry_publish_period: must be > 0 [s]");
  const int telemetry_max_samples =
      typedParam<int>(pnh_, "telemetry_max_samples", static_cast<int>(TelemetryIdentifier::kDefaultMaxSamples));
  const std::string input = typedParam<std::string>(pnh_, "input", "batch");
  if (input != "batch" && input != "single")
    throw ConfigError("parameter ~input: must be 'batch' or 'single', got '" + input + "'");

  map_publish_period_ = typedParam<double>(pnh_, "map_publish_period", 1.0);
  if (!(map_publish_period_ > 0)) throw ConfigError("parameter ~map_publish_period: must be > 0 [s]");
  map_csv_ = typedParam<std::string>(pnh_, "map_csv", "");

  config_ = config;
  configured_data_kind_ = data_kind_;
  identifier_ = makeIdentifier(config);
  if (telemetry_max_samples < 12) throw ConfigError("parameter ~telemetry_max_samples: must be >= 12 (the fit's minimum)");
  telemetry_ = std::make_unique<TelemetryIdentifier>(config, static_cast<std::size_t>(telemetry_max_samples));
  saved_references_ = loadThermalStateFor(thermal_state_, config.thermal.reference_temperature);
  if (saved_references_.any()) {
    identifier_->restoreReferences(saved_references_);
    ROS_INFO("thermal references from %s (R_s %.6g ohm, psi_f %.6g Wb at %.4g degC): not learnt again",
             thermal_state_.c_str(), saved_references_.R_s, saved_references_.psi_f, saved_references_.reference_temperature);
  }
  monitor_ = ConditionMonitor::forConfig(config);
  map_ = MotorMap(config.map);
  pub_map_ = pnh_.advertise<ParameterMap>("map", 1, true);
  pub_estimate_ = pnh_.advertise<ParameterEstimate>("estimate", 1000);
  pub_events_ = pnh_.advertise<ConditionEvent>("events", 100, true);
  pub_active_ = pnh_.advertise<ActiveAlarms>("active_alarms", 1, true);
  publishActiveAlarms(0.0);
  const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
  if (input == "batch")
    sub_ = nh_.subscribe("samples_batch", 1000, &IdentifierNode::onBatch, this, hints);
  else
    sub_ = nh_.subscribe("samples", 100000, &IdentifierNode::onSample, this, hints);
  updater_.setHardwareID("pmsm_param_id/" + config.method);
  updater_.add("identifier", this, &IdentifierNode::diagnose);
  last_receive_ = rate_window_start_ = ros::WallTime::now();
  timer_ = nh_.createWallTimer(ros::WallDuration(0.1), &IdentifierNode::onTimer, this);
  reset_service_ = pnh_.advertiseService("reset", &IdentifierNode::onReset, this);
  publish_period_service_ = pnh_.advertiseService("set_publish_period", &IdentifierNode::onSetPublishPeriod, this);
  ROS_INFO("identifier '%s' listening on %s (%s, data: %s), publishing %s every %g s of stamp time (telemetry: every %g s)",
           config.method.c_str(), sub_.getTopic().c_str(), input.c_str(), data.c_str(), pub_estimate_.getTopic().c_str(),
           publish_period_, std::max(publish_period_, telemetry_publish_period_));
}

void IdentifierNode::onBatch(const DriveSampleBatch::ConstPtr& msg) {
  const std::string problem = checkBatch(*msg);
  if (!problem.empty()) {
    ++bad_messages_;
    ROS_WARN_THROTTLE(1.0, "dropping a malformed sample batch: %s", problem.c_str());
    return;
  }
  if (have_index_ && msg->first_index > expected_index_) {
    dropped_ += msg->first_index - expected_index_;
    ROS_WARN_THROTTLE(1.0, "%llu samples lost before index %llu",
                      static_cast<unsigned long long>(msg->first_index - expected_index_),
                      static_cast<unsigned long long>(msg->first_index));
  }
  expected_index_ = msg->first_index + msg->u_d.size();
  have_index_ = true;
  try {
    // The samples' times from the stream's index where the batch continues it (stamp jitter).
    const BatchTiming::Start start = batch_timing_.start(clock_, *msg);
    for (std::size_t k = 0; k < msg->u_d.size(); ++k)
      consume(toSample(*msg, k, clock_.seconds(start.anchor, start.offset + k, msg->sample_period)));
  } catch (const std::exception& e) {  // whatever it is, one message's problem never ends the node
    ++bad_messages_;
    ROS_ERROR_THROTTLE(1.0, "dropping the rest of a sample batch: %s", e.what());
  }
}

void IdentifierNode::onSample(const DriveSample::ConstPtr& msg) {
  try {
    consume(toSample(*msg, clock_.seconds(msg->header.stamp)));
  } catch (const std::exception& e) {
    ++bad_messages_;
    ROS_ERROR_THROTTLE(1.0, "dropping a sample: %s", e.what());
  }
}

void IdentifierNode::consume(const Sample& s) {
  ++received_;
  ++rate_window_count_;
  last_receive_ = ros::WallTime::now();
  switch (data_kind_) {
    case DataKind::Undecided:
      pending_.push_back(s);
      if (pending_.size() >= kDecisionSamples) decideDataKind();
      return;
    case DataKind::CurrentLoop:
      consumeCurrentLoop(s);
      return;
    case DataKind::Telemetry:
      consumeTelemetry(s);
      return;
  }
}

void IdentifierNode::decideDataKind() {
  // As identify --data auto: a median spacing slower than any current loop is telemetry.
  const double T = medianSpacing(pending_);
  data_kind_ = T > kTelemetryPeriod ? DataKind::Telemetry : DataKind::CurrentLoop;
  if (data_kind_ == DataKind::Telemetry)
    ROS_INFO("samples every %.3g s, slower than any current loop: telemetry, the steady-state fit "
             "(set ~data: current_loop if the stamps are wrong instead)", T);
  std::vector<Sample> held;
  held.swap(pending_);
  for (const Sample& h : held) {
    if (data_kind_ == DataKind::Telemetry) consumeTelemetry(h);
    else consumeCurrentLoop(h);
  }
}

void IdentifierNode::consumeTelemetry(const Sample& s) {
  switch (telemetry_->process(s)) {
    case SampleStatus::TimeReset:
      ROS_WARN("stamps went backwards (a looping bag?): the steady-state fit starts again from this sample");
      next_publish_ = 0.0;
      restartHistory();
      break;
    case SampleStatus::SkippedNonFinite:
      ROS_WARN_THROTTLE(1.0, "a sample with a NaN or inf value: left out of the fit");
      return;
    default:
      break;
  }
  last_t_ = s.t;
  unpublished_ = true;
  const double period = std::max(publish_period_, telemetry_publish_period_);
  if (s.t + 1e-12 >= next_publish_ && ros::WallTime::now() >= telemetry_fit_allowed_) {
    publish();
    next_publish_ = (std::floor(s.t / period + 1e-9) + 1.0) * period;
  }
}

Estimate IdentifierNode::currentEstimate() {
  return data_kind_ == DataKind::Telemetry ? telemetry_->estimate() : identifier_->estimate();
}

void IdentifierNode::consumeCurrentLoop(const Sample& s) {
  const SampleStatus status = identifier_->process(s);
  switch (status) {
    case SampleStatus::TimeReset:
      ROS_WARN("stamps went backwards (a looping bag?): the identifier, the monitor and the map restarted");
      next_publish_ = 0.0;
      restartHistory();
      break;
    case SampleStatus::Gap:
      ROS_WARN_THROTTLE(1.0, "gap in the sample stream at stamp %.6f s: fitness blocks restarted",
                        clock_.stampOf(s.t).toSec());
      break;
    case SampleStatus::SkippedNonFinite:
      ROS_WARN_THROTTLE(1.0, "skipping a sample with a NaN or inf value (%llu so far)",
                        static_cast<unsigned long long>(identifier_->counters().skipped_nonfinite));
      return;
    case SampleStatus::SkippedDuplicate:
      return;
    case SampleStatus::SkippedTooClose:  // not used: the stream's time stays at the last used sample
      ROS_WARN_THROTTLE(1.0, "skipping a sample stamped less than a quarter period after the previous one (%llu so far)",
                        static_cast<unsigned long long>(identifier_->counters().skipped_too_close));
      return;
    case SampleStatus::PeriodChanged:
      ROS_WARN("the sampling period changed at stamp %.6f s (now %.4g s): statistics restarted at the new rate",
               clock_.stampOf(s.t).toSec(),
               identifier_->samplePeriod());
      break;
    case SampleStatus::Used:
      break;
  }
  last_t_ = s.t;
  unpublished_ = true;
  if (s.t + 1e-12 >= next_publish_) {
    publish();
    next_publish_ = (std::floor(s.t / publish_period_ + 1e-9) + 1.0) * publish_period_;
  }
}

void IdentifierNode::publish() {
  const ros::WallTime fit_start = ros::WallTime::now();
  const Estimate e = currentEstimate();
  if (data_kind_ == DataKind::Telemetry) {  // the steady-state fit: at most a tenth of the wall time
    const ros::WallDuration took = ros::WallTime::now() - fit_start;
    telemetry_fit_allowed_ = ros::WallTime::now() + ros::WallDuration(9.0 * took.toSec());
    if (took.toSec() > 0.1 * telemetry_publish_period_)
      ROS_INFO_THROTTLE(60.0, "the steady-state fit of %zu samples took %.2g s: refitted at most every %.2g s of wall time",
                        telemetry_->size(), took.toSec(), 10.0 * took.toSec());
  }
  unpublished_ = false;
  for (double v : e.parameters)
    if (!std::isfinite(v)) {  // before the data fix the motor's scale there is no estimate to publish
      ++nonfinite_estimates_;
      ROS_INFO_THROTTLE(5.0, "no estimate yet: %s", e.reason[kLq].c_str());
      return;
    }
  pub_estimate_.publish(toMessage(e, clock_.stampOf(last_t_), frame_id_));
  ++published_;
  if (data_kind_ == DataKind::Telemetry) {
    // Telemetry's fit covers the whole stream, not one operating point's recent state: no map, and
    // of the alarms only the temperatures' (a winding over its limit, a magnet reading hotter than
    // the winding by more than heat explains); parameter jumps and drift are judged on the current
    // loop's estimates only.
    Estimate temperatures = e;
    temperatures.identifiable.fill(false);
    raiseAlarms(temperatures);
    return;
  }
  map_changed_ |= map_.add(e) >= 0;
  if (last_t_ + 1e-12 >= next_map_publish_) {
    publishMap();
    next_map_publish_ = (std::floor(last_t_ / map_publish_period_ + 1e-9) + 1.0) * map_publish_period_;
  }
  raiseAlarms(e);
  saveThermalState();
}

void IdentifierNode::raiseAlarms(const Estimate& e) {
  for (const AlarmEvent& ev : monitor_.update(e)) {  // alarms only from identified parameters
    ConditionEvent m;
    m.header.stamp = clock_.stampOf(ev.t);
    m.header.frame_id = frame_id_;
    m.method = e.method;
    m.kind = toString(ev.kind);
    m.raised = ev.raised;
    m.text = ev.text;
    pub_events_.publish(m);
    if (ev.raised) ROS_ERROR("alarm %s: %s", m.kind.c_str(), ev.text.c_str());
    else ROS_INFO("alarm %s cleared", m.kind.c_str());
    if (ev.raised) active_alarms_[ev.kind] = ev;
    else active_alarms_.erase(ev.kind);
    publishActiveAlarms(ev.t);
  }
}

void IdentifierNode::publishActiveAlarms(double t) {
  ActiveAlarms m;
  m.header.stamp = t > 0 ? clock_.stampOf(t) : ros::Time(0);
  m.header.frame_id = frame_id_;
  m.method = identifier_->method();
  for (const auto& [kind, ev] : active_alarms_) {
    ConditionEvent c;
    c.header.stamp = clock_.stampOf(ev.t);
    c.header.frame_id = frame_id_;
    c.method = m.method;
    c.kind = toString(kind);
    c.raised = true;
    c.text = ev.text;
    m.active.push_back(c);
  }
  pub_active_.publish(m);
}

void IdentifierNode::saveThermalState() {
  if (thermal_state_.empty()) return;
  const LearntReferences now = identifier_->learntReferences();
  if (!now.any() || now == saved_references_) return;
  try {
    writeThermalState(thermal_state_, now, identifier_->method());
    saved_references_ = now;
    ROS_INFO("thermal references learnt and written to %s (R_s %.6g ohm, psi_f %.6g Wb at %.4g degC)",
             thermal_state_.c_str(), now.R_s, now.psi_f, now.reference_temperature);
  } catch (const UserError& e) {
    ROS_WARN_THROTTLE(10.0, "%s", e.what());
  }
}

void IdentifierNode::publishMap() {
  if (!map_changed_) return;
  map_changed_ = false;
  pub_map_.publish(toMessage(map_, identifier_->method(), clock_, last_t_, frame_id_));
  if (map_csv_.empty()) return;
  FluxTable table;
  try {
    table = map_.fluxTable();
  } catch (const UserError& e) {  // no cell has all three identified yet
    ROS_INFO_THROTTLE(10.0, "map not written to %s yet: %s", map_csv_.c_str(), e.what());
    return;
  }
  const std::string note = map_.coverageNote();
  try {
    writeFluxTable(table, map_csv_,
                   "flux map learnt by the " + identifier_->method() + " identifier (doc/algorithm.md section 12)" +
                       (note.empty() ? "" : "; " + note));
  } catch (const UserError& e) {
    ROS_WARN_THROTTLE(10.0, "%s", e.what());
    return;
  }
  if (!note.empty()) ROS_WARN_THROTTLE(10.0, "map %s: %s", map_csv_.c_str(), note.c_str());
}

void IdentifierNode::onTimer(const ros::WallTimerEvent&) {
  // A stream that paused before its spacing was clear: decided from what came.
  if (data_kind_ == DataKind::Undecided && pending_.size() >= 2 && (ros::WallTime::now() - last_receive_).toSec() > 0.2) {
    try {
      decideDataKind();
    } catch (const std::exception& e) {
      ++bad_messages_;
      ROS_ERROR_THROTTLE(1.0, "dropping held samples: %s", e.what());
    }
  }
  // The stream paused or ended: publish the state after the last sample once, and the map.
  if (unpublished_ && (ros::WallTime::now() - last_receive_).toSec() > 0.2) {
    try {
      publish();
      publishMap();
    } catch (const std::exception& e) {  // never out of a callback: in a nodelet manager it ends every motor
      unpublished_ = false;
      ROS_ERROR_THROTTLE(1.0, "no estimate published: %s", e.what());
    }
  }
  const double window = (ros::WallTime::now() - rate_window_start_).toSec();
  if (window >= 1.0) {
    rate_ = static_cast<double>(rate_window_count_) / window;
    rate_window_count_ = 0;
    rate_window_start_ = ros::WallTime::now();
  }
  updater_.update();
}

void IdentifierNode::restartHistory() {
  monitor_ = ConditionMonitor::forConfig(config_);
  active_alarms_.clear();
  map_ = MotorMap(config_.map);
  map_changed_ = false;
  next_map_publish_ = 0.0;
  ++history_restarts_;
  publishActiveAlarms(0.0);
}

bool IdentifierNode::onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  identifier_ = makeIdentifier(config_);
  if (saved_references_.any()) identifier_->restoreReferences(saved_references_);
  telemetry_->reset();
  data_kind_ = configured_data_kind_;
  pending_.clear();
  restartHistory();
  clock_.reset();
  batch_timing_.reset();
  next_publish_ = next_map_publish_ = last_t_ = 0.0;
  unpublished_ = false;
  have_index_ = false;
  ++resets_;
  res.success = true;
  res.message = "reset: the estimates, alarms, map and data kind start again from the next sample" +
                std::string(saved_references_.any() ? " (the thermal references stay)" : "");
  ROS_INFO("%s", res.message.c_str());
  return true;
}

bool IdentifierNode::onSetPublishPeriod(SetPublishPeriod::Request& req, SetPublishPeriod::Response& res) {
  if (!(std::isfinite(req.publish_period) && req.publish_period > 0)) {
    res.success = false;
    res.message = "publish_period must be > 0 and finite [s], got " + std::to_string(req.publish_period) +
                  "; kept " + std::to_string(publish_period_);
    ROS_WARN("%s", res.message.c_str());
    return true;
  }
  publish_period_ = req.publish_period;
  next_publish_ = (std::floor(last_t_ / publish_period_ + 1e-9) + 1.0) * publish_period_;
  pnh_.setParam("publish_period", publish_period_);
  char buf[160];
  std::snprintf(buf, sizeof buf, "publish_period %g s (of stamp time)", publish_period_);
  res.success = true;
  res.message = buf;
  ROS_INFO("%s", buf);
  return true;
}

void IdentifierNode::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
  // (Telemetry: the last published fit; fitting again here would double its cost.)
  const Estimate e = data_kind_ == DataKind::Telemetry ? telemetry_->lastFit().estimate : identifier_->estimate();
  const IdentifierCounters c = data_kind_ == DataKind::Telemetry ? e.counters : identifier_->counters();
  const double silent = (ros::WallTime::now() - last_receive_).toSec();
  // Bad input warns for bad_input_hold after the last of it, then the state of the data shows
  // again (the counters keep the totals).
  const std::uint64_t bad = c.skipped_nonfinite + dropped_ + c.gaps + c.time_resets + bad_messages_;
  if (bad > bad_input_seen_) {
    bad_input_seen_ = bad;
    last_bad_input_ = ros::WallTime::now();
  }
  const bool bad_input_recent = bad > 0 && (ros::WallTime::now() - last_bad_input_).toSec() < bad_input_hold_;
  using diagnostic_msgs::DiagnosticStatus;
  if (received_ == 0 && silent > timeout_)
    stat.summaryf(DiagnosticStatus::WARN, "no samples received for %.1f s on %s", silent, sub_.getTopic().c_str());
  else if (silent > timeout_)
    stat.summaryf(DiagnosticStatus::WARN, "no samples for %.1f s", silent);
  else if (bad_input_recent)
    stat.summaryf(DiagnosticStatus::WARN, "running; some input was bad within the last %g s (see counters)", bad_input_hold_);
  else if (published_ == 0 && nonfinite_estimates_ > 0)
    stat.summary(DiagnosticStatus::WARN, "no estimate yet: the data do not determine the motor's scale (no current?)");
  else
    stat.summary(DiagnosticStatus::OK, "running");
  int poor = 0, identified = 0;
  for (int p = 0; p < kParameterCount; ++p) {
    poor += e.status[p] == ParameterStatus::PoorFit || e.status[p] == ParameterStatus::Implausible;
    identified += e.identifiable[p];
  }
  if (stat.level == DiagnosticStatus::OK && poor > 0)
    stat.summaryf(DiagnosticStatus::WARN, "the model does not fit the data%s%s",
                  e.fit.likely_cause.empty() ? "" : ": likely cause: ", e.fit.likely_cause.c_str());
  else if (stat.level == DiagnosticStatus::OK)
    stat.summaryf(DiagnosticStatus::OK, "running; %d of 4 parameters identified", identified);
  for (AlarmKind k : {AlarmKind::WindingOverTemperature, AlarmKind::Demagnetisation, AlarmKind::ParameterJump,
                      AlarmKind::FastDrift}) {
    if (!monitor_.active(k)) continue;
    const bool severe = k == AlarmKind::WindingOverTemperature || k == AlarmKind::Demagnetisation;
    stat.mergeSummaryf(severe ? DiagnosticStatus::ERROR : DiagnosticStatus::WARN, "alarm: %s", toString(k));
  }
  stat.add("method", e.method);
  stat.add("data", data_kind_ == DataKind::Telemetry   ? "telemetry: the steady-state fit of the samples kept"
                   : data_kind_ == DataKind::CurrentLoop ? "the current loop's samples"
                                                         : "not yet known (waiting for samples)");
  if (data_kind_ == DataKind::Telemetry) {
    stat.add("telemetry samples kept", telemetry_->size());
    stat.add("telemetry samples let go (oldest beyond the limit)", telemetry_->forgotten());
  }
  stat.add("sampling period [s]", e.sample_period);
  stat.add("current noise from the data [A]", std::max(e.fit.noise_std_d, e.fit.noise_std_q));
  stat.add("fit consistent", e.fit.consistent ? "yes" : "no");
  if (!e.fit.likely_cause.empty()) stat.add("likely cause of the misfit", e.fit.likely_cause);
  stat.add("samples received", received_);
  stat.add("samples used", c.used);
  stat.add("samples skipped (non-finite)", c.skipped_nonfinite);
  stat.add("samples skipped (duplicate stamp)", c.skipped_duplicate);
  stat.add("samples skipped (stamp too close)", c.skipped_too_close);
  stat.add("sampling period changes", c.period_changes);
  stat.add("samples dropped (index gaps)", dropped_);
  stat.add("malformed messages", bad_messages_);
  stat.add("time gaps", c.gaps);
  stat.add("time resets (stamps went backwards)", c.time_resets);
  stat.add("batch stamps re-anchored (drifted from the index's time)", batch_timing_.reanchored());
  stat.add("rate [samples/s]", rate_);
  stat.add("estimates published", published_);
  stat.add("resets (~reset)", resets_);
  stat.add("monitor and map restarts (time resets, ~reset)", history_restarts_);
  stat.add("estimates withheld (no estimate yet)", nonfinite_estimates_);
  for (int p = 0; p < kParameterCount; ++p)
    stat.add(parameterNames()[p], std::string(toString(e.status[p])) + ": " + e.reason[p]);
  stat.add("drive model", e.drive_model.empty() ? std::string("as configured") : e.drive_model);
  if (e.fit.inverter_modelled)
    stat.addf("inverter voltage [V]", "%.4g (%s: %s)", e.inverter_voltage, toString(e.inverter_status), e.inverter_reason.c_str());
  if (e.fit.voltage_angle_modelled)
    stat.addf("voltage angle [omega_e T_s]", "%.3g +- %.2g", e.fit.voltage_angle, e.fit.voltage_angle_std);
  if (identifier_->config().thermal.enabled) {
    const auto temperature = [&](const char* key, const Temperature& t) {
      if (std::isfinite(t.value)) stat.addf(key, "%.1f +- %.1f K", t.value, t.uncertainty);
      else stat.add(key, "unknown (parameter not identified)");
    };
    temperature("winding temperature [degC]", e.winding_temperature);
    temperature("magnet temperature [degC]", e.magnet_temperature);
  }
}

}  // namespace pmsm_param_id
