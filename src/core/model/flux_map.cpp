#include "pmsm_param_id/model/flux_map.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include "pmsm_param_id/io/config_error.hpp"

namespace pmsm_param_id {

namespace {
std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t\r") - a + 1);
}
std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) out.push_back(trim(cell));
  return out;
}
/// Index of the cell [v[k], v[k+1]] holding x, the border cells beyond the ends.
std::size_t cellIndex(const std::vector<double>& v, double x) {
  const auto it = std::upper_bound(v.begin(), v.end(), x);
  const std::size_t k = it == v.begin() ? 0 : static_cast<std::size_t>(it - v.begin()) - 1;
  return std::min(k, v.size() - 2);
}
std::string number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}
}  // namespace

FluxTable::FluxTable(std::vector<double> i_d, std::vector<double> i_q, std::vector<double> psi_d,
                     std::vector<double> psi_q, const std::string& source)
    : i_d_(std::move(i_d)), i_q_(std::move(i_q)), psi_d_(std::move(psi_d)), psi_q_(std::move(psi_q)) {
  const auto fail = [&](const std::string& what) { throw InputError(source + ": " + what); };
  if (i_d_.size() < 2 || i_q_.size() < 2)
    fail("a flux map needs at least two i_d and two i_q values (got " + std::to_string(i_d_.size()) + " and " +
         std::to_string(i_q_.size()) + ")");
  if (psi_d_.size() != i_d_.size() * i_q_.size() || psi_q_.size() != psi_d_.size())
    fail("node count does not match the grid");
  for (const auto* axis : {&i_d_, &i_q_})
    for (std::size_t k = 0; k + 1 < axis->size(); ++k)
      if (!((*axis)[k] < (*axis)[k + 1]) || !std::isfinite((*axis)[k + 1])) fail("grid currents must be finite and increasing");
  for (std::size_t q = 0; q < i_q_.size(); ++q)
    for (std::size_t d = 0; d < i_d_.size(); ++d) {
      if (!std::isfinite(psiD(d, q)) || !std::isfinite(psiQ(d, q)))
        fail("non-finite flux at i_d = " + number(i_d_[d]) + " A, i_q = " + number(i_q_[q]) + " A");
      if (d + 1 < i_d_.size() && !(psiD(d + 1, q) > psiD(d, q)))
        fail("psi_d must increase with i_d (a positive incremental L_d); it does not between i_d = " + number(i_d_[d]) +
             " and " + number(i_d_[d + 1]) + " A at i_q = " + number(i_q_[q]) + " A");
      if (q + 1 < i_q_.size() && !(psiQ(d, q + 1) > psiQ(d, q)))
        fail("psi_q must increase with i_q (a positive incremental L_q); it does not between i_q = " + number(i_q_[q]) +
             " and " + number(i_q_[q + 1]) + " A at i_d = " + number(i_d_[d]) + " A");
    }
  // The incremental inductance matrix must be positive definite (a machine stores positive
  // magnetic energy; the simulator's Newton step divides by its determinant): at each cell's corners.
  for (std::size_t q = 0; q + 1 < i_q_.size(); ++q)
    for (std::size_t d = 0; d + 1 < i_d_.size(); ++d)
      for (double a : {1e-6, 1.0 - 1e-6})
        for (double b : {1e-6, 1.0 - 1e-6}) {
          const FluxLinkage f = at(i_d_[d] + a * (i_d_[d + 1] - i_d_[d]), i_q_[q] + b * (i_q_[q + 1] - i_q_[q]));
          if (!(f.dpsi_d_di_d * f.dpsi_q_di_q - f.dpsi_d_di_q * f.dpsi_q_di_d > 0))
            fail("the incremental inductance matrix is not positive definite in the cell i_d = " + number(i_d_[d]) +
                 ".." + number(i_d_[d + 1]) + " A, i_q = " + number(i_q_[q]) + ".." + number(i_q_[q + 1]) +
                 " A (cross terms larger than the self-inductances allow)");
        }
}

