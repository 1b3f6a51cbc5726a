#include "runfile/series.hpp"

#include <array>
#include <sstream>

namespace pbdbench {

namespace {

// Accessors: each writes `width` values of one series from a row. Non-capturing lambdas, so
// they convert to the plain function pointers the table holds.
using Read = void (*)(const SeriesRow&, double*);

#define PBDBENCH_SAMPLE(field) \
  [](const SeriesRow& r, double* out) { out[0] = static_cast<double>(r.sample->field); }
#define PBDBENCH_SAMPLE3(field)                                                         \
  [](const SeriesRow& r, double* out) {                                                 \
    for (int k = 0; k < 3; ++k) out[k] = r.sample->field[k];                            \
  }
#define PBDBENCH_REPORT(field) \
  [](const SeriesRow& r, double* out) { out[0] = static_cast<double>(r.report->field); }
#define PBDBENCH_SHADOW(field)                                                            \
  [](const SeriesRow& r, double* out) {                                                   \
    out[0] = r.shadow != nullptr ? r.shadow->field : ShadowSample::kNaN;                  \
  }

const std::array kSeries = {
    // Time.
    SeriesSpec{"time", "s", "simulated time after the step (0 for the initial row)", 1, true,
               [](const SeriesRow& r, double* out) { out[0] = r.time; }},
    SeriesSpec{"step", "1", "steps taken (0 for the initial row)", 1, true,
               [](const SeriesRow& r, double* out) { out[0] = static_cast<double>(r.step); }},

    // Constraint error.
    SeriesSpec{"constraint_error_max", "1",
               "max over all constraints of the normalised error: |C|/|rest| for distance and "
               "volume (|C| when rest = 0), |C| in rad for bending, the FEM kinds' deviation from "
               "their rest value (|det F - 1| for fem_hydrostatic; metrics/metrics.hpp)",
               1, true, PBDBENCH_SAMPLE(constraint_error_max)},
    SeriesSpec{"constraint_error_rms", "1",
               "root mean square over all constraints of the same normalised error", 1, true,
               PBDBENCH_SAMPLE(constraint_error_rms)},

    // Volume.
    SeriesSpec{"tet_volume", "m^3", "sum of signed tet volumes (NaN without tets)", 1, true,
               PBDBENCH_SAMPLE(tet_volume)},
    SeriesSpec{"volume_drift", "1", "(tet_volume - V0) / |V0| (NaN without tets)", 1, true,
               PBDBENCH_SAMPLE(volume_drift)},
    SeriesSpec{"surface_volume", "m^3",
               "volume enclosed by the closed surface (NaN without a closed surface)", 1, true,
               PBDBENCH_SAMPLE(surface_volume)},
    SeriesSpec{"surface_volume_drift", "1",
               "(surface_volume - V0) / |V0| (NaN without a closed surface)", 1, true,
               PBDBENCH_SAMPLE(surface_volume_drift)},

    // Energy of the dynamic particles.
    SeriesSpec{"kinetic_energy", "J", "sum of 1/2 m v^2 over dynamic particles", 1, true,
               PBDBENCH_SAMPLE(kinetic_energy)},
    SeriesSpec{"potential_energy", "J", "gravitational energy -m g . x of dynamic particles", 1,
               true, PBDBENCH_SAMPLE(potential_energy)},
    SeriesSpec{"elastic_energy", "J",
               "the scene's physical material's energy, the same for every solver: sum of C^2 / "
               "(2 alpha) over compliant constraints (alpha > 0) plus the FEM elements' energy; NaN "
               "where the run does not simulate that material (pbd with an explicit k, pbd-seed)",
               1, true,
               PBDBENCH_SAMPLE(elastic_energy)},
    SeriesSpec{"total_energy", "J", "kinetic + potential + elastic", 1, true,
               PBDBENCH_SAMPLE(total_energy)},

    // Momentum of the dynamic particles.
    SeriesSpec{"linear_momentum", "kg m/s", "sum of m v over dynamic particles", 3, true,
               PBDBENCH_SAMPLE3(linear_momentum)},
    SeriesSpec{"angular_momentum", "kg m^2/s",
               "sum of m (x cross v) over dynamic particles, about the origin", 3, true,
               PBDBENCH_SAMPLE3(angular_momentum)},

    // Penetration.
    SeriesSpec{"penetration_max", "m", "deepest penetration of any contact (0 when none)", 1,
               true, PBDBENCH_SAMPLE(penetration_max)},
    SeriesSpec{"penetration_count", "1", "contacts in penetration", 1, true,
               PBDBENCH_SAMPLE(penetration_count)},

    // Failure detectors (metrics/metrics.hpp: height_min, sunk_particles, velocity_hf_rms).
    SeriesSpec{"height_min", "m",
               "min over dynamic particles (inv_mass != 0) of up . x, up = -gravity/|gravity| (+y "
               "without gravity): below 0 is below a ground y = 0 (NaN without dynamic particles)",
               1, true, PBDBENCH_SAMPLE(height_min)},
    SeriesSpec{"sunk_count", "1",
               "dynamic particles whose centre is on the forbidden side of a collider's surface "
               "(radius ignored, unlike penetration_count)",
               1, true, PBDBENCH_SAMPLE(sunk_count)},
    SeriesSpec{"sunk_depth", "m",
               "largest depth of a dynamic particle's centre past a collider's surface (0 when "
               "none)",
               1, true, PBDBENCH_SAMPLE(sunk_depth)},
    SeriesSpec{"velocity_hf_rms", "m/s",
               "jitter: sqrt(mean over dynamic particles of |v_n - 2 v_n-1 + v_n-2|^2) / 4, v_n "
               "the velocities after step n (an alternating +a/-a reads |a|; NaN in rows 0 and 1)",
               1, true, PBDBENCH_SAMPLE(velocity_hf_rms)},

    // Explosion indicators.
    SeriesSpec{"max_speed", "m/s", "max particle speed (NaN when a velocity is not finite)", 1,
               true, PBDBENCH_SAMPLE(max_speed)},
    SeriesSpec{"extent", "m", "max distance of a particle from the centroid", 1, true,
               PBDBENCH_SAMPLE(extent)},

    // Observables of the scene (Model::observables; metrics/metrics.hpp says how each is taken).
    SeriesSpec{"tip_displacement", "m",
               "mean position of the tip particles minus their mean rest position (NaN without a "
               "tip)",
               3, true, PBDBENCH_SAMPLE3(tip_displacement)},
    SeriesSpec{"support_force", "N",
               "force of the supports (particles with inv_mass 0) on the body: minus the sum of "
               "grad_i C lambda over the constraints touching them (NaN when the solver keeps no "
               "multipliers, e.g. pbd, in the initial row, or when an FEM element touches a "
               "support; 0 when nothing is pinned)",
               3, true, PBDBENCH_SAMPLE3(support_force)},
    SeriesSpec{"pendulum_angle", "rad",
               "signed angle of the bob about the pivot from the gravity direction, positive "
               "towards +x (NaN without a bob)",
               1, true, PBDBENCH_SAMPLE(pendulum_angle)},

    // What the step did (StepReport; 0 or NaN for the initial row).
    SeriesSpec{"substeps", "1", "substeps taken in the step", 1, true, PBDBENCH_REPORT(substeps)},
    SeriesSpec{"iterations", "1", "projection sweeps summed over substeps", 1, true,
               PBDBENCH_REPORT(iterations)},
    SeriesSpec{"contacts", "1", "contact constraints built, summed over substeps", 1, true,
               PBDBENCH_REPORT(contacts)},
    SeriesSpec{"active_contacts", "1",
               "contacts with C < 0 at some projection, summed over substeps", 1, true,
               PBDBENCH_REPORT(active_contacts)},
    SeriesSpec{"skipped", "1",
               "projections skipped (undefined gradient or zero generalised mass), summed", 1,
               true, PBDBENCH_REPORT(skipped)},
    SeriesSpec{"stop_reason", "1",
               "why the step's solve stopped, the worst of its substeps: 0 none (the initial "
               "row), 1 fixed_work (pbd-seed, pbd, xpbd, force-symplectic), 2 converged, 3 "
               "iteration_limit, 4 stalled, 5 line_search_failed, 6 linear_solver_failed (3-6: "
               "not trusted, counted in the run's warnings; solver_api/solver.hpp StopReason)",
               1, true, PBDBENCH_REPORT(stop)},
    SeriesSpec{"residual_g", "kg m",
               "XPBD residual |M (x - x~) - grad C^T lambda|_2 at the end of the step (NaN "
               "when the solver does not define it)",
               1, true, PBDBENCH_REPORT(residual_g)},
    SeriesSpec{"residual_h", "mixed",
               "XPBD residual |C(x) + alpha~ lambda|_2 in the units of the constraints (NaN "
               "when the solver does not define it)",
               1, true, PBDBENCH_REPORT(residual_h)},

    // The reference integrators' account of the step (0, or NaN for the drift, for the PBD
    // family).
    SeriesSpec{"ref_steps", "1", "internal integrator steps taken to advance by the step", 1, true,
               PBDBENCH_REPORT(ref_steps)},
    SeriesSpec{"newton_iterations", "1", "nonlinear (Newton) iterations in the step", 1, true,
               PBDBENCH_REPORT(newton_iterations)},
    SeriesSpec{"linear_setups", "1", "Jacobian evaluations and factorisations in the step", 1,
               true, PBDBENCH_REPORT(linear_setups)},
    SeriesSpec{"linear_solves", "1", "linear solves with a factorisation in the step", 1, true,
               PBDBENCH_REPORT(linear_solves)},
    SeriesSpec{"error_test_failures", "1", "internal steps rejected by the local error test", 1,
               true, PBDBENCH_REPORT(error_test_failures)},
    SeriesSpec{"convergence_failures", "1", "nonlinear solves that did not converge", 1, true,
               PBDBENCH_REPORT(convergence_failures)},
    SeriesSpec{"cholesky_factorizations", "1",
               "of the linear setups, Cholesky factorisations of the reduced Newton matrix", 1,
               true, PBDBENCH_REPORT(cholesky_factorizations)},
    SeriesSpec{"lu_factorizations", "1",
               "of the linear setups, LU factorisations (the reduced matrix was indefinite or "
               "unsymmetric)",
               1, true, PBDBENCH_REPORT(lu_factorizations)},
    SeriesSpec{"linear_iterations", "1",
               "global solvers: conjugate-gradient (global-cg; global-cholmod's solves "
               "preconditioned with an earlier factorisation) or Levenberg-Marquardt "
               "(global-ceres) iterations in the step",
               1, true, PBDBENCH_REPORT(linear_iterations)},
    SeriesSpec{"factor_cost_ratio", "1",
               "global-cholmod: the flops of a Cholesky factorisation of the step's Newton matrix "
               "over those of one conjugate-gradient iteration preconditioned with it (4 nnz(L) "
               "+ 2 nnz(A)), from CHOLMOD's analysis; the factorisation is reused across Newton "
               "iterations where this is at least 2 (NaN otherwise)",
               1, true, PBDBENCH_REPORT(factor_cost_ratio)},
    SeriesSpec{"residual_position", "m",
               "global solvers: the KKT residual of the step's last substep in position units; "
               "ref-be with contact: the largest final Newton step of its substeps (NaN "
               "otherwise)",
               1, true, PBDBENCH_REPORT(residual_position)},
    SeriesSpec{"line_search_cuts", "1",
               "ref-be with contact: halvings of the Newton steps in the line search, after the "
               "collision check's bound, in the step",
               1, true, PBDBENCH_REPORT(line_search_cuts)},
    SeriesSpec{"barrier_energy", "J",
               "ref-be with contact: the IPC barrier potential kappa sum b(d) at the end of the "
               "step (NaN otherwise)",
               1, true, PBDBENCH_REPORT(barrier_energy)},
    SeriesSpec{"constraint_drift", "mixed",
               "max |C| of the rigid constraints at the end of the step, in their units (ref-dae; "
               "NaN otherwise)",
               1, true, PBDBENCH_REPORT(constraint_drift)},

    // The shadow (shadow.solver): the same step solved by a global solver from the same start
    // (metrics/shadow.hpp); NaN on the steps without one.
    SeriesSpec{"shadow_gap", "kg^1/2 m",
               "|x - x*|_M, the run's step against the shadow's converged step x* over the "
               "dynamic particles",
               1, true, PBDBENCH_SHADOW(gap)},
    SeriesSpec{"shadow_gap_rms", "m", "shadow_gap / sqrt(dynamic mass): the mass-weighted RMS "
               "distance from x*", 1, true, PBDBENCH_SHADOW(gap_rms)},
    SeriesSpec{"shadow_gap_max", "m", "max particle distance from x*", 1, true,
               PBDBENCH_SHADOW(gap_max)},
    SeriesSpec{"shadow_constraint_error_max", "1", "constraint_error_max of x*", 1, true,
               PBDBENCH_SHADOW(error_max)},
    SeriesSpec{"shadow_force_error", "1",
               "|F - F*| / |F*|: the run's support force against the shadow's (the forces of the "
               "converged step from the same start); NaN without a support force",
               1, true, PBDBENCH_SHADOW(force_error)},
    SeriesSpec{"shadow_residual_g", "kg m", "the shadow's residual_g at x*", 1, true,
               PBDBENCH_SHADOW(residual_g)},
    SeriesSpec{"shadow_residual_h", "mixed", "the shadow's residual_h at x*", 1, true,
               PBDBENCH_SHADOW(residual_h)},
    SeriesSpec{"shadow_residual_position", "m", "the shadow's residual_position at x*", 1, true,
               PBDBENCH_SHADOW(residual_position)},
    SeriesSpec{"shadow_iterations", "1", "the shadow's Newton (or augmented-Lagrangian) iterations",
               1, true, PBDBENCH_SHADOW(iterations)},
    SeriesSpec{"shadow_time", "s", "wall time of the shadow's step", 1, false,
               PBDBENCH_SHADOW(time)},
    SeriesSpec{"shadow_cost_ratio", "1", "shadow_time / wall_step, the shadow's cost in run steps",
               1, false, PBDBENCH_SHADOW(cost_ratio)},

    // Wall-clock timings: not deterministic.
    SeriesSpec{"time_predict", "s", "wall time in prediction, summed over substeps", 1, false,
               PBDBENCH_REPORT(time_predict)},
    SeriesSpec{"time_contacts", "s", "wall time in contact generation, summed over substeps", 1,
               false, PBDBENCH_REPORT(time_contacts)},
    SeriesSpec{"time_project", "s", "wall time in constraint projection, summed over substeps",
               1, false, PBDBENCH_REPORT(time_project)},
    SeriesSpec{"time_residual", "s",
               "wall time in xpbd's residuals g and h (solver.xpbd.residuals; 0 otherwise)", 1,
               false, PBDBENCH_REPORT(time_residual)},
    SeriesSpec{"time_velocity", "s", "wall time in the velocity update, summed over substeps", 1,
               false, PBDBENCH_REPORT(time_velocity)},
    SeriesSpec{"time_linear", "s",
               "wall time in Jacobian assembly, factorisation and linear solves (references)", 1,
               false, PBDBENCH_REPORT(time_linear)},
    SeriesSpec{"wall_step", "s", "wall time of the whole step", 1, false,
               [](const SeriesRow& r, double* out) { out[0] = r.wall_step; }},
};

#undef PBDBENCH_SAMPLE
#undef PBDBENCH_SAMPLE3
#undef PBDBENCH_REPORT
#undef PBDBENCH_SHADOW

const std::array kGroupSeries = {
    GroupSeriesSpec{"constraint_error_max_", "1",
                    "constraint_error_max over the constraints of one group",
                    [](const GroupError& g) { return g.max; }},
    GroupSeriesSpec{"constraint_error_rms_", "1",
                    "constraint_error_rms over the constraints of one group",
                    [](const GroupError& g) { return g.rms; }},
};

// Markdown table cells: a literal '|' would end the cell.
std::string cell(std::string_view text) {
  std::string out;
  for (char c : text) {
    if (c == '|') out += '\\';
    out += c;
  }
  return out;
}

}  // namespace

std::span<const SeriesSpec> series_table() { return kSeries; }

std::span<const GroupSeriesSpec> group_series_table() { return kGroupSeries; }

std::string series_markdown() {
  std::ostringstream md;
  md << "| name | shape | units | description |\n";
  md << "|---|---|---|---|\n";
  for (const SeriesSpec& s : series_table()) {
    md << "| `" << s.name << "` | " << (s.width == 1 ? "(rows,)" : "(rows, 3)") << " | "
       << cell(s.units) << " | " << cell(s.doc)
       << (s.deterministic ? "" : " (wall clock: not deterministic)") << " |\n";
  }
  for (const GroupSeriesSpec& g : group_series_table()) {
    md << "| `" << g.prefix << "<group>` | (rows,) | " << cell(g.units) << " | " << cell(g.doc)
       << ", one dataset per group of /model group_names |\n";
  }
  return md.str();
}

}  // namespace pbdbench
