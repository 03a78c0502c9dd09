// A machine's flux linkages on a rectangular (i_d, i_q) grid: what users get from FEA or a dyno
// test, and what the identifier's online map exports (doc/simulator.md, "Flux maps").
//
// CSV, one row per grid node, any row order, '#' lines are comments:
//   i_d,i_q,psi_d,psi_q            (header; columns in any order; [A], [A], [Wb], [Wb])
// Every combination of the distinct i_d and i_q values must be present once; at least two values
// on each axis; psi_d strictly increasing in i_d and psi_q strictly increasing in i_q (positive
// incremental self-inductances). Between nodes psi is interpolated bilinearly; outside the grid it
// is extrapolated linearly from the border cells.
#pragma once
#include <string>
#include <vector>

namespace pmsm_param_id {

struct FluxLinkage {
  double psi_d = 0.0, psi_q = 0.0;  ///< [Wb]
  double dpsi_d_di_d = 0.0, dpsi_d_di_q = 0.0, dpsi_q_di_d = 0.0, dpsi_q_di_q = 0.0;  ///< [H]
};

class FluxTable {
 public:
  FluxTable() = default;
  /// Node values, psi_*[q_index * i_d.size() + d_index]; checked as the loader checks a file.
  FluxTable(std::vector<double> i_d, std::vector<double> i_q, std::vector<double> psi_d, std::vector<double> psi_q,
            const std::string& source = "flux table");
  /// Flux linkages and their partial derivatives (those of the bilinear cell holding the point).
  FluxLinkage at(double i_d, double i_q) const;
  const std::vector<double>& iD() const { return i_d_; }
  const std::vector<double>& iQ() const { return i_q_; }
  double psiD(std::size_t d, std::size_t q) const { return psi_d_[q * i_d_.size() + d]; }
  double psiQ(std::size_t d, std::size_t q) const { return psi_q_[q * i_d_.size() + d]; }

 private:
  std::vector<double> i_d_, i_q_, psi_d_, psi_q_;
};

/// Reads a flux-map CSV; InputError naming the file, line and what is wrong.
FluxTable loadFluxTable(const std::string& path);
/// Writes the CSV format above (with a comment line first); throws UserError if it cannot write.
void writeFluxTable(const FluxTable& table, const std::string& path, const std::string& comment);

}  // namespace pmsm_param_id
