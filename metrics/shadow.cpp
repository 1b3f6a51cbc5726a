#include "metrics/shadow.hpp"

#include <algorithm>
#include <cmath>

#include "core/constraint_functions.hpp"
#include "metrics/metrics.hpp"

namespace pbdbench {

ShadowSample measure_shadow(const Model& model, const State& run, const State& shadow) {
  ShadowSample s;
  double gap2 = 0.0, mass = 0.0, gap_max = 0.0;
  for (int i = 0; i < model.particle_count(); ++i) {
    const double w = model.inv_mass[static_cast<size_t>(i)];
    if (!(w > 0.0)) continue;
    const double d2 = (run.x.row(i) - shadow.x.row(i)).squaredNorm();
    gap2 += d2 / w;
    mass += 1.0 / w;
    gap_max = std::max(gap_max, std::sqrt(d2));
    if (std::isnan(d2)) gap_max = ShadowSample::kNaN;
  }
  s.gap = std::sqrt(gap2);
  s.gap_rms = mass > 0.0 ? std::sqrt(gap2 / mass) : 0.0;
  s.gap_max = gap_max;
  // The same measure as Sample::constraint_error_max (FEM kinds left out).
  double error = 0.0;
  for (const Constraint& c : model.constraints) {
    if (is_fem_kind(c.kind)) continue;
    const double e = normalized_error(c, eval_constraint(c, shadow.x).C);
    error = std::isnan(e) ? e : std::max(error, e);
    if (std::isnan(error)) break;
  }
  s.error_max = error;
  const Vec3 f = support_force(model, run), f_star = support_force(model, shadow);
  const double denominator = f_star.norm();
  if (f.allFinite() && f_star.allFinite() && denominator > 0.0) s.force_error = (f - f_star).norm() / denominator;
  return s;
}

}  // namespace pbdbench
