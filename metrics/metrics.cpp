#include "metrics/metrics.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <memory>
#include <limits>
#include <sstream>
#include <vector>

#include "core/constraint_functions.hpp"
#include "core/contacts.hpp"
#include "core/fem.hpp"

namespace pbdbench {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The sum of the tets' signed volumes; `inverted` (when given) gets the number of tets whose
// signed volume is negative (Model::tets are positively oriented at rest: such a tet has turned
// inside out).
double total_tet_volume(const Model& model, const Points& x, int* inverted = nullptr) {
  double v = 0.0;
  int turned = 0;
  for (const auto& t : model.tets) {
    const double vt = tet_signed_volume(x.row(t[0]), x.row(t[1]), x.row(t[2]), x.row(t[3]));
    v += vt;
    turned += vt < 0.0;
  }
  if (inverted != nullptr) *inverted = turned;
  return v;
}

// Enclosed volume of a closed, outward-wound surface: (1/6) sum x0 . (x1 x2).
double enclosed_volume(const Model& model, const Points& x) {
  double v = 0.0;
  for (const auto& t : model.triangles) {
    const Vec3 a = x.row(t[0]), b = x.row(t[1]), c = x.row(t[2]);
    v += a.dot(b.cross(c));
  }
  return v / 6.0;
}

double max_distance_from_centroid(const Points& x) {
  if (x.rows() == 0) return 0.0;
  const Vec3 c = x.colwise().mean().transpose();
  // The largest squared distance, then its root: the root is correctly rounded and never
  // decreasing, so this is the largest of the roots, bit for bit, for one root instead of n.
  double d2 = 0.0;
  for (Eigen::Index i = 0; i < x.rows(); ++i) d2 = std::max(d2, (Vec3(x.row(i)) - c).squaredNorm());
  return std::sqrt(d2);
}

// measure's quantities of the particles (the energy and momentum, the finiteness of x and of v,
// the largest speed, the lowest particle) in one pass over x, v and the inverse masses, which
// are read from memory once a step instead of five times.
// Each quantity takes its particles in index order
// with the arithmetic it had in its own loop: the same bits.
struct ParticleScan {
  double kinetic = 0.0, potential = 0.0;
  Vec3 linear = Vec3::Zero(), angular = Vec3::Zero();
  bool finite = true;          // every coordinate of x and v
  double speed2_max = 0.0;     // max_i |v_i|^2 over every particle (meaningful where finite)
  double lowest = kNaN;        // min over dynamic particles of up . x_i (NaN: none)
  bool dynamic_finite = true;  // every dynamic particle's position finite
  double away2_max = 0.0;      // max over finite dynamic particles of |x_i - origin|^2
};

ParticleScan scan_particles(const Model& model, const Points& x, const Points& v, const Vec3& up,
                            const Vec3& origin = Vec3::Zero()) {
  ParticleScan out;
  const int n = model.particle_count();
  const double* w_of = model.inv_mass.data();
  constexpr double kMax = std::numeric_limits<double>::max();
  unsigned bad = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3 xi = x.row(i), vi = v.row(i);
    unsigned bad_x = 0;
    for (int k = 0; k < 3; ++k) {
      bad_x |= !(std::abs(xi[k]) <= kMax);
      bad |= !(std::abs(vi[k]) <= kMax);
    }
    bad |= bad_x;
    out.speed2_max = std::max(out.speed2_max, vi.squaredNorm());
    const double w = w_of[i];
    if (w == 0.0) continue;
    const double m = 1.0 / w;
    out.kinetic += 0.5 * m * vi.squaredNorm();
    out.potential -= m * model.gravity.dot(xi);
    out.linear += m * vi;
    out.angular += m * xi.cross(vi);
    if (bad_x) {
      out.dynamic_finite = false;
      continue;
    }
    const double h = up.dot(xi);
    if (std::isnan(out.lowest) || h < out.lowest) out.lowest = h;
    out.away2_max = std::max(out.away2_max, (xi - origin).squaredNorm());
  }
  out.finite = bad == 0;
  if (!out.dynamic_finite) out.lowest = kNaN;
  return out;
}

bool has_colliders(const Model& model) {
  return !model.planes.empty() || !model.spheres.empty() || !model.meshes.empty();
}

}  // namespace

