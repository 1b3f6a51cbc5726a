#include "solvers/step_common.hpp"

namespace pbdbench {

JacobiAccumulator::JacobiAccumulator(int particles) { resize(particles); }

void JacobiAccumulator::resize(int particles) {
  sum_.assign(static_cast<size_t>(particles), Vec3::Zero());
  count_.assign(static_cast<size_t>(particles), 0);
  touched_.clear();
}

void JacobiAccumulator::add(int particle, const Vec3& dx) {
  if (dx.isZero(0.0)) return;  // not a correction of this particle
  const size_t p = static_cast<size_t>(particle);
  if (count_[p] == 0) touched_.push_back(particle);
  sum_[p] += dx;
  ++count_[p];
}

void JacobiAccumulator::apply(Points& x, double omega, bool averaging) {
  for (int particle : touched_) {
    const size_t p = static_cast<size_t>(particle);
    const double scale = averaging ? omega / static_cast<double>(count_[p]) : omega;
    x.row(particle) += (scale * sum_[p]).transpose();
    sum_[p].setZero();
    count_[p] = 0;
  }
  touched_.clear();
}

}  // namespace pbdbench
