// Metrics: pure functions of (model, state), the same code whatever solver produced the state.
// One `Sample` is one row of the run file's series (runfile/series.hpp declares the columns).
#pragma once

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"

namespace pbdbench {

// What measure() reads of each constraint, in arrays of their own, built once by
// measure_baseline (metrics/metrics.cpp).
struct MetricsTable;

// Quantities of the initial state that later samples are measured against.
struct MetricsBaseline {
  double tet_volume = 0.0;      // m^3, sum of signed tet volumes at t = 0
  double surface_volume = 0.0;  // m^3, enclosed volume of the closed surface at t = 0
  double extent = 0.0;          // m, max distance of a particle from the centroid at t = 0
  Vec3 centroid = Vec3::Zero();  // m, the particles' centroid at t = 0 (distance_from_start_max)
  // Whether the scene's physical material (its compliances and FEM elements) is the material
  // the run simulates, so that elastic_energy is defined (solvers/pbd_material.hpp,
  // elastic_energy_defined: not for pbd with an explicit k, nor for pbd-seed's k). Set by the
  // runner; measure_baseline leaves it true.
  bool elastic_defined = true;
  // The model constraints that touch a particle with inv_mass 0 (support_force's sum), listed
  // once by measure_baseline; when not listed, measure finds them in every sample.
  std::vector<int> support_constraints;
  bool supports_listed = false;
  // The constraints as measure() reads them (their runs of one kind, particles, rest values,
  // error scales, compliances and groups: 40 to 50 bytes a constraint, read once a sample, where
  // the Constraint records have 64, read twice), for
  // this model; when absent, measure builds it for the sample.
  std::shared_ptr<const MetricsTable> table;
};

MetricsBaseline measure_baseline(const Model& model, const State& initial);

struct GroupError {
  double max = 0.0;  // max over the group's constraints of normalized_error (core/constraint_functions.hpp)
  double rms = 0.0;  // root mean square of the same
  int count = 0;     // constraints in the group
  // The FEM kinds count like the others, by constraint_error() below.
};

// The error of one constraint as the metrics report it: normalized_error
// (core/constraint_functions.hpp) for distance, volume and bending; for the FEM kinds, the
// deviation of the constraint function from its value at the element's rest shape (F = I),
// relative to that value where it is not 0:
//   fem_deviatoric   |sqrt(tr F^T F) - sqrt(d)| / sqrt(d)   (d = 3 for a tet, 2 for a triangle)
//   fem_hydrostatic  |det F - 1|                            (the element's relative volume change)
//   fem_strain_*     |strain vector| (Green or linear strain, 0 at rest)
// so that a collapsing FEM block never reads 0. NaN for an FEM constraint without its element.
double constraint_error(const Model& model, const Constraint& c, const Points& x);

struct Sample {
  // Constraint error over the model's constraints, normalised per kind (relative to rest length
  // or volume; radians for bending; FEM kinds: constraint_error below), overall and per group
  // (indexed like Model::group_names).
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
  // elastic: the energy of the scene's physical material, the same formula whatever the solver:
  // sum over compliant constraints (alpha > 0) of C^2 / (2 alpha), the FEM kinds left out, plus
  // sum over FEM elements of V0 (Psi(F) - Psi(I)) (fem::element_energy, which stands for the
  // FEM-kind constraints too); rigid constraints (alpha = 0) store none. NaN (and total NaN)
  // when the run does not simulate that material (MetricsBaseline::elastic_defined: pbd with an
  // explicit k, pbd-seed). total = their sum.
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

  // Failure detectors (see the functions below). height_min and sunk_* are NaN / 0 when the
  // state is not finite; velocity_hf_rms needs two earlier velocities, which only the runner
  // has: measure() leaves it NaN and the runner fills it from row 2 on.
  double height_min = std::numeric_limits<double>::quiet_NaN();  // m
  int sunk_count = 0;                                            // particles
  double sunk_depth = 0.0;                                       // m
  double velocity_hf_rms = std::numeric_limits<double>::quiet_NaN();  // m/s
  // What the run health's detectors read (metrics/health.hpp), not logged as series:
  //   link_stretch_max         the largest |d - d0| / d0 over the distance constraints with
  //                            d0 > 0 (0 without; NaN when a constraint error is NaN)
  //   tets_inverted            tets (Model::tets, positively oriented at rest) whose signed
  //                            volume is negative
  //   distance_from_start_max  the largest distance of a dynamic particle from the initial
  //                            centroid (MetricsBaseline::centroid), m; NaN when a dynamic
  //                            position is not finite
  double link_stretch_max = 0.0;                                             // 1
  int tets_inverted = 0;                                                     // tets
  double distance_from_start_max = 0.0;                                      // m

