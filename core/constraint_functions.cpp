#include "core/constraint_functions.hpp"

#include <algorithm>
#include <cmath>

#include "core/fem.hpp"

namespace pbdbench {

ConstraintEval eval_distance(const Vec3& x0, const Vec3& x1, double rest) {
  ConstraintEval e;
  const Vec3 d = x1 - x0;
  const double len = d.norm();
  e.C = len - rest;
  if (!(len > 0.0)) {
    e.valid = false;
    return e;
  }
  const Vec3 n = d / len;
  e.grad[0] = -n;
  e.grad[1] = n;
  return e;
}

double tet_signed_volume(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  return (x1 - x0).dot((x2 - x0).cross(x3 - x0)) / 6.0;
}

ConstraintEval eval_volume(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                           double rest) {
  ConstraintEval e;
  const Vec3 e1 = x1 - x0, e2 = x2 - x0, e3 = x3 - x0;
  e.C = e1.dot(e2.cross(e3)) / 6.0 - rest;
  e.grad[1] = e2.cross(e3) / 6.0;
  e.grad[2] = e3.cross(e1) / 6.0;
  e.grad[3] = e1.cross(e2) / 6.0;
  e.grad[0] = -(e.grad[1] + e.grad[2] + e.grad[3]);
  e.valid = e.grad[0].squaredNorm() + e.grad[1].squaredNorm() + e.grad[2].squaredNorm() +
                e.grad[3].squaredNorm() > 0.0;
  return e;
}

double dihedral_angle(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  const Vec3 e = x1 - x0;
  const Vec3 c1 = e.cross(x2 - x0), c2 = e.cross(x3 - x0);
  const double d = std::clamp(c1.normalized().dot(c2.normalized()), -1.0, 1.0);
  return std::acos(d);
}

ConstraintEval eval_bending(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                            double rest) {
  // d = n1 . n2 with n_k = c_k / |c_k|, c1 = e x a, c2 = e x b, e = x1-x0, a = x2-x0, b = x3-x0.
  // dd/dc1 = (I - n1 n1^T) n2 / |c1| =: g1, dd/dc2 = (I - n2 n2^T) n1 / |c2| =: g2.
  // Since c1 . g1 = e . (a x g1) = a . (g1 x e):
  //   dd/da = g1 x e,  dd/db = g2 x e,  dd/de = a x g1 + b x g2.
  // Hence dd/dx2 = g1 x e, dd/dx3 = g2 x e, dd/dx1 = a x g1 + b x g2, dd/dx0 = -(sum).
  // C = acos(d) - rest, dC/dx = -dd/dx / sqrt(1 - d^2).
  ConstraintEval e;
  const Vec3 edge = x1 - x0, a = x2 - x0, b = x3 - x0;
  const Vec3 c1 = edge.cross(a), c2 = edge.cross(b);
  const double l1 = c1.norm(), l2 = c2.norm();
  if (!(l1 > 0.0) || !(l2 > 0.0)) {
    e.C = -rest;  // a degenerate triangle has no normal: report the angle as 0
    e.valid = false;
    return e;
  }
  const Vec3 n1 = c1 / l1, n2 = c2 / l2;
  const double d_raw = n1.dot(n2);
  const double d = std::clamp(d_raw, -1.0, 1.0);
  e.C = std::acos(d) - rest;
  const double s2 = 1.0 - d * d;
  if (s2 < 1e-12) {
    e.valid = false;
    return e;
  }
  const Vec3 g1 = (n2 - n1 * d_raw) / l1;
  const Vec3 g2 = (n1 - n2 * d_raw) / l2;
  const double f = -1.0 / std::sqrt(s2);
  e.grad[2] = f * g1.cross(edge);
  e.grad[3] = f * g2.cross(edge);
  e.grad[1] = f * (a.cross(g1) + b.cross(g2));
  e.grad[0] = -(e.grad[1] + e.grad[2] + e.grad[3]);
  return e;
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

double normalized_error(const Constraint& c, double C) {
  switch (c.kind) {
    case ConstraintKind::Distance:
    case ConstraintKind::Volume:
      return std::abs(c.rest) > 0.0 ? std::abs(C) / std::abs(c.rest) : std::abs(C);
    case ConstraintKind::Bending:
    case ConstraintKind::FemDeviatoric:
    case ConstraintKind::FemHydrostatic:
    case ConstraintKind::FemStrainTriangle:
    case ConstraintKind::FemStrainTet:
      return std::abs(C);
  }
  return std::abs(C);
}

}  // namespace pbdbench
