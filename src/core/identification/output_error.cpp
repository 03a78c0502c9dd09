#include "pmsm_param_id/identification/output_error.hpp"

#include <algorithm>
#include <cmath>

namespace pmsm_param_id {

const char* toString(FitnessKind k) {
  switch (k) {
    case FitnessKind::Block: return "block";
    case FitnessKind::Paper: return "paper";
    case FitnessKind::PaperOneStep: return "paper_one_step";
  }
  return "?";
}

bool fitnessKindFrom(const std::string& name, FitnessKind& out) {
  for (FitnessKind k : {FitnessKind::Block, FitnessKind::Paper, FitnessKind::PaperOneStep})
    if (name == toString(k)) {
      out = k;
      return true;
    }
  return false;
}

OutputErrorWindow::OutputErrorWindow(FitnessKind kind, int window_samples, int voltage_delay_samples)
    : kind_(kind),
      capacity_(kind == FitnessKind::PaperOneStep ? 2 : static_cast<std::size_t>(std::max(2, window_samples))),
      delay_(voltage_delay_samples) {
  for (auto* v : {&t_, &ud_, &uq_, &w_, &id_, &iq_}) v->assign(2 * capacity_, 0.0);
}

void OutputErrorWindow::clear() {
  count_ = 0;
  have_previous_ = false;
}

void OutputErrorWindow::push(const Sample& s) {
  // The voltage acting from this sample on: its own, or (one sample of delay) the previous one.
  double ud = s.u_d, uq = s.u_q;
  if (delay_ > 0) {
    const bool first = !have_previous_;
    ud = previous_ud_;
    uq = previous_uq_;
    previous_ud_ = s.u_d;
    previous_uq_ = s.u_q;
    have_previous_ = true;
    if (first) return;  // the voltage acting from the first sample on is not in the data
  }
  const std::size_t i = count_ % capacity_;
  for (std::size_t j : {i, i + capacity_}) {
    t_[j] = s.t;
    ud_[j] = ud;
    uq_[j] = uq;
    w_[j] = s.omega_e;
    id_[j] = s.i_d;
    iq_[j] = s.i_q;
  }
  ++count_;
}

bool OutputErrorWindow::ready() const { return count_ >= capacity_; }

std::vector<Sample> OutputErrorWindow::samples() const {
  std::vector<Sample> out;
  const std::size_t n = size(), head = count_ < capacity_ ? 0 : count_ % capacity_;
  for (std::size_t k = head; k < head + n; ++k) out.push_back(Sample{t_[k], ud_[k], uq_[k], id_[k], iq_[k], w_[k]});
  return out;
}

double OutputErrorWindow::operator()(const ParameterVector& p) const {
  double f = 0.0;
  kernel(&p, 1, &f);
  return f;
}

void OutputErrorWindow::batch(const ParameterVector* p, std::size_t n, double* out) const {
  constexpr std::size_t kChunk = 32;
  for (std::size_t k = 0; k < n; k += kChunk) kernel(p + k, std::min(kChunk, n - k), out + k);
}

// Eq. (11) for up to 32 parameter vectors side by side; Eq. (12) accumulated on the way. Built
// twice, for AVX2 with FMA and for the baseline, and picked at run time (GCC function
// multi-versioning): the particles' loop is 4 wide where the CPU allows.
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
__attribute__((target_clones("arch=haswell", "default")))
#endif
void OutputErrorWindow::kernel(const ParameterVector* p, std::size_t n, double* out) const {
  constexpr std::size_t kChunk = 32;
  alignas(64) double R[kChunk], inv_Ld[kChunk], inv_Lq[kChunk], Ld[kChunk], Lq[kChunk], psi[kChunk];
  alignas(64) double id_hat[kChunk], iq_hat[kChunk], err[kChunk];
  const std::size_t size = this->size();
  const std::size_t head = count_ < capacity_ ? 0 : count_ % capacity_;
  const double *t = &t_[head], *ud = &ud_[head], *uq = &uq_[head], *w = &w_[head], *id = &id_[head], *iq = &iq_[head];
  for (std::size_t j = 0; j < n; ++j) {
    R[j] = p[j][kRs];
    Ld[j] = p[j][kLd];
    Lq[j] = p[j][kLq];
    psi[j] = p[j][kPsiF];
    inv_Ld[j] = 1.0 / Ld[j];
    inv_Lq[j] = 1.0 / Lq[j];
    id_hat[j] = size ? id[0] : 0.0;
    iq_hat[j] = size ? iq[0] : 0.0;
    err[j] = 0.0;
  }
  for (std::size_t k = 0; k + 1 < size; ++k) {
    const double T = t[k + 1] - t[k], u_d = ud[k], u_q = uq[k], omega = w[k], i_d = id[k + 1], i_q = iq[k + 1];
    for (std::size_t j = 0; j < n; ++j) {
      const double did = (u_d - R[j] * id_hat[j] + omega * Lq[j] * iq_hat[j]) * inv_Ld[j];
      const double diq = (u_q - R[j] * iq_hat[j] - omega * (Ld[j] * id_hat[j] + psi[j])) * inv_Lq[j];
      id_hat[j] += T * did;
      iq_hat[j] += T * diq;
      const double ed = i_d - id_hat[j], eq = i_q - iq_hat[j];
      err[j] += ed * ed + eq * eq;
    }
  }
  const double scale = size > 1 ? 1.0 / static_cast<double>(size - 1) : 0.0;
  for (std::size_t j = 0; j < n; ++j) {
    const double f = err[j] * scale;
    out[j] = f < 1e300 ? f : 1e300;  // a diverging model (or NaN) is the worst fitness, not NaN
  }
}

}  // namespace pmsm_param_id
