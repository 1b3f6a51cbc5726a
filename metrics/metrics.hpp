// Metrics: pure functions of (model, state), the same code whatever solver produced the state.
// One `Sample` is one row of the run file's series (runfile/series.hpp declares the columns).
#pragma once

#include <string>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"

namespace pbdbench {

// Quantities of the initial state that later samples are measured against.
struct MetricsBaseline {
  double tet_volume = 0.0;      // m^3, sum of signed tet volumes at t = 0
  double surface_volume = 0.0;  // m^3, enclosed volume of the closed surface at t = 0
  double extent = 0.0;          // m, max distance of a particle from the centroid at t = 0
};

MetricsBaseline measure_baseline(const Model& model, const State& initial);

struct GroupError {
  double max = 0.0;  // max over the group's constraints of normalized_error (core/constraint_functions.hpp)
  double rms = 0.0;  // root mean square of the same
  int count = 0;     // constraints in the group
};

struct Sample {
  // Constraint error over the model's constraints, normalised per kind (relative to rest length
  // or volume; radians for bending), overall and per group (indexed like Model::group_names).
  double constraint_error_max = 0.0;
  double constraint_error_rms = 0.0;
  std::vector<GroupError> groups;

  // Volume: total signed tet volume and the enclosed volume of the closed surface, each with its
  // drift (V - V0) / V0. NaN where the model has no tets / no closed surface.
  double tet_volume = 0.0;            // m^3
  double volume_drift = 0.0;          // 1
  double surface_volume = 0.0;        // m^3
  double surface_volume_drift = 0.0;  // 1

  // Energy of the dynamic particles (inv_mass > 0): kinetic 1/2 m v^2, gravitational -m g . x,
  // elastic sum over compliant constraints (alpha > 0) of C^2 / (2 alpha); total = their sum.
  double kinetic_energy = 0.0;    // J
  double potential_energy = 0.0;  // J
  double elastic_energy = 0.0;    // J
  double total_energy = 0.0;      // J

  // Momentum of the dynamic particles; angular about the origin.
  Vec3 linear_momentum = Vec3::Zero();   // kg m/s
  Vec3 angular_momentum = Vec3::Zero();  // kg m^2/s

  // Penetration against colliders and between particles (contacts with C < 0, margin 0).
  double penetration_max = 0.0;  // m, deepest penetration (0 when none)
  int penetration_count = 0;     // contacts in penetration

  // Explosion indicators.
  double max_speed = 0.0;  // m/s over all particles (NaN when a velocity is not finite)
  double extent = 0.0;     // m, max distance of a particle from the current centroid
  bool finite = true;      // every position and velocity finite
};

Sample measure(const Model& model, const State& state, const MetricsBaseline& baseline);

// When a run counts as exploded. Keys of the [limits] table.
struct ExplosionLimits {
  double max_speed = 1e3;         // limits.max_speed: m/s
  double max_extent_ratio = 1e2;  // limits.max_extent_ratio: extent / max(initial extent, 1e-3 m)
  double max_distance = 1e4;      // limits.max_distance: m from the origin
};

// Empty when the sample is within the limits, else why not, e.g.
// "non-finite position of particle 12", "max speed 1.2e+05 m/s exceeds limits.max_speed = 1000".
std::string explosion_reason(const Model& model, const State& state, const Sample& sample,
                             const ExplosionLimits& limits, const MetricsBaseline& baseline);

}  // namespace pbdbench
