// bag_tool csv2bag CSV BAG   : a drive log (t,u_d,u_q,i_d,i_q,omega_e[,theta_e][,v_dc][,R_s,L_d,L_q,psi_f]) as a bag
//                              that replay.launch plays (/drive/samples_batch, /drive/true_parameters).
// bag_tool bag2csv BAG CSV   : the samples of a bag as a drive log, with the identifier node's time
//                              base (seconds since the first stamp), so ./run identify sees exactly
//                              what the node saw.
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/io/sample_csv.hpp"
#include "pmsm_param_id/ros/ros_bridge.hpp"

using namespace pmsm_param_id;

namespace {
const char* kBatchTopic = "/drive/samples_batch";
const char* kTruthTopic = "/drive/true_parameters";
const ros::Time kOrigin(1000.0);  // stamp of t = 0 in bags made from CSV logs

// The sampling period: the median spacing, refined over the longest stretch of spacings within 1 %
// of it (a Unix-epoch time column carries its values to about 0.24 us: single spacings of 100 us
// are 0.2 % off, a stretch's mean is not).
double samplePeriodOf(const std::vector<Sample>& samples) {
  std::vector<double> dts;
  for (std::size_t k = 1; k < samples.size(); ++k) {
    const double dt = samples[k].t - samples[k - 1].t;
    if (std::isfinite(dt) && dt > 0) dts.push_back(dt);
  }
  if (dts.empty()) return 0.0;
  std::nth_element(dts.begin(), dts.begin() + static_cast<long>(dts.size() / 2), dts.end());
  const double median = dts[dts.size() / 2];
  std::size_t best_start = 0, best_length = 0, start = 0;
  for (std::size_t k = 1; k <= samples.size(); ++k) {
    const bool regular = k < samples.size() && std::abs(samples[k].t - samples[k - 1].t - median) <= 0.01 * median;
    if (regular) continue;
    if (k - 1 - start > best_length) {
      best_length = k - 1 - start;
      best_start = start;
    }
    start = k;
  }
  if (best_length < 2) return median;
  return (samples[best_start + best_length].t - samples[best_start].t) / static_cast<double>(best_length);
}

int csv2bag(const std::string& csv, const std::string& bag_path, std::size_t batch) {
  const SampleLog log = readSampleCsv(csv);
  if (log.samples.size() < 2) throw InputError(csv + ": fewer than 2 samples");
  const double Ts = samplePeriodOf(log.samples);
  if (!(Ts > 0)) throw InputError(csv + ": time never increases");
  // ros::Time holds up to 2^32 s: a time column beyond that is in another unit.
  for (std::size_t k = 0; k < log.samples.size(); ++k)
    if (std::isfinite(log.samples[k].t) && log.samples[k].t > 4.0e9)
    {
      char value[32];
      std::snprintf(value, sizeof value, "%.6g", log.samples[k].t);
      throw InputError(csv + ":" + std::to_string(log.line_numbers[k]) + ": time " + value +
                       " s is beyond ROS time's range (2^32 s): is the time column in ns or us? Convert it to seconds");
    }
  const std::string tmp = bag_path + ".tmp";
  std::size_t written = 0, skipped = 0, messages = 0, restarts = 0;
  try {
    rosbag::Bag bag(tmp, rosbag::bagmode::Write);
    DriveSampleBatch msg;
    double first_t = 0, previous_t = -INFINITY;
    std::size_t index_base = 0;
    // Playback follows the record times: they never go back, so a log whose time restarts plays its
    // stretches one after the other (the stamps go back once, and the identifier restarts once).
    ros::Time record_time = kOrigin, last_record = kOrigin;
    ParameterVector truth{};
    auto flush = [&]() {
      if (msg.u_d.empty()) return;
      const auto none = [](const std::vector<double>& v) { return std::all_of(v.begin(), v.end(), [](double a) { return std::isnan(a); }); };
      if (none(msg.theta_e)) msg.theta_e.clear();
      if (none(msg.v_dc)) msg.v_dc.clear();
      bag.write(kBatchTopic, record_time, msg);
      if (log.has_truth) bag.write(kTruthTopic, record_time, toMessage(truth, msg.header.stamp));
      last_record = record_time;
      written += msg.u_d.size();
      ++messages;
      msg = DriveSampleBatch();
    };
    for (std::size_t k = 0; k < log.samples.size(); ++k) {
      const Sample& s = log.samples[k];
      if (!std::isfinite(s.t) || s.t < 0) {
        std::fprintf(stderr, "%s:%zu: time '%g' cannot be stamped: row skipped\n", csv.c_str(), log.line_numbers[k], s.t);
        ++skipped;
        continue;
      }
      if (s.t < previous_t) {
        ++restarts;
        index_base = k;  // a restarted drive counts its samples from 0 again
        std::fprintf(stderr, "%s:%zu: time goes back from %.9g to %.9g s: played after what comes before it (the "
                     "identifier restarts there)\n", csv.c_str(), log.line_numbers[k], previous_t, s.t);
      }
      previous_t = s.t;
      const std::size_t n = msg.u_d.size();
      // On the batch's grid within a millionth of a period, or within the time column's own
      // resolution (8 ulps: a Unix-epoch column's 0.24 us).
      const double tolerance = std::max(1e-6 * Ts, 8.0 * (std::nextafter(s.t, INFINITY) - s.t));
      const bool on_grid = n > 0 && std::abs(s.t - (first_t + static_cast<double>(n) * Ts)) <= tolerance;
      if (n >= batch || (n > 0 && !on_grid)) flush();
      if (msg.u_d.empty()) {
        first_t = s.t;
        msg.header.stamp.fromSec(kOrigin.toSec() + s.t);  // (a Duration would stop at 2^31 s)
        record_time = std::max(msg.header.stamp, messages > 0 ? last_record + ros::Duration(Ts) : kOrigin);
        msg.sample_period = Ts;
        msg.first_index = k - index_base;
        if (log.has_truth) truth = log.truth[k];
      }
      msg.u_d.push_back(s.u_d);
      msg.u_q.push_back(s.u_q);
      msg.i_d.push_back(s.i_d);
      msg.i_q.push_back(s.i_q);
      msg.omega_e.push_back(s.omega_e);
      msg.theta_e.push_back(s.theta_e);
      msg.v_dc.push_back(s.v_dc);
    }
    flush();
    bag.close();
  } catch (...) {
    std::remove(tmp.c_str());  // no half-written bag left behind
    throw;
  }
  if (std::rename(tmp.c_str(), bag_path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw InputError(bag_path + ": cannot write");
  }
  std::printf("wrote %zu samples in %zu messages (T_s = %.6g s) to %s%s%s\n", written, messages, Ts, bag_path.c_str(),
              skipped ? " (some rows skipped, see above)" : "",
              restarts ? " (the time restarts, see above)" : "");
  return 0;
}

int bag2csv(const std::string& bag_path, const std::string& csv, const std::string& topic) {
  rosbag::Bag bag;
  try {
    bag.open(bag_path, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& e) {
    throw InputError(bag_path + ": not a readable bag (" + e.what() + ")");
  }
  std::map<ros::Time, ParameterVector> truth;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery(kTruthTopic)))
    if (auto t = m.instantiate<ElectricalParameters>()) truth[t->header.stamp] = {t->R_s, t->L_d, t->L_q, t->psi_f};
  StreamClock clock;
  BatchTiming timing;  // the node's sample times: from the index where a batch continues the stream
  std::vector<SimulatedSample> rows;
  std::size_t older = 0;  // DriveSampleBatch of an older definition (before v_dc)
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery(topic))) {
    if (m.getDataType() == ros::message_traits::DataType<DriveSampleBatch>::value() &&
        m.getMD5Sum() != ros::message_traits::MD5Sum<DriveSampleBatch>::value()) {
      ++older;
      continue;
    }
    auto b = m.instantiate<DriveSampleBatch>();
    if (!b || !checkBatch(*b).empty()) continue;
    ParameterVector p{NAN, NAN, NAN, NAN};
    auto it = truth.upper_bound(b->header.stamp);
    if (it != truth.begin()) p = std::prev(it)->second;
    const BatchTiming::Start start = timing.start(clock, *b);
    for (std::size_t k = 0; k < b->u_d.size(); ++k) {
      SimulatedSample s;
      s.sample = toSample(*b, k, clock.seconds(start.anchor, start.offset + k, b->sample_period));
      s.truth = p;
      rows.push_back(s);
    }
  }
  if (rows.empty() && older > 0)
    throw InputError(bag_path + ": " + std::to_string(older) + " DriveSampleBatch messages on " + topic +
                     " of an older definition (before v_dc); upgrade the bag first: rosbag fix " + bag_path +
                     " NEW.bag $(rospack find pmsm_param_id)/migration_rules/drive_samples.bmr");
  if (rows.empty()) throw InputError(bag_path + ": no DriveSampleBatch messages on " + topic);
  writeSampleCsv(csv, rows);
  std::printf("wrote %zu samples to %s\n", rows.size(), csv.c_str());
  return 0;
}
}  // namespace

int main(int argc, char** argv) {
  const std::string usage =
      "usage: bag_tool csv2bag CSV BAG [BATCH]\n       bag_tool bag2csv BAG CSV [TOPIC]\n";
  if (argc < 4) {
    std::fputs(usage.c_str(), stderr);
    return 2;
  }
  const std::string cmd = argv[1];
  try {
    ros::Time::init();
    if (cmd == "csv2bag") return csv2bag(argv[2], argv[3], argc > 4 ? std::stoul(argv[4]) : 100);
    if (cmd == "bag2csv") return bag2csv(argv[2], argv[3], argc > 4 ? argv[4] : kBatchTopic);
  } catch (const UserError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  std::fputs(usage.c_str(), stderr);
  return 2;
}
