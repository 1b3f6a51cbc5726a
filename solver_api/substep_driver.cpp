#include "solver_api/substep_driver.hpp"

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

void apply_gravity(const Model& model, double h, Points& v, Precision precision) {
  if (precision == Precision::Float) {
    // v += h g in float: float(h) float(g) rounded, added in float.
    const float hf = static_cast<float>(h);
    float dv[3];
    for (int k = 0; k < 3; ++k) dv[k] = hf * static_cast<float>(model.gravity[k]);
    for (int i = 0; i < model.particle_count(); ++i)
      if (model.inv_mass[static_cast<size_t>(i)] > 0.0)
        for (int k = 0; k < 3; ++k) v(i, k) = static_cast<double>(static_cast<float>(v(i, k)) + dv[k]);
    return;
  }
  for (int i = 0; i < model.particle_count(); ++i)
    if (model.inv_mass[static_cast<size_t>(i)] > 0.0) v.row(i) += (h * model.gravity).transpose();
}

void predict_positions(const Model& model, const Points& x, const Points& v, double h, Points& p,
                       Precision precision) {
  p = x;
  if (precision == Precision::Float) {
    const float hf = static_cast<float>(h);
    for (int i = 0; i < model.particle_count(); ++i)
      if (model.inv_mass[static_cast<size_t>(i)] > 0.0)
        for (int k = 0; k < 3; ++k)
          p(i, k) = static_cast<double>(static_cast<float>(x(i, k)) + hf * static_cast<float>(v(i, k)));
    return;
  }
  for (int i = 0; i < model.particle_count(); ++i)
    if (model.inv_mass[static_cast<size_t>(i)] > 0.0) p.row(i) += h * v.row(i);
}

void update_from_positions(const Model& model, double h, const Points& p, Points& x, Points& v,
                           Precision precision) {
  const bool single = precision == Precision::Float;
  const float hf = static_cast<float>(h);
  for (int i = 0; i < model.particle_count(); ++i) {
    if (model.inv_mass[static_cast<size_t>(i)] > 0.0) {
      if (single) {
        for (int k = 0; k < 3; ++k)
          v(i, k) = static_cast<double>((static_cast<float>(p(i, k)) - static_cast<float>(x(i, k))) / hf);
      } else {
        v.row(i) = (p.row(i) - x.row(i)) / h;
      }
    }
    x.row(i) = p.row(i);
  }
}

}  // namespace pbdbench