double constraint_error(const Model& model, const Constraint& c, const Points& x) {
  if (!is_fem_kind(c.kind)) return normalized_error(c, eval_constraint(c, x).C);
  const ConstraintEval e = eval_constraint(model, c, x);
  if (c.element < 0 || c.element >= static_cast<int>(model.elements.size())) return kNaN;
  switch (c.kind) {
    case ConstraintKind::FemDeviatoric: {
      // sqrt(tr F^T F) is sqrt(d) at rest (d = 3 for a tet, 2 for a triangle).
      const double d = model.elements[static_cast<size_t>(c.element)].vertices - 1;
      const double rest_value = std::sqrt(d);
      return std::abs(e.C + c.rest - rest_value) / rest_value;
    }
    case ConstraintKind::FemHydrostatic: return std::abs(e.C + c.rest - 1.0);  // |det F - 1|
    default: return std::abs(e.C);  // the strain kinds: |strain vector|, 0 at rest
  }
}

namespace {

// The model constraints that touch a particle with inv_mass 0, in model order.
std::vector<int> constraints_touching_supports(const Model& model) {
  std::vector<int> out;
  for (size_t j = 0; j < model.constraints.size(); ++j) {
    const Constraint& c = model.constraints[j];
    bool touches = false;
    for (int k = 0; k < arity(c.kind); ++k)
      touches = touches || model.inv_mass[static_cast<size_t>(c.particles[static_cast<size_t>(k)])] == 0.0;
    if (touches) out.push_back(static_cast<int>(j));
  }
  return out;
}

}  // namespace

struct MetricsTable {
  ConstraintRuns runs;            // constraint_values' view (core/constraint_functions.hpp)
  // normalized_error's divisor: |rest| for distance and volume where it is not 0, else 1 (a
  // division by 1 leaves |C|'s bits as they are); negative (-|rest|) for a link, a distance
  // constraint with a rest length, so that the same division gives its stretch a sign of its
  // own (IEEE division is symmetric in the sign: |C| / -s is -(|C| / s), bit for bit) and the
  // pass takes Sample::link_stretch_max without an array more.
  std::vector<double> scale;
  // 2 alpha where C^2 / (2 alpha) counts in the elastic energy (alpha > 0, not an FEM kind),
  // else 1; counted: all ones where it counts, else 0 (the term's bits and-ed with it: +0.0). A
  // division by 1 and a mask instead of a branch around the division: the loop is vectorised.
  std::vector<double> two_alpha;
  std::vector<std::uint64_t> counted;
  std::size_t constraints = 0;     // the model's count it was built for
  // The constraints in runs of one group, in model order: measure sums each run in lanes.
  struct GroupRun {
    std::size_t begin = 0, end = 0;
    std::uint16_t group = 0;
  };
  std::vector<GroupRun> group_runs;
  std::vector<std::size_t> fem;   // the FEM-kind constraints: their error by constraint_error
};

namespace {

std::shared_ptr<const MetricsTable> metrics_table(const Model& model) {
  auto t = std::make_shared<MetricsTable>();
  t->runs = constraint_runs(model);
  const size_t m = model.constraints.size();
  t->scale.resize(m);
  t->two_alpha.resize(m);
  t->counted.resize(m);
  t->constraints = m;
  for (size_t j = 0; j < m; ++j) {
    const Constraint& c = model.constraints[j];
    const bool fem = is_fem_kind(c.kind);
    const bool relative = c.kind == ConstraintKind::Distance || c.kind == ConstraintKind::Volume;
    t->scale[j] = relative && std::abs(c.rest) > 0.0 ? std::abs(c.rest) : 1.0;
    if (c.kind == ConstraintKind::Distance && std::abs(c.rest) > 0.0) t->scale[j] = -t->scale[j];
    // The FEM kinds' C^2 / (2 alpha) is V0 Psi_snh + a constant: their elements count it
    // (adding both would count each element twice).
    const bool counts = c.compliance > 0.0 && !fem;
    t->two_alpha[j] = counts ? 2.0 * c.compliance : 1.0;
    t->counted[j] = counts ? ~std::uint64_t{0} : 0;
    if (j == 0 || c.group != t->group_runs.back().group) t->group_runs.push_back({j, j, c.group});
    t->group_runs.back().end = j + 1;
    if (fem) t->fem.push_back(j);
  }
  return t;
}

double relative_drift(double now, double start) {
  return start != 0.0 ? (now - start) / std::abs(start) : kNaN;
}

// measure's pass over the constraints (what it computes and in which order: there), in a clone
// for AVX2 and one for any x86-64, chosen when the program loads (GCC's target_clones): the same
// IEEE operations in the same order in both (no FMA: the build has -ffp-contract=off), so the
// same bits, four lanes to a register instead of two.
constexpr size_t kLanes = 8;
double tree(const double* a) { return ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7])); }

