// The gap between a run's step and its shadow: the same step solved by a global solver from the
// same start (shadow.solver; harness/runner.cpp), measured on the two end states. NaN in every
// field on the steps without a shadow solve.
#pragma once

#include <limits>

#include "core/model.hpp"
#include "core/state.hpp"

namespace pbdbench {

struct ShadowSample {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double gap = kNaN;              // kg^1/2 m: |x_run - x*|_M = sqrt(sum m_i |x_run,i - x*_i|^2)
                                  // over the dynamic particles
  double gap_rms = kNaN;          // m: gap / sqrt(total dynamic mass), the mass-weighted RMS
  double gap_max = kNaN;          // m: max_i |x_run,i - x*_i|
  double error_max = kNaN;        // the shadow's constraint_error_max (metrics/metrics.hpp)
  double force_error = kNaN;      // |F - F*| / |F*| of the support force (metrics/metrics.hpp,
                                  // support_force) of the run's step against the shadow's: how
                                  // far the multipliers are from the converged step's forces;
                                  // NaN when the scene has no support force or |F*| = 0
  double residual_g = kNaN;       // the shadow's |g|_2, kg m
  double residual_h = kNaN;       // the shadow's |h|_2, units of C
  double residual_position = kNaN;  // the shadow's KKT residual in position units, m
  double iterations = kNaN;       // the shadow's outer (Newton) iterations
  double time = kNaN;             // s, wall time of the shadow's step
  double cost_ratio = kNaN;       // shadow time / the run's step time
};

// gap, gap_rms, gap_max, error_max and force_error of `run` against `shadow` (same model). The
// report fields (residuals, iterations, times) are the caller's to fill.
ShadowSample measure_shadow(const Model& model, const State& run, const State& shadow);

}  // namespace pbdbench
