#include "pmsm_param_id/io/sample_csv.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "pmsm_param_id/io/config_error.hpp"

namespace pmsm_param_id {

void writeFileAtomically(const std::string& path, const std::function<void(std::FILE*)>& body) {
  // A device or a pipe (/dev/null, /dev/stdout, a shell's process substitution) is written in
  // place: a rename over it would put a regular file where /dev/null was.
  struct stat st{};
  const bool special = ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode);
  const std::string target = special ? path : path + ".tmp." + std::to_string(::getpid());
  FILE* f = std::fopen(target.c_str(), "w");
  if (!f) throw std::runtime_error(path + ": cannot write (" + std::string(std::strerror(errno)) + ")");
  body(f);
  const bool ok = std::ferror(f) == 0;
  const bool closed = std::fclose(f) == 0;
  if (special) {
    if (!ok || !closed) throw std::runtime_error(path + ": write failed");
    return;
  }
  if (!closed || !ok || std::rename(target.c_str(), path.c_str()) != 0) {
    std::remove(target.c_str());
    throw std::runtime_error(path + ": write failed");
  }
}

void writeSampleCsv(const std::string& path, const std::vector<SimulatedSample>& samples) {
  writeFileAtomically(path, [&](FILE* f) {
    std::fputs("t,u_d,u_q,i_d,i_q,omega_e,theta_e,v_dc,R_s,L_d,L_q,psi_f\n", f);
    for (const SimulatedSample& s : samples) {
      const Sample& x = s.sample;
      std::fprintf(f, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", x.t, x.u_d, x.u_q,
                   x.i_d, x.i_q, x.omega_e, x.theta_e, x.v_dc, s.truth[kRs], s.truth[kLd], s.truth[kLq], s.truth[kPsiF]);
    }
  });
}

void writeSampleCsv(const std::string& path, const std::vector<SimulatedSample>& samples, const LogFormat& format,
                    double clock_start) {
  format.validate("log format");
  // (column name, file value from a sample)
  std::vector<std::pair<std::string, std::function<double(const SimulatedSample&)>>> columns;
  const auto add = [&](const char* quantity, std::function<double(const SimulatedSample&)> value) {
    const auto it = format.columns.find(quantity);
    if (it != format.columns.end() && !it->second.empty()) columns.emplace_back(it->second, std::move(value));
  };
  add("t", [&](const SimulatedSample& s) {
    double t = (clock_start + s.sample.t) / format.timeFactor();
    if (format.time_wraps_at > 0) t = std::fmod(t, format.time_wraps_at);
    return t;
  });
  add("u_d", [&](const SimulatedSample& s) { return s.sample.u_d / format.voltageFactor(); });
  add("u_q", [&](const SimulatedSample& s) { return s.sample.u_q / format.voltageFactor(); });
  add("i_d", [&](const SimulatedSample& s) { return s.sample.i_d / format.currentFactor(); });
  add("i_q", [&](const SimulatedSample& s) { return s.sample.i_q / format.currentFactor(); });
  add("omega_e", [&](const SimulatedSample& s) { return s.sample.omega_e / format.speedFactor(); });
  if (!samples.empty() && std::isfinite(samples.front().sample.theta_e))
    add("theta_e", [&](const SimulatedSample& s) { return s.sample.theta_e / format.angleFactor(); });
  if (!samples.empty() && std::isfinite(samples.front().sample.v_dc))
    add("v_dc", [&](const SimulatedSample& s) { return s.sample.v_dc / format.busVoltageFactor(); });
  for (int p = 0; p < kParameterCount; ++p)
    columns.emplace_back(parameterNames()[p], [p](const SimulatedSample& s) { return s.truth[p]; });
  writeFileAtomically(path, [&](FILE* f) {
    for (std::size_t c = 0; c < columns.size(); ++c)
      std::fprintf(f, "%s%c", columns[c].first.c_str(), c + 1 < columns.size() ? format.separator : '\n');
    for (const SimulatedSample& s : samples)
      for (std::size_t c = 0; c < columns.size(); ++c)
        std::fprintf(f, "%.17g%c", columns[c].second(s), c + 1 < columns.size() ? format.separator : '\n');
  });
}

namespace {
/// A CSV log's line is a few hundred bytes; one longer than this is not a log (a binary file, a file
/// of NULs), and reading it whole could take gigabytes.
constexpr std::size_t kMaxLineBytes = 1 << 20;

/// std::getline, but refusing a line beyond kMaxLineBytes with the line's number (istream::getline
/// into a fixed buffer: it stops at the buffer's end instead of growing a string without bound).
bool readLine(std::istream& in, std::vector<char>& buffer, std::string& line, std::size_t line_no,
              const std::string& path) {
  in.getline(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  const std::streamsize n = in.gcount();
  if (in.fail() && !in.eof() && n == static_cast<std::streamsize>(buffer.size()) - 1)
    throw InputError(path + ":" + std::to_string(line_no) + ": a line longer than 1 MiB: not a CSV drive log");
  if (n == 0 && !in) return false;  // end of file
  const bool delimited = !in.eof();   // the newline was extracted (and counted in n), not stored
  line.assign(buffer.data(), static_cast<std::size_t>(delimited ? n - 1 : n));
  return true;
}

std::vector<std::string> splitCells(const std::string& line, char separator) {
  std::vector<std::string> cells;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, separator)) {
    const auto b = cell.find_first_not_of(" \t\r");
    const auto e = cell.find_last_not_of(" \t\r");
    cells.push_back(b == std::string::npos ? std::string() : cell.substr(b, e - b + 1));
  }
  if (!line.empty() && line.back() == separator) cells.emplace_back();
  return cells;
}
}  // namespace