  // Explosion indicators.
  double max_speed = 0.0;  // m/s over all particles (NaN when a velocity is not finite)
  double extent = 0.0;     // m, max distance of a particle from the current centroid
  bool finite = true;      // every position and velocity finite

  // Observables of the scene (Model::observables); NaN where the scene has none or the state
  // cannot give them. See the functions below.
  Vec3 tip_displacement = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());  // m
  Vec3 support_force = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());     // N
  double pendulum_angle = std::numeric_limits<double>::quiet_NaN();                  // rad
};

Sample measure(const Model& model, const State& state, const MetricsBaseline& baseline);

// Mean position of the tip particles (Model::observables.tip) minus their mean rest position
// (m). NaN when the model has no tip.
Vec3 tip_displacement(const Model& model, const State& state);

// The force the supports exert on the body (N): minus the sum, over the particles with
// inv_mass 0 (pinned or kinematic), of the constraint forces on them, grad_i C_j(x) lambda_j
// (State::lambda's convention) over the model constraints j touching them. A chain hanging at
// rest gets its weight, upward. 0 when no constraint touches such a particle (nothing pinned).
// NaN when any lambda involved is NaN (solvers without multipliers), in the initial state
// (state.step == 0: no step has computed the multipliers yet), when state.lambda does not have
// one entry per constraint, when a gradient involved is undefined (with lambda != 0), and when
// an FEM element touches a support (its forces are not in lambda). Contacts and colliders are
// not supports here.
Vec3 support_force(const Model& model, const State& state);
// The same over the given constraints, those of the model that touch a support, in model order
// (MetricsBaseline::support_constraints).
Vec3 support_force(const Model& model, const State& state, const std::vector<int>& touching);

// The signed angle (rad) of the pendulum's bob (Model::observables.bob) about the pivot, from
// the gravity direction g^: with d = x_bob - pivot and e = the unit vector of +x with its
// component along g^ removed, atan2(d . e, d . g^), in (-pi, pi], positive towards +x. The
// component of d out of the plane of g^ and +x is ignored. NaN without a bob, without gravity, or
// when gravity is along x.
double pendulum_angle(const Model& model, const State& state);

// The lowest dynamic particle (inv_mass != 0): min_i up . x_i (m), up = up_direction(model)
// (-gravity / |gravity|, or +y without gravity). A cloth that has sunk below a ground y = 0
// shows a negative value whatever its collider says. NaN without dynamic particles or when a
// dynamic position is not finite.
double height_min(const Model& model, const State& state);

// Dynamic particles (inv_mass != 0) whose centre is on the forbidden side of a collider's
// surface, the particle radius ignored (unlike penetration_*, which counts radius overlaps):
//   plane:          (n . x + offset) / |n| < 0                       depth -(n . x + offset) / |n|
//   sphere outside: |x - c(t)| < R                                   depth R - |x - c(t)|
//   sphere inside:  |x - c(t)| > R                                   depth |x - c(t)| - R
//   bowl:           as inside, only where (x - c(t)) . up < 0 (core/contacts.hpp)
//   mesh:           -s(x - offset(t)), s the mesh's signed distance (core/mesh_collider.hpp)
// count: particles sunk into at least one collider; depth: the largest depth over particles and
// colliders (m, 0 when none). A particle whose position is not finite is not counted, and makes
// depth NaN.
struct SunkParticles {
  int count = 0;
  double depth = 0.0;  // m
};
SunkParticles sunk_particles(const Model& model, const State& state);

// The high-frequency content of the velocities ("jitter"), from the velocities after three
// consecutive steps v_n, v_{n-1}, v_{n-2} (each n x 3, m/s):
//   sqrt( mean over dynamic particles (inv_mass != 0) of |v_n - 2 v_{n-1} + v_{n-2}|^2 ) / 4.
// The second difference is 4a for a velocity alternating +a, -a, +a, hence the 1/4: that reads
// |a|; it is 0 for a velocity that changes linearly in time (constant acceleration). NaN
// without dynamic particles.
double velocity_hf_rms(const Model& model, const Points& v_n, const Points& v_n1, const Points& v_n2);

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