// The constraints [begin, end) of one group into the lanes: sq[k] and mx[k] (from 0) get the
// sum of squares and the largest of the errors |C| / |scale| of the constraints begin + k,
// begin + k + kLanes, ...; el[k] (carried over the runs) their elastic terms C^2 / (2 alpha),
// and-ed with `counted`; lk[k] (carried over the runs) the largest error of a link (scale < 0).
// The largest as std::max: a NaN is passed over.
__attribute__((target_clones("avx2", "default")))
void lane_sums(const double* __restrict V, const double* __restrict scale, const double* __restrict two_alpha,
               const std::uint64_t* __restrict counted, size_t begin, size_t end, double* __restrict sq_out,
               double* __restrict mx_out, double* __restrict el_inout, double* __restrict lk_inout) {
  double sq[kLanes] = {}, mx[kLanes] = {}, el[kLanes], lk[kLanes];
  for (size_t k = 0; k < kLanes; ++k) {
    el[k] = el_inout[k];
    lk[k] = lk_inout[k];
  }
  const auto add = [&](size_t k, size_t j) {
    const double q = std::abs(V[j]) / scale[j];  // -err for a link, else err
    const double err = std::abs(q);               // normalized_error (core/constraint_functions.hpp)
    sq[k] += err * err;
    mx[k] = mx[k] < err ? err : mx[k];
    lk[k] = lk[k] < -q ? -q : lk[k];  // -q < 0 for any other constraint
    el[k] += std::bit_cast<double>(std::bit_cast<std::uint64_t>(V[j] * V[j] / two_alpha[j]) & counted[j]);
  };
  size_t j = begin;
  for (; j + kLanes <= end; j += kLanes)
    for (size_t k = 0; k < kLanes; ++k) add(k, j + k);
  for (size_t k = 0; j < end; ++j, ++k) add(k, j);
  for (size_t k = 0; k < kLanes; ++k) {
    sq_out[k] = sq[k];
    mx_out[k] = mx[k];
    el_inout[k] = el[k];
    lk_inout[k] = lk[k];
  }
}

}  // namespace

MetricsBaseline measure_baseline(const Model& model, const State& initial) {
  MetricsBaseline b;
  b.tet_volume = model.tets.empty() ? kNaN : total_tet_volume(model, initial.x);
  b.surface_volume = model.surface_closed ? enclosed_volume(model, initial.x) : kNaN;
  b.extent = max_distance_from_centroid(initial.x);
  if (initial.x.rows() > 0) b.centroid = initial.x.colwise().mean().transpose();
  b.support_constraints = constraints_touching_supports(model);
  b.supports_listed = true;
  b.table = metrics_table(model);
  return b;
}

