#include "pmsm_param_id/ros/plant_simulator.hpp"

#include <rosgraph_msgs/Clock.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/ros/ros_bridge.hpp"
#include "pmsm_param_id/simulation/drive_simulator.hpp"

namespace pmsm_param_id {

PlantSimulator::PlantSimulator(ros::NodeHandle pnh) : pnh_(pnh) {
  const std::string path = typedParam<std::string>(pnh_, "scenario", "");
  const double duration = typedParam<double>(pnh_, "duration", 0.0);
  realtime_ = typedParam<double>(pnh_, "realtime_factor", 1.0);
  linger_ = typedParam<double>(pnh_, "linger", 1.0);
  const int seed = typedParam<int>(pnh_, "seed", -1);
  const int substeps = typedParam<int>(pnh_, "integration_substeps", 0);
  batch_ = typedParam<int>(pnh_, "batch_size", 100);
  decimation_ = typedParam<int>(pnh_, "decimation", 100);
  wait_for_ = typedParam<int>(pnh_, "wait_for_subscribers", 0);
  publish_clock_ = typedParam<bool>(pnh_, "publish_clock", false);
  if (path.empty()) throw ConfigError("parameter ~scenario: missing (path of a scenario YAML)");
  if (batch_ < 1) throw ConfigError("parameter ~batch_size: must be >= 1");
  if (decimation_ < 1) throw ConfigError("parameter ~decimation: must be >= 1");
  if (realtime_ < 0) throw ConfigError("parameter ~realtime_factor: must be >= 0");
  if (substeps < 0 || substeps > 10000)
    throw ConfigError("parameter ~integration_substeps: must be 0 (the scenario's) to 10000");
  try {
    scenario_ = loadScenario(path);
  } catch (const ConfigError& e) {
    throw ConfigError(std::string("parameter ~scenario: ") + e.what());
  }
  if (duration > 0) scenario_.duration = duration;
  if (seed >= 0) scenario_.seed = static_cast<std::uint64_t>(seed);
  if (substeps > 0) scenario_.drive.integration_substeps = substeps;
}

void PlantSimulator::advertise() {
  pub_batch_ = pnh_.advertise<DriveSampleBatch>("samples_batch", 1000);
  pub_sample_ = pnh_.advertise<DriveSample>("samples", 1000);
  pub_truth_ = pnh_.advertise<ElectricalParameters>("true_parameters", 100, true);
  if (publish_clock_) pub_clock_ = ros::NodeHandle().advertise<rosgraph_msgs::Clock>("/clock", 10);
  wait_start_ = ros::WallTime::now();
}

bool PlantSimulator::subscribersReady() {
  if (static_cast<int>(pub_batch_.getNumSubscribers()) >= wait_for_) return true;
  if ((ros::WallTime::now() - wait_start_).toSec() < 20.0) return false;
  ROS_WARN("only %u of %d subscribers after 20 s; starting anyway", pub_batch_.getNumSubscribers(), wait_for_);
  return true;
}

void PlantSimulator::begin() {
  sim_ = std::make_unique<DriveSimulator>(scenario_);
  // Owning /clock, time starts at 1 s (ros::Time(0) means "unset" to many tools).
  start_ = publish_clock_ ? ros::Time(1.0) : ros::Time::now();
  wall_start_ = ros::WallTime::now();
  ROS_INFO("simulating '%s': %.3g s at T_s = %.3g s, batches of %d, real-time factor %g", scenario_.name.c_str(),
           scenario_.duration, scenario_.drive.sample_period, batch_, realtime_);
}

double PlantSimulator::nextDue() const {
  // Published when the batch's last sample exists, as a real drive must (scaled by the factor).
  const std::uint64_t last = sim_->sampleIndex() + static_cast<std::uint64_t>(batch_) - 1;
  return realtime_ > 0 ? static_cast<double>(last) * scenario_.drive.sample_period / realtime_ : 0.0;
}

void PlantSimulator::publishBatch() {
  const double Ts = scenario_.drive.sample_period;
  DriveSampleBatch::Ptr msg = boost::make_shared<DriveSampleBatch>();
  std::vector<DriveSample::Ptr> singles;  // the decimated per-sample topic, sent with the batch
  msg->sample_period = Ts;
  msg->first_index = sim_->sampleIndex();
  ParameterVector truth{};
  double winding_temperature = NAN, magnet_temperature = NAN;
  for (auto* v : {&msg->u_d, &msg->u_q, &msg->i_d, &msg->i_q, &msg->omega_e, &msg->theta_e, &msg->v_dc})
    v->reserve(static_cast<std::size_t>(batch_));
  for (int k = 0; k < batch_ && !sim_->done(); ++k) {
    const SimulatedSample s = sim_->step();
    if (k == 0) {
      msg->header.stamp = start_ + ros::Duration(static_cast<double>(msg->first_index) * Ts);
      truth = s.truth;
      winding_temperature = s.winding_temperature;
      magnet_temperature = s.magnet_temperature;
    }
    msg->u_d.push_back(s.sample.u_d);
    msg->u_q.push_back(s.sample.u_q);
    msg->i_d.push_back(s.sample.i_d);
    msg->i_q.push_back(s.sample.i_q);
    msg->omega_e.push_back(s.sample.omega_e);
    msg->theta_e.push_back(s.sample.theta_e);
    msg->v_dc.push_back(s.sample.v_dc);
    if ((msg->first_index + static_cast<std::uint64_t>(k)) % static_cast<std::uint64_t>(decimation_) == 0) {
      DriveSample::Ptr one = boost::make_shared<DriveSample>();
      one->header.stamp = msg->header.stamp + ros::Duration(k * Ts);
      one->u_d = s.sample.u_d;
      one->u_q = s.sample.u_q;
      one->i_d = s.sample.i_d;
      one->i_q = s.sample.i_q;
      one->omega_e = s.sample.omega_e;
      one->theta_e = s.sample.theta_e;
      one->v_dc = s.sample.v_dc;
      singles.push_back(one);
    }
  }
  published_ += msg->u_d.size();
  const ros::Time stamp = msg->header.stamp;
  for (const DriveSample::Ptr& one : singles) pub_sample_.publish(one);
  pub_batch_.publish(msg);
  pub_truth_.publish(toMessage(truth, stamp, winding_temperature, magnet_temperature));
  if (publish_clock_) {
    rosgraph_msgs::Clock clock;
    clock.clock = start_ + ros::Duration(static_cast<double>(sim_->sampleIndex()) * Ts);
    pub_clock_.publish(clock);
  }
}

void PlantSimulator::finish() {
  ROS_INFO("published %llu samples (%.3g s of drive time) in %.3g s of wall time",
           static_cast<unsigned long long>(published_), static_cast<double>(published_) * scenario_.drive.sample_period,
           (ros::WallTime::now() - wall_start_).toSec());
  // A parameter's integer is 32 bits (XML-RPC): beyond it (60 h at 10 kHz) the count goes as a double.
  if (published_ <= static_cast<std::uint64_t>(std::numeric_limits<int>::max()))
    pnh_.setParam("samples_published", static_cast<int>(published_));
  else
    pnh_.setParam("samples_published", static_cast<double>(published_));
}

std::uint64_t PlantSimulator::run() {
  // The pacer's steps, sleeping between them (an error ends the node with its message, status 1).
  advertise();
  for (double wait = step(); wait >= 0; wait = step())
    if (wait > 0) ros::WallDuration(wait).sleep();
  if (phase_ == Phase::Running) finish();  // stopped (Ctrl-C) before the scenario's end
  return published_;
}

double PlantSimulator::advance() {
  // Never an exception out of here: in a nodelet manager it would end every motor.
  try {
    return step();
  } catch (const std::exception& e) {
    ROS_ERROR("the simulated drive stopped: %s", e.what());
    phase_ = Phase::Done;
    return -1.0;
  }
}

double PlantSimulator::step() {
  if (stop_ || phase_ == Phase::Done || !ros::ok()) return -1.0;
  switch (phase_) {
    case Phase::Waiting:
      if (!subscribersReady()) return 0.05;
      phase_ = Phase::Settling;  // let the remaining connections settle, as run() does
      settle_until_ = ros::WallTime::now() + ros::WallDuration(0.5);
      return 0.5;
    case Phase::Settling:
      if (ros::WallTime::now() < settle_until_) return (settle_until_ - ros::WallTime::now()).toSec();
      begin();
      phase_ = Phase::Running;
      break;
    default:
      break;
  }
  // Real time: the batches due by now; as fast as possible: one batch per call (the pacer's other
  // plants take their turns).
  const double elapsed = (ros::WallTime::now() - wall_start_).toSec();
  for (int n = 0; !stop_ && !sim_->done() && (realtime_ > 0 ? nextDue() <= elapsed : n < 1); ++n) publishBatch();
  if (sim_->done()) {
    finish();
    phase_ = Phase::Done;
    return -1.0;
  }
  return realtime_ > 0 ? std::max(0.0, nextDue() - (ros::WallTime::now() - wall_start_).toSec()) : 0.0;
}

std::shared_ptr<PlantPacer> PlantPacer::shared() {
  static std::mutex mutex;
  static std::weak_ptr<PlantPacer> instance;
  const std::lock_guard<std::mutex> lock(mutex);
  std::shared_ptr<PlantPacer> p = instance.lock();
  if (!p) {
    p = std::shared_ptr<PlantPacer>(new PlantPacer());
    instance = p;
  }
  return p;
}

PlantPacer::PlantPacer() : thread_([this] { loop(); }) {}

PlantPacer::~PlantPacer() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    quit_ = true;
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void PlantPacer::add(PlantSimulator* plant) {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    plants_.push_back({plant, Clock::now()});
  }
  changed_.notify_all();
}

