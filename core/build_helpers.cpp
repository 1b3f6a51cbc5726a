#include "core/build_helpers.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "core/constraint_functions.hpp"

namespace pbdbench::core::detail {

std::string format_number(double v, int digits) {
  std::ostringstream s;
  s.precision(digits);
  s << v;
  return s.str();
}

std::string format_vec3(const Vec3& v, int digits) {
  std::ostringstream s;
  s.precision(digits);
  s << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return s.str();
}

void require_min(const std::string& field, int value, int minimum) {
  if (value < minimum)
    throw std::invalid_argument(field + " = " + std::to_string(value) + " is below the minimum " +
                                std::to_string(minimum));
}

void require_positive(const std::string& field, double value, int digits) {
  if (!(value > 0.0) || !std::isfinite(value))
    throw std::invalid_argument(field + " = " + format_number(value, digits) +
                                " must be finite and above 0");
}

void require_non_negative(const std::string& field, double value, int digits) {
  if (!(value >= 0.0) || !std::isfinite(value))
    throw std::invalid_argument(field + " = " + format_number(value, digits) +
                                " must be finite and at least 0");
}

void require_finite(const std::string& field, const Vec3& value, int digits) {
  if (!value.allFinite())
    throw std::invalid_argument(field + " = " + format_vec3(value, digits) + " is not finite");
}

void require_params(const std::string& field, const ConstraintParams& p, int digits) {
  require_non_negative(field + ".compliance", p.compliance, digits);
  if (!(p.stiffness >= 0.0 && p.stiffness <= 1.0))
    throw std::invalid_argument(field + ".stiffness = " + format_number(p.stiffness, digits) +
                                " is outside [0, 1]");
  require_non_negative(field + ".damping", p.damping, digits);
}

int append_particles(Model& model, const Points& positions, const std::vector<double>& masses,
                     double radius) {
  const int begin = model.particle_count();
  const int k = static_cast<int>(positions.rows());
  model.rest_positions.conservativeResize(begin + k, 3);
  model.rest_positions.bottomRows(k) = positions;
  for (int i = 0; i < k; ++i) {
    model.inv_mass.push_back(1.0 / masses[static_cast<size_t>(i)]);
    model.radius.push_back(radius);
  }
  return begin;
}

Constraint make_constraint(ConstraintKind kind, std::array<int, 4> particles, double rest,
                           const ConstraintParams& p, std::uint16_t group) {
  Constraint c;
  c.kind = kind;
  c.particles = particles;
  c.rest = rest;
  c.compliance = p.compliance;
  c.stiffness = p.stiffness;
  c.damping = p.damping;
  c.group = group;
  return c;
}

void add_distance(Model& model, int a, int b, const ConstraintParams& p, std::uint16_t group) {
  const Vec3 xa = model.rest_positions.row(a), xb = model.rest_positions.row(b);
  model.constraints.push_back(
      make_constraint(ConstraintKind::Distance, {a, b, -1, -1}, (xb - xa).norm(), p, group));
}

void add_dihedral_bending(Model& model, const std::vector<std::array<int, 3>>& triangles,
                          const ConstraintParams& p, std::uint16_t group) {
  struct Wing {
    int from, to, opposite;
  };
  std::map<std::pair<int, int>, std::vector<Wing>> wings;
  for (const auto& t : triangles) {
    for (int e = 0; e < 3; ++e) {
      const int a = t[static_cast<size_t>(e)], b = t[static_cast<size_t>((e + 1) % 3)];
      const int c = t[static_cast<size_t>((e + 2) % 3)];
      wings[{std::min(a, b), std::max(a, b)}].push_back({a, b, c});
    }
  }
  for (const auto& [edge, w] : wings) {
    if (w.size() != 2) continue;
    const std::array<int, 4> q{w[0].from, w[0].to, w[0].opposite, w[1].opposite};
    const Vec3 x0 = model.rest_positions.row(q[0]), x1 = model.rest_positions.row(q[1]);
    const Vec3 x2 = model.rest_positions.row(q[2]), x3 = model.rest_positions.row(q[3]);
    model.constraints.push_back(
        make_constraint(ConstraintKind::Bending, q, dihedral_angle(x0, x1, x2, x3), p, group));
  }
}

}  // namespace pbdbench::core::detail