Sample measure(const Model& model, const State& state, const MetricsBaseline& baseline) {
  Sample s;
  const Points& x = state.x;
  const Points& v = state.v;

  // Constraint error, overall and per group (constraint_error above: the FEM kinds by their
  // deviation from the rest shape).
  s.groups.assign(model.group_names.size(), GroupError{});
  const size_t m = model.constraints.size();
  std::shared_ptr<const MetricsTable> own;
  const MetricsTable* t = baseline.table.get();
  if (t == nullptr || t->constraints != m) {
    own = metrics_table(model);
    t = own.get();
  }
  // C of every constraint (core/constraint_functions.hpp), in a buffer kept by the thread: a
  // fresh one of a large model's size is a fresh mapping whose pages fault in at every sample.
  thread_local std::vector<double> values;
  constraint_values(t->runs, model, x, values);
  // One pass over the table's arrays, a run of one group at a time: each constraint's error and
  // elastic energy, summed in kLanes partial sums (lane k takes the run's constraints begin + k,
  // begin + k + kLanes, ...), added at the run's end in a fixed tree: a sum in one register
  // chains every constraint through the adder's latency, and this pass was most of measure's own
  // time (metrics/measure/* of bench_solvers). The order depends on the model alone, so a sample is
  // the same bits on every machine and build flags that keep IEEE double; it is not the bits of
  // the one-at-a-time sum (the lanes round differently, by a few ulps of the sum). A constraint
  // whose energy is not counted adds +0.0. The maxima ignore a NaN error; a NaN error makes its
  // group's sum of squares NaN, and that marks the maxima. An FEM-kind constraint's error is
  // constraint_error's, put in its value's place (its scale is 1 and its energy not counted here).
  for (const size_t j : t->fem) values[j] = constraint_error(model, model.constraints[j], x);
  const double* __restrict V = values.data();
  double elastic_lanes[kLanes] = {}, link_lanes[kLanes] = {};
  double sum_sq = 0.0, error_max = 0.0;
  for (const MetricsTable::GroupRun& run : t->group_runs) {
    double sq[kLanes] = {}, mx[kLanes] = {};
    lane_sums(V, t->scale.data(), t->two_alpha.data(), t->counted.data(), run.begin, run.end, sq, mx, elastic_lanes,
              link_lanes);
    const double run_sq = tree(sq);
    double run_max = mx[0];
    for (size_t k = 1; k < kLanes; ++k) run_max = std::max(run_max, mx[k]);
    GroupError& g = s.groups[run.group];
    g.rms += run_sq;
    g.max = std::max(g.max, run_max);
    g.count += static_cast<int>(run.end - run.begin);
    sum_sq += run_sq;
    error_max = std::max(error_max, run_max);
  }
  const double elastic = tree(elastic_lanes);  // the lanes of every run
  for (size_t k = 0; k < kLanes; ++k) s.link_stretch_max = std::max(s.link_stretch_max, link_lanes[k]);
  for (GroupError& g : s.groups)
    if (std::isnan(g.rms)) g.max = kNaN;  // a NaN error in the group
  if (std::isnan(sum_sq)) {
    error_max = kNaN;
    s.link_stretch_max = kNaN;
  }
  s.constraint_error_max = error_max;
  for (GroupError& g : s.groups) g.rms = g.count > 0 ? std::sqrt(g.rms / g.count) : 0.0;
  s.constraint_error_rms = m == 0 ? 0.0 : std::sqrt(sum_sq / static_cast<double>(m));

  // Volume.
  if (model.tets.empty()) {
    s.tet_volume = kNaN;
    s.volume_drift = kNaN;
  } else {
    s.tet_volume = total_tet_volume(model, x, &s.tets_inverted);
    s.volume_drift = relative_drift(s.tet_volume, baseline.tet_volume);
  }
  if (model.surface_closed) {
    s.surface_volume = enclosed_volume(model, x);
    s.surface_volume_drift = relative_drift(s.surface_volume, baseline.surface_volume);
  } else {
    s.surface_volume = kNaN;
    s.surface_volume_drift = kNaN;
  }

  // Energy and momentum of the dynamic particles, and the particles' checks below, in one pass.
  const ParticleScan scan = scan_particles(model, x, v, up_direction(model), baseline.centroid);
  s.distance_from_start_max = scan.dynamic_finite ? std::sqrt(scan.away2_max) : kNaN;
  s.kinetic_energy = scan.kinetic;
  s.potential_energy = scan.potential;
  s.linear_momentum = scan.linear;
  s.angular_momentum = scan.angular;
  s.elastic_energy = elastic;  // the compliant constraints', summed above
  for (const FemElement& e : model.elements) s.elastic_energy += fem::element_energy(e, x);
  if (!baseline.elastic_defined) s.elastic_energy = kNaN;
  s.total_energy = s.kinetic_energy + s.potential_energy + s.elastic_energy;

  // Explosion indicators.
  s.finite = scan.finite;
  if (s.finite) {
    s.max_speed = std::sqrt(scan.speed2_max);
    s.extent = max_distance_from_centroid(x);
  } else {
    s.max_speed = kNaN;
    s.extent = kNaN;
  }

  // Penetration (contacts in penetration at margin 0).
  if (s.finite) {
    for (const Contact& c : find_contacts(model, x, state.time, 0.0)) {
      const double C = eval_contact(model, c, x, state.time).C;
      if (C < 0.0) {
        ++s.penetration_count;
        s.penetration_max = std::max(s.penetration_max, -C);
      }
    }
  } else {
    s.penetration_max = kNaN;
  }

  // Failure detectors.
  s.height_min = scan.lowest;
  // Without colliders nothing is sunk; the depth is NaN where a dynamic position is not finite.
  const SunkParticles sunk = has_colliders(model)
                                 ? sunk_particles(model, state)
                                 : SunkParticles{0, scan.dynamic_finite ? 0.0 : kNaN};
  s.sunk_count = sunk.count;
  s.sunk_depth = sunk.depth;

  // Observables of the scene.
  s.tip_displacement = tip_displacement(model, state);
  s.support_force = baseline.supports_listed
                       ? support_force(model, state, baseline.support_constraints)
                       : support_force(model, state);
  s.pendulum_angle = pendulum_angle(model, state);
  return s;
}