void PlantPacer::remove(PlantSimulator* plant) {
  std::unique_lock<std::mutex> lock(mutex_);
  // Not while its batch is being published (the loop notifies when it is out).
  changed_.wait(lock, [&] { return running_ != plant; });
  plants_.erase(std::remove_if(plants_.begin(), plants_.end(), [&](const Entry& e) { return e.plant == plant; }),
                plants_.end());
  lock.unlock();
  changed_.notify_all();
}

void PlantPacer::loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (!quit_) {
    if (plants_.empty()) {
      changed_.wait(lock);
      continue;
    }
    // The plant due first; its batches run outside the lock (a plant being added or removed, and
    // roscpp's own locks in publish, never wait on this thread's).
    auto first = std::min_element(plants_.begin(), plants_.end(), [](const Entry& a, const Entry& b) { return a.due < b.due; });
    if (Clock::now() < first->due) {
      changed_.wait_until(lock, first->due);  // an add or remove wakes it early
      continue;
    }
    PlantSimulator* plant = running_ = first->plant;
    lock.unlock();
    const double wait = plant->advance();
    lock.lock();
    running_ = nullptr;
    const auto it = std::find_if(plants_.begin(), plants_.end(), [&](const Entry& e) { return e.plant == plant; });
    if (it != plants_.end()) {
      if (wait < 0) plants_.erase(it);
      else it->due = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wait));
    }
    changed_.notify_all();  // a remove() waiting for this plant
  }
}

}  // namespace pmsm_param_id
