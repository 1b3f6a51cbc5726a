#include "core/constraint_functions.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "core/constraint_stencils.hpp"
#include "core/constraint_values_packed.hpp"
#include "core/simd.hpp"
#include "core/fem.hpp"

namespace pbdbench {

namespace {

V3<double> v3(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
Vec3 vec3(const V3<double>& v) { return Vec3(v.x, v.y, v.z); }

ConstraintEval to_eval(const StencilEval<double>& s, int count) {
  ConstraintEval e;
  e.C = s.C;
  e.valid = s.valid;
  for (int i = 0; i < count; ++i) e.grad[static_cast<size_t>(i)] = vec3(s.grad[static_cast<size_t>(i)]);
  return e;
}

}  // namespace

ConstraintEval eval_distance(const Vec3& x0, const Vec3& x1, double rest) {
  return to_eval(distance_stencil(v3(x0), v3(x1), rest), 2);
}

double tet_signed_volume(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  return (x1 - x0).dot((x2 - x0).cross(x3 - x0)) / 6.0;
}

ConstraintEval eval_volume(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                           double rest) {
  return to_eval(volume_stencil(v3(x0), v3(x1), v3(x2), v3(x3), rest), 4);
}

double dihedral_angle(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  // The angle of bending_stencil (core/constraint_stencils.hpp), so that a constraint built with
  // this rest value has C = 0 exactly in its rest configuration.
  return bending_stencil(v3(x0), v3(x1), v3(x2), v3(x3), 0.0).C;
}

ConstraintEval eval_bending(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                            double rest) {
  return to_eval(bending_stencil(v3(x0), v3(x1), v3(x2), v3(x3), rest), 4);
}

ConstraintEval eval_constraint(const Constraint& c, const Points& x) {
  const auto& p = c.particles;
  switch (c.kind) {
    case ConstraintKind::Distance:
      return eval_distance(x.row(p[0]), x.row(p[1]), c.rest);
    case ConstraintKind::Volume:
      return eval_volume(x.row(p[0]), x.row(p[1]), x.row(p[2]), x.row(p[3]), c.rest);
    case ConstraintKind::Bending:
      return eval_bending(x.row(p[0]), x.row(p[1]), x.row(p[2]), x.row(p[3]), c.rest);
    case ConstraintKind::FemDeviatoric:
    case ConstraintKind::FemHydrostatic:
    case ConstraintKind::FemStrainTriangle:
    case ConstraintKind::FemStrainTet:
      break;  // needs the element: eval_constraint(model, c, x)
  }
  ConstraintEval none;
  none.valid = false;
  return none;
}

ConstraintEval eval_constraint(const Model& model, const Constraint& c, const Points& x) {
  if (!is_fem_kind(c.kind)) return eval_constraint(c, x);
  if (c.element < 0 || c.element >= static_cast<int>(model.elements.size())) {
    ConstraintEval none;
    none.valid = false;
    return none;
  }
  const FemElement& e = model.elements[static_cast<size_t>(c.element)];
  if (is_strain_kind(c.kind)) {
    // A vector constraint (fem::eval_strain): C is the norm of its strain vector, and there is no
    // one gradient to report.
    ConstraintEval ev;
    ev.C = fem::eval_strain(e, x).C.norm();
    ev.valid = false;
    return ev;
  }
  if (c.kind == ConstraintKind::FemHydrostatic) return fem::eval_hydrostatic(e, x, c.rest);
  ConstraintEval ev = fem::eval_deviatoric(e, x);  // sqrt(tr F^T F), its rest is 0
  ev.C -= c.rest;
  return ev;
}

namespace detail {
void constraint_values_avx2(const Model& model, const Points& x, const double* X, const RunsView& v, double* C);
void constraint_values_avx512(const Model& model, const Points& x, const double* X, const RunsView& v, double* C);
}  // namespace detail

ConstraintRuns constraint_runs(const Model& model) {
  ConstraintRuns out;
  const size_t m = model.constraints.size();
  for (std::vector<std::int32_t>& p : out.particle) p.assign(m, -1);
  out.rest.resize(m);
  for (size_t j = 0; j < m; ++j) {
    const Constraint& c = model.constraints[j];
    if (out.runs.empty() || out.runs.back().kind != c.kind)
      out.runs.push_back({c.kind, j, j});
    ++out.runs.back().end;
    out.rest[j] = c.rest;
    if (!is_fem_kind(c.kind))
      for (int i = 0; i < arity(c.kind); ++i) out.particle[static_cast<size_t>(i)][j] = c.particles[static_cast<size_t>(i)];
  }
  return out;
}

namespace {

detail::RunsView view_of(const ConstraintRuns& runs, const Model& model) {
  if (runs.rest.size() != model.constraints.size())
    throw std::invalid_argument("constraint_values: the runs were built for a model of " +
                                std::to_string(runs.rest.size()) + " constraints, this one has " +
                                std::to_string(model.constraints.size()));
  detail::RunsView v;
  v.runs = runs.runs.data();
  v.count = runs.runs.size();
  for (int i = 0; i < 4; ++i) v.particle[i] = runs.particle[static_cast<size_t>(i)].data();
  v.rest = runs.rest.data();
  v.constraints = model.constraints.data();
  return v;
}

}  // namespace

void constraint_values(const ConstraintRuns& runs, const Model& model, const Points& x, std::vector<double>& C) {
  // The widest packs the processor has (core/constraint_values_packed.hpp): the same bits at
  // every width.
  enum class Width { Sse2, Avx2, Avx512 };
  static const Width width = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("fma") ? Width::Avx512
                             : __builtin_cpu_supports("avx2")  ? Width::Avx2
                                                               : Width::Sse2;
  const detail::RunsView v = view_of(runs, model);
  C.resize(model.constraints.size());
  switch (width) {
    case Width::Avx512: detail::constraint_values_avx512(model, x, x.data(), v, C.data()); return;
    case Width::Avx2: detail::constraint_values_avx2(model, x, x.data(), v, C.data()); return;
    case Width::Sse2: break;
  }
  detail::constraint_values_packed<Pack<double, 16>>(model, x, x.data(), v, C.data());
}

void constraint_values(const Model& model, const Points& x, std::vector<double>& C) {
  constraint_values(constraint_runs(model), model, x, C);
}

void constraint_values_sse2(const Model& model, const Points& x, std::vector<double>& C) {
  const ConstraintRuns runs = constraint_runs(model);
  C.resize(model.constraints.size());
  detail::constraint_values_packed<Pack<double, 16>>(model, x, x.data(), view_of(runs, model), C.data());
}


}  // namespace pbdbench