double height_min(const Model& model, const State& state) {
  return scan_particles(model, state.x, state.v, up_direction(model)).lowest;
}

SunkParticles sunk_particles(const Model& model, const State& state) {
  SunkParticles out;
  const Vec3 up = up_direction(model);
  std::vector<Vec3> centers;
  for (const SphereCollider& sphere : model.spheres)
    centers.push_back(sphere_center(model, sphere, state.time));
  std::vector<double> plane_norms;  // |normal| of each plane, once a sample rather than once a particle
  for (const PlaneCollider& p : model.planes) plane_norms.push_back(p.normal.norm());
  for (int i = 0; i < model.particle_count(); ++i) {
    if (model.inv_mass[static_cast<size_t>(i)] == 0.0) continue;
    const Vec3 x = state.x.row(i);
    if (!x.allFinite()) {
      out.depth = kNaN;
      continue;
    }
    double deepest = 0.0;  // of this particle, over the colliders
    bool sunk = false;
    for (size_t k = 0; k < model.planes.size(); ++k) {
      const PlaneCollider& p = model.planes[k];
      const double nn = plane_norms[k];
      const double signed_distance = (p.normal.dot(x) + p.offset) / nn;
      if (signed_distance < 0.0) {
        sunk = true;
        deepest = std::max(deepest, -signed_distance);
      }
    }
    for (size_t k = 0; k < model.spheres.size(); ++k) {
      const SphereCollider& sphere = model.spheres[k];
      const Vec3 d = x - centers[k];
      const double r = d.norm();
      double depth = 0.0;
      switch (sphere.side) {
        case SphereSide::Outside: depth = sphere.radius - r; break;
        case SphereSide::Inside: depth = r - sphere.radius; break;
        case SphereSide::Bowl: depth = d.dot(up) < 0.0 ? r - sphere.radius : 0.0; break;
      }
      if (depth > 0.0) {
        sunk = true;
        deepest = std::max(deepest, depth);
      }
    }
    for (const MeshCollider& mesh : model.meshes) {
      const double depth = -mesh_distance(mesh, x - mesh_offset(model, mesh, state.time)).distance;
      if (depth > 0.0) {
        sunk = true;
        deepest = std::max(deepest, depth);
      }
    }
    if (sunk) ++out.count;
    if (!std::isnan(out.depth)) out.depth = std::max(out.depth, deepest);
  }
  return out;
}

double velocity_hf_rms(const Model& model, const Points& v_n, const Points& v_n1, const Points& v_n2) {
  double sum = 0.0;
  int dynamic = 0;
  for (int i = 0; i < model.particle_count(); ++i) {
    if (model.inv_mass[static_cast<size_t>(i)] == 0.0) continue;
    sum += (v_n.row(i) - 2.0 * v_n1.row(i) + v_n2.row(i)).squaredNorm();
    ++dynamic;
  }
  return dynamic == 0 ? kNaN : std::sqrt(sum / dynamic) / 4.0;
}

