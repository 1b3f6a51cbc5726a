#include "solvers/step_common.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace pbdbench {

void check_step(const Model& model, const State& state, double dt, int particles, int constraints) {
  if (!(dt > 0.0) || !std::isfinite(dt))
    throw std::invalid_argument("dt = " + std::to_string(dt) + " must be a finite number > 0");
  if (model.particle_count() != particles || model.constraint_count() != constraints)
    throw std::invalid_argument("the model has " + std::to_string(model.particle_count()) +
                                " particles and " + std::to_string(model.constraint_count()) +
                                " constraints; the solver was built for " +
                                std::to_string(particles) + " and " + std::to_string(constraints));
  if (state.x.rows() != particles || state.v.rows() != particles)
    throw std::invalid_argument("state.x or state.v does not have one row per particle (" +
                                std::to_string(particles) + ")");
}

void set_kinematic(const Model& model, Points& x, Points& v, double t) {
  for (const Attachment& a : model.attachments) {
    x.row(a.particle) = attachment_target(model, a, t).transpose();
    const Vec3 velocity = a.motion < 0
                              ? Vec3::Zero()
                              : motion_velocity(model.motions[static_cast<size_t>(a.motion)], t);
    v.row(a.particle) = velocity.transpose();
  }
}

void round_to_float(Points& p) {
  for (Eigen::Index i = 0; i < p.size(); ++i) p.data()[i] = round_to_float(p.data()[i]);
}

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
