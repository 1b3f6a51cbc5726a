#include "solvers/substep.hpp"

#include "solvers/velocity_pass.hpp"

namespace pbdbench {

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

void find_substep_contacts(const Model& model, double t_end, double margin, const Points& x,
                           Ordering& ordering, SubstepScratch& work, StepReport& report) {
  work.contacts = find_contacts(model, work.p, t_end, margin);
  ordering.set_contacts(model, work.contacts, x);
  work.contact_lambda.assign(work.contacts.size(), 0.0);
  work.contact_active.assign(work.contacts.size(), 0);
  report.contacts += static_cast<int>(work.contacts.size());
}

ConstraintEval contact_stencil(const Model& model, size_t k, double t_end, SubstepScratch& work,
                               Stencil& st, Weights& w) {
  const Contact& c = work.contacts[k];
  st.count = c.kind == ContactKind::Particle ? 2 : 1;
  st.particles = {c.a, c.b, -1, -1};
  w = Weights{};
  w[0] = model.inv_mass[static_cast<size_t>(c.a)];
  if (st.count == 2) w[1] = model.inv_mass[static_cast<size_t>(c.b)];
  const ConstraintEval e = eval_contact(model, c, work.p, t_end);
  if (e.valid && e.C < 0.0) work.contact_active[k] = 1;
  return e;
}

void finish_substep(const Model& model, double t_end, double h, SubstepScratch& work, Points& x,
                    Points& v, Precision precision) {
  const bool single = precision == Precision::Float;
  const float hf = static_cast<float>(h);
  for (int i = 0; i < model.particle_count(); ++i) {
    if (model.inv_mass[static_cast<size_t>(i)] > 0.0) {
      if (single) {
        for (int k = 0; k < 3; ++k)
          v(i, k) = static_cast<double>((static_cast<float>(work.p(i, k)) - static_cast<float>(x(i, k))) / hf);
      } else {
        v.row(i) = (work.p.row(i) - x.row(i)) / h;
      }
    }
    x.row(i) = work.p.row(i);
  }
  velocity_pass(model, work.contacts, work.contact_lambda, x, work.v_before, v, t_end, h,
                precision);
}

}  // namespace pbdbench
