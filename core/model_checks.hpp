// Checks that a Model is physically meaningful before anything runs on it.
#pragma once

#include <string>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"

namespace pbdbench {

struct ModelProblem {
  std::string what;  // e.g. "particle 12: inverse mass -1 is negative"
};

// Every problem found, in a stable order; empty when the model is sound. Checks: finite
// positions, radii > 0, inverse masses finite and >= 0, indices in range and distinct within a
// constraint or element, rest lengths of distance constraints >= 0, compliance, stiffness and
// damping in range, degenerate tets (|volume| tiny relative to their edge lengths) and triangles,
// attached particles with inv_mass 0, motion and collider indices valid, plane normals non-zero,
// sphere radii > 0, finite gravity.
// `free_inverse_mass`: particles whose inverse mass was set on purpose (a scene defect,
// defects.inverse_mass_*): any finite value is accepted for them, negative included.
std::vector<ModelProblem> check_model(const Model& model, const std::vector<int>& free_inverse_mass = {});

// Every problem of a state for this model: sizes, finite values.
std::vector<ModelProblem> check_state(const Model& model, const State& state);

}  // namespace pbdbench