Vec3 tip_displacement(const Model& model, const State& state) {
  const std::vector<int>& tip = model.observables.tip;
  if (tip.empty()) return Vec3::Constant(kNaN);
  Vec3 sum = Vec3::Zero();
  for (int i : tip) sum += (state.x.row(i) - model.rest_positions.row(i)).transpose();
  return sum / static_cast<double>(tip.size());
}

Vec3 support_force(const Model& model, const State& state) {
  return support_force(model, state, constraints_touching_supports(model));
}

Vec3 support_force(const Model& model, const State& state, const std::vector<int>& touching) {
  const Vec3 nan = Vec3::Constant(kNaN);
  auto support = [&](int i) { return model.inv_mass[static_cast<size_t>(i)] == 0.0; };
  for (const FemElement& e : model.elements)
    for (int k = 0; k < e.vertices; ++k)
      if (support(e.particles[static_cast<size_t>(k)])) return nan;  // its forces are not in lambda
  if (state.lambda.size() != model.constraints.size()) return nan;
  bool any_support = false;
  for (int i = 0; i < model.particle_count(); ++i) any_support = any_support || support(i);
  if (!any_support) return Vec3::Zero();
  if (state.step == 0) return nan;  // no step has computed the multipliers yet
  Vec3 on_supports = Vec3::Zero();  // sum of the constraint forces on the supports
  for (const int jj : touching) {
    const size_t j = static_cast<size_t>(jj);
    const Constraint& c = model.constraints[j];
    const double lambda = state.lambda[j];
    if (std::isnan(lambda)) return nan;
    if (lambda == 0.0) continue;
    const ConstraintEval e = eval_constraint(c, state.x);
    if (!e.valid) return nan;
    for (int k = 0; k < arity(c.kind); ++k)
      if (support(c.particles[static_cast<size_t>(k)])) on_supports += e.grad[static_cast<size_t>(k)] * lambda;
  }
  return -on_supports;
}

double pendulum_angle(const Model& model, const State& state) {
  const int bob = model.observables.bob;
  if (bob < 0 || bob >= model.particle_count()) return kNaN;
  const double g = model.gravity.norm();
  if (!(g > 0.0)) return kNaN;
  const Vec3 down = model.gravity / g;
  Vec3 across = Vec3::UnitX() - down.x() * down;  // +x without its component along gravity
  if (across.norm() < 1e-12) return kNaN;          // gravity along x: no plane
  across.normalize();
  const Vec3 d = state.x.row(bob).transpose() - model.observables.pivot;
  return std::atan2(d.dot(across), d.dot(down));
}

std::string explosion_reason(const Model& model, const State& state, const Sample& sample,
                             const ExplosionLimits& limits, const MetricsBaseline& baseline) {
  // The message, formatted only when there is one (a stream built at every step was about a
  // tenth of the step logger's own time outside measure on the 64 x 64 cloth).
  const auto say = [](const auto&... parts) {
    std::ostringstream why;
    (why << ... << parts);
    return why.str();
  };
  const int n = model.particle_count();
  if (!sample.finite) {
    for (int i = 0; i < n; ++i) {
      if (!state.x.row(i).allFinite()) return say("non-finite position of particle ", i);
      if (!state.v.row(i).allFinite()) return say("non-finite velocity of particle ", i);
    }
    return "non-finite state";
  }
  if (sample.max_speed > limits.max_speed)
    return say("max speed ", sample.max_speed, " m/s exceeds limits.max_speed = ", limits.max_speed);
  const double ref = std::max(baseline.extent, 1e-3);
  if (sample.extent > limits.max_extent_ratio * ref)
    return say("extent ", sample.extent, " m exceeds limits.max_extent_ratio = ", limits.max_extent_ratio,
               " times the initial ", ref, " m");
  // The root only where the square comes near the limit (a particle within 0.999 of it squared
  // is not beyond it): the same particles as the distance of every one, for n roots fewer.
  const double near_sq = 0.999 * limits.max_distance * limits.max_distance;
  for (int i = 0; i < n; ++i) {
    if (!(state.x.row(i).squaredNorm() > near_sq)) continue;
    const double d = state.x.row(i).norm();
    if (d > limits.max_distance)
      return say("particle ", i, " is ", d, " m from the origin, beyond limits.max_distance = ", limits.max_distance);
  }
  return {};
}

}  // namespace pbdbench