FluxLinkage FluxTable::at(double i_d, double i_q) const {
  const std::size_t d = cellIndex(i_d_, i_d), q = cellIndex(i_q_, i_q);
  const double hd = i_d_[d + 1] - i_d_[d], hq = i_q_[q + 1] - i_q_[q];
  const double a = (i_d - i_d_[d]) / hd, b = (i_q - i_q_[q]) / hq;  // outside [0, 1]: linear extrapolation
  const auto blend = [&](double f00, double f10, double f01, double f11, double& value, double& by_d, double& by_q) {
    value = (1 - a) * (1 - b) * f00 + a * (1 - b) * f10 + (1 - a) * b * f01 + a * b * f11;
    by_d = ((1 - b) * (f10 - f00) + b * (f11 - f01)) / hd;
    by_q = ((1 - a) * (f01 - f00) + a * (f11 - f10)) / hq;
  };
  FluxLinkage out;
  blend(psiD(d, q), psiD(d + 1, q), psiD(d, q + 1), psiD(d + 1, q + 1), out.psi_d, out.dpsi_d_di_d, out.dpsi_d_di_q);
  blend(psiQ(d, q), psiQ(d + 1, q), psiQ(d, q + 1), psiQ(d + 1, q + 1), out.psi_q, out.dpsi_q_di_d, out.dpsi_q_di_q);
  return out;
}

FluxTable loadFluxTable(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open the flux map");
  std::string line;
  int line_no = 0;
  int col[4] = {-1, -1, -1, -1};
  const char* names[4] = {"i_d", "i_q", "psi_d", "psi_q"};
  bool header = false;
  std::map<std::pair<double, double>, std::pair<double, double>> nodes;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const std::vector<std::string> cells = split(t);
    const std::string where = path + ":" + std::to_string(line_no) + ": ";
    if (!header) {
      for (std::size_t k = 0; k < cells.size(); ++k)
        for (int c = 0; c < 4; ++c)
          if (cells[k] == names[c]) col[c] = static_cast<int>(k);
      for (int c = 0; c < 4; ++c)
        if (col[c] < 0) throw InputError(where + "header must name the columns i_d,i_q,psi_d,psi_q (missing '" + names[c] + "')");
      header = true;
      continue;
    }
    double v[4];
    for (int c = 0; c < 4; ++c) {
      if (static_cast<std::size_t>(col[c]) >= cells.size()) throw InputError(where + "missing column '" + names[c] + "'");
      const std::string& s = cells[static_cast<std::size_t>(col[c])];
      char* end = nullptr;
      v[c] = std::strtod(s.c_str(), &end);
      if (s.empty() || *end != '\0' || !std::isfinite(v[c]))
        throw InputError(where + "'" + names[c] + "' is not a finite number: '" + s + "'");
    }
    if (!nodes.emplace(std::make_pair(v[0], v[1]), std::make_pair(v[2], v[3])).second)
      throw InputError(where + "node i_d = " + number(v[0]) + " A, i_q = " + number(v[1]) + " A given twice");
  }
  if (!header) throw InputError(path + ": empty flux map (no header line)");
  std::vector<double> i_d, i_q;
  for (const auto& n : nodes) {
    i_d.push_back(n.first.first);
    i_q.push_back(n.first.second);
  }
  for (auto* axis : {&i_d, &i_q}) {
    std::sort(axis->begin(), axis->end());
    axis->erase(std::unique(axis->begin(), axis->end()), axis->end());
  }
  std::vector<double> psi_d, psi_q;
  for (double q : i_q)
    for (double d : i_d) {
      const auto it = nodes.find({d, q});
      if (it == nodes.end())
        throw InputError(path + ": not a full grid: node i_d = " + number(d) + " A, i_q = " + number(q) + " A is missing");
      psi_d.push_back(it->second.first);
      psi_q.push_back(it->second.second);
    }
  return FluxTable(i_d, i_q, psi_d, psi_q, path);
}

void writeFluxTable(const FluxTable& table, const std::string& path, const std::string& comment) {
  std::ofstream out(path);
  if (!out) throw UserError(path + ": cannot write the flux map");
  out << "# " << comment << "\n";
  out << "i_d,i_q,psi_d,psi_q\n";
  char buf[128];
  for (std::size_t q = 0; q < table.iQ().size(); ++q)
    for (std::size_t d = 0; d < table.iD().size(); ++d) {
      std::snprintf(buf, sizeof buf, "%.10g,%.10g,%.10g,%.10g\n", table.iD()[d], table.iQ()[q], table.psiD(d, q),
                    table.psiQ(d, q));
      out << buf;
    }
  if (!out) throw UserError(path + ": writing the flux map failed");
}

}  // namespace pmsm_param_id