SampleLog readSampleCsv(const std::string& path, const LogFormat& format) {
  format.validate("log format");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open file");
  std::string line;
  std::vector<char> buffer(kMaxLineBytes + 1);
  std::size_t line_no = 0;
  // Header: first non-empty line.
  while (readLine(in, buffer, line, line_no + 1, path)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") != std::string::npos) break;
  }
  if (line_no == 0 || line.find_first_not_of(" \t\r") == std::string::npos)
    throw InputError(path + ": empty file (expected a header t,u_d,u_q,i_d,i_q,omega_e)");
  // A UTF-8 byte-order mark (spreadsheet exports write one) is not part of the first column's name.
  if (line_no == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
  const std::vector<std::string> header = splitCells(line, format.separator);
  std::map<std::string, std::size_t> column;
  for (std::size_t i = 0; i < header.size(); ++i) column[header[i]] = i;
  const char* required[] = {"t", "u_d", "u_q", "i_d", "i_q", "omega_e"};
  std::size_t index[6];
  const bool timed = !format.columns.at("t").empty();  // else the rows are sample_period apart
  for (int i = timed ? 0 : 1; i < 6; ++i) {
    const std::string& name = format.columns.at(required[i]);
    const auto it = column.find(name);
    if (it == column.end())
      throw InputError(path + ":" + std::to_string(line_no) + ": missing column '" + name + "' for " + required[i] +
                       " (name the columns with --column or a --format file)");
    index[i] = it->second;
  }
  // The optional columns: a format that does not name one reads it under its own name.
  const auto optional = [&](const char* quantity) {
    const auto named = format.columns.find(quantity);
    return column.find(named != format.columns.end() ? named->second : std::string(quantity));
  };
  const auto theta_it = optional("theta_e");
  const bool has_theta = theta_it != column.end();
  const auto bus_it = optional("v_dc");
  const bool has_bus = bus_it != column.end();
  SampleLog log;
  std::size_t truth_index[4];
  log.has_truth = true;
  for (int p = 0; p < kParameterCount; ++p) {
    const auto it = column.find(parameterNames()[p]);
    if (it == column.end()) {
      log.has_truth = false;
      break;
    }
    truth_index[p] = it->second;
  }
  auto number = [&](const std::vector<std::string>& cells, std::size_t i) {
    const std::string& text = cells[i];
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || end == text.c_str() || *end != '\0')
      throw InputError(path + ":" + std::to_string(line_no) + ": column '" + header[i] + "': not a number: '" +
                       text + "'");
    return v;  // nan/inf parse and are returned as such
  };
  double wraps = 0.0;  // whole wraps of the time column so far [its unit]
  double last_raw_t = std::numeric_limits<double>::quiet_NaN();
  while (readLine(in, buffer, line, line_no + 1, path)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::vector<std::string> cells = splitCells(line, format.separator);
    if (cells.size() != header.size())
      throw InputError(path + ":" + std::to_string(line_no) + ": expected " + std::to_string(header.size()) +
                       " cells, found " + std::to_string(cells.size()));
    Sample s;
    const double raw_t = timed ? number(cells, index[0]) : static_cast<double>(log.samples.size()) * format.sample_period / format.timeFactor();
    // A clock that restarts (ms since midnight) continues across the restart.
    if (format.time_wraps_at > 0 && raw_t < last_raw_t - 0.5 * format.time_wraps_at) wraps += format.time_wraps_at;
    if (std::isfinite(raw_t)) last_raw_t = raw_t;
    s.t = (raw_t + wraps) * format.timeFactor();
    s.u_d = number(cells, index[1]) * format.voltageFactor();
    s.u_q = number(cells, index[2]) * format.voltageFactor();
    s.i_d = number(cells, index[3]) * format.currentFactor();
    s.i_q = number(cells, index[4]) * format.currentFactor();
    s.omega_e = number(cells, index[5]) * format.speedFactor();
    if (has_theta) s.theta_e = number(cells, theta_it->second) * format.angleFactor();
    if (has_bus) s.v_dc = number(cells, bus_it->second) * format.busVoltageFactor();
    log.samples.push_back(s);
    log.line_numbers.push_back(line_no);
    if (log.has_truth) {
      ParameterVector p{};
      for (int j = 0; j < kParameterCount; ++j) p[j] = number(cells, truth_index[j]);
      log.truth.push_back(p);
    }
  }
  return log;
}

}  // namespace pmsm_param_id
