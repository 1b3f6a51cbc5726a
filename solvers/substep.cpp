#include "solvers/substep.hpp"

#include "solver_api/velocity_pass.hpp"

namespace pbdbench {

void find_substep_contacts(const Model& model, double t_end, double margin, const Points& x,
                           Ordering& ordering, SubstepScratch& work, StepReport& report) {
  work.contacts = find_contacts(model, work.p, t_end, margin, &work.surface_cache);
  ordering.set_contacts(model, work.contacts, x);
  work.contact_lambda.assign(work.contacts.size(), 0.0);
  work.contact_active.assign(work.contacts.size(), 0);
  report.contacts += static_cast<int>(work.contacts.size());
}

ConstraintEval contact_stencil(const Model& model, size_t k, double t_end, SubstepScratch& work,
                               Stencil& st, Weights& w) {
  const Contact& c = work.contacts[k];
  std::array<int, 4> ps{};
  st.count = contact_particles(model, c, ps);
  st.particles = {ps[0], ps[1], ps[2], ps[3]};
  w = Weights{};
  for (int i = 0; i < st.count; ++i) w[static_cast<size_t>(i)] = model.inv_mass[static_cast<size_t>(ps[static_cast<size_t>(i)])];
  const ConstraintEval e = eval_contact(model, c, work.p, t_end);
  if (e.valid && e.C < 0.0) work.contact_active[k] = 1;
  return e;
}

void finish_substep(const Model& model, double t_end, double h, SubstepScratch& work, Points& x,
                    Points& v, Precision precision) {
  update_from_positions(model, h, work.p, x, v, precision);
  velocity_pass(model, work.contacts, work.contact_lambda, x, work.v_before, v, t_end, h,
                precision);
}

}  // namespace pbdbench
