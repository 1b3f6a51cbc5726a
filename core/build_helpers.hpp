// Helpers shared by the model builders of core/ (generators.cpp, mesh_io.cpp) and by the model
// checks (model_checks.cpp): numbers in messages, spec checks, and appending particles and
// constraints to a Model. Not part of the module's interface.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/generators.hpp"
#include "core/model.hpp"

namespace pbdbench::core::detail {

// ---------------------------------------------------------------------------------------------
// Numbers in messages.

// Significant digits of a number in a message: 17 writes any double exactly (the generators'
// spec checks); 6 is the short form (mesh import, model checks).
inline constexpr int kExactDigits = 17;
inline constexpr int kShortDigits = 6;

// v as an output stream writes it with `digits` significant digits ("0.1", "1e-12").
std::string format_number(double v, int digits);

// "(x, y, z)", each coordinate as format_number writes it.
std::string format_vec3(const Vec3& v, int digits);

// The first `count` entries of p separated by spaces: "3 7 12".
template <size_t K>
std::string index_list(const std::array<int, K>& p, int count) {
  std::string s;
  for (int k = 0; k < count; ++k) {
    if (k > 0) s += ' ';
    s += std::to_string(p[static_cast<size_t>(k)]);
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// Spec checks. Each throws std::invalid_argument reading "<field> = <value> <what is wrong>",
// the value written with `digits` significant digits.

void require_min(const std::string& field, int value, int minimum);
void require_positive(const std::string& field, double value, int digits = kExactDigits);
void require_non_negative(const std::string& field, double value, int digits = kExactDigits);
void require_finite(const std::string& field, const Vec3& value, int digits = kExactDigits);
// field.compliance >= 0 and finite, field.stiffness in [0, 1], field.damping >= 0 and finite.
void require_params(const std::string& field, const ConstraintParams& p,
                    int digits = kExactDigits);

// ---------------------------------------------------------------------------------------------
// Building blocks.

// Appends particles at `positions` (k x 3, m) with the given masses (k, kg, > 0) and radius (m);
// returns the index of the first one.
int append_particles(Model& model, const Points& positions, const std::vector<double>& masses,
                     double radius);

Constraint make_constraint(ConstraintKind kind, std::array<int, 4> particles, double rest,
                           const ConstraintParams& p, std::uint16_t group);

// A distance constraint between a and b, rest length from the model's rest positions.
void add_distance(Model& model, int a, int b, const ConstraintParams& p, std::uint16_t group);

// Dihedral bending constraints on every edge shared by exactly two of `triangles` (model
// indices), in the order of the edges' sorted vertex pairs. x0, x1 is the edge as the first
// triangle traverses it; x2 the first triangle's third vertex, x3 the second's. Rest angles from
// the model's rest positions.
void add_dihedral_bending(Model& model, const std::vector<std::array<int, 3>>& triangles,
                          const ConstraintParams& p, std::uint16_t group);

}  // namespace pbdbench::core::detail
