// pbd-seed: the seed article's PBD listing (its sections 3.1 main loop, 3.2 distance, 3.3 volume,
// 3.4 plane collision, with the stiffness of 4.3 and the damping of 3.1 and 4.4), reproduced to
// the letter, including what looks wrong: its purpose is to study what that published code does.
// It lives in its own file so that none of it can leak into the corrected solvers.
//
// Every line that departs from Mueller et al. 2007 carries a comment "// Dn: ..." and can be
// switched alone to its Mueller counterpart with solver.seed.fixes = ["Dn", ...]; with no fixes
// this is the listing. docs/seed-departures.md has the table. Things the article gives no listing
// for are marked N1 (bending), N2 (sphere and particle-particle contacts), N3 (kinematic
// particles).
//
// The listing works in float (D10): the state is copied to float at the start of a step and back
// to double at its end (a float survives that round trip exactly). With "D10" fixed the very same
// code runs in double. Substeps: the whole listing Step(dt / substeps) is repeated, by the
// substep driver every family shares (solver_api/substep_driver.hpp).
//
// The article's tuning options (solver.seed.iteration_schedule, backup, dynamic_inverse_mass,
// graded_inverse_mass; solvers/pbd_seed.hpp) change how many sweeps a step makes, where step 1's
// backup happens, and the inverse masses the listing sees; their defaults are the listing.
#include "solvers/pbd_seed.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/cancel.hpp"
#include "core/constraint_functions.hpp"
#include "core/contacts.hpp"
#include "solvers/kernels.hpp"
#include "solvers/ordering.hpp"
#include "solvers/step_common.hpp"
#include "solver_api/velocity_pass.hpp"

namespace pbdbench {

int seed_iterations(const SolverOptions& options, long step, double fastest) {
  const bool fast = fastest > options.seed_fast_speed;
  if (options.seed_iteration_schedule == "dynamic") {
    if (step == 0) return 10;  // "the first frame: 10"
    return fast ? 5 : 3;       // "then 3; 5 on large displacements"
  }
  if (options.seed_iteration_schedule == "mixed") return fast ? 1 : 3;  // 5.3
  return options.iterations;
}

std::vector<double> seed_dynamic_inverse_masses(const Model& model, const Points& v,
                                                double fast_speed) {
  std::vector<double> w(model.inv_mass.size(), 0.0);
  for (int i = 0; i < model.particle_count(); ++i)
    if (model.inv_mass[static_cast<size_t>(i)] > 0.0)
      w[static_cast<size_t>(i)] = v.row(i).norm() > fast_speed ? 0.1 : 0.3;
  return w;
}

std::vector<double> seed_graded_inverse_masses(const Model& model) {
  const int n = model.particle_count();
  // Neighbours: every two particles of a constraint.
  std::vector<std::vector<int>> adjacent(static_cast<size_t>(n));
  for (const Constraint& c : model.constraints)
    for (int a = 0; a < arity(c.kind); ++a)
      for (int b = 0; b < arity(c.kind); ++b)
        if (a != b)
          adjacent[static_cast<size_t>(c.particles[static_cast<size_t>(a)])].push_back(
              c.particles[static_cast<size_t>(b)]);
  // Breadth-first search from every particle with inverse mass 0 at once.
  const int unreached = std::numeric_limits<int>::max();
  std::vector<int> d(static_cast<size_t>(n), unreached);
  std::deque<int> queue;
  for (int i = 0; i < n; ++i)
    if (model.inv_mass[static_cast<size_t>(i)] == 0.0) {
      d[static_cast<size_t>(i)] = 0;
      queue.push_back(i);
    }
  if (queue.empty())
    throw std::invalid_argument(
        "solver.seed.graded_inverse_mass grades the inverse masses from the pinned particles "
        "(inverse mass 0), and the model has none");
  while (!queue.empty()) {
    const int p = queue.front();
    queue.pop_front();
    for (int q : adjacent[static_cast<size_t>(p)])
      if (d[static_cast<size_t>(q)] == unreached) {
        d[static_cast<size_t>(q)] = d[static_cast<size_t>(p)] + 1;
        queue.push_back(q);
      }
  }
  int largest = 0;
  for (int di : d)
    if (di != unreached) largest = std::max(largest, di);
  const double dc = std::max(1.0, largest / 2.0);
  std::vector<double> w(static_cast<size_t>(n), 0.0);
  for (int i = 0; i < n; ++i) {
    if (!(model.inv_mass[static_cast<size_t>(i)] > 0.0)) continue;
    const int di = d[static_cast<size_t>(i)];
    w[static_cast<size_t>(i)] = di == unreached ? 0.3 : 0.3 * std::min(1.0, di / dc);
  }
  return w;
}

namespace {

// Which departures are fixed: fixed[k] for id "D<k>".
struct SeedFixes {
  std::array<bool, 12> fixed{};
  explicit SeedFixes(const std::vector<std::string>& ids) {
    for (const std::string& id : ids) fixed[static_cast<size_t>(std::stoi(id.substr(1)))] = true;
  }
  bool operator()(int id) const { return fixed[static_cast<size_t>(id)]; }
};

template <class Real>
using V3 = Eigen::Matrix<Real, 3, 1>;

// The listing's vector helpers, with an explicit evaluation order.
template <class Real>
Real dot(const V3<Real>& a, const V3<Real>& b) {
  return a.x() * b.x() + a.y() * b.y() + a.z() * b.z();
}
template <class Real>
V3<Real> cross(const V3<Real>& a, const V3<Real>& b) {
  return V3<Real>(a.y() * b.z() - a.z() * b.y(), a.z() * b.x() - a.x() * b.z(),
                  a.x() * b.y() - a.y() * b.x());
}
template <class Real>
Real length(const V3<Real>& a) {
  return std::sqrt(dot(a, a));
}
template <class Real>
V3<Real> to_real(const Vec3& v) {
  return v.cast<Real>();
}

// The listing's particle: "每个Particle含 pos, old_pos, inv_mass" (and velocity, radius).
template <class Real>
struct Particle {
  V3<Real> pos, old_pos, velocity;
  Real inv_mass = 0;
  Real radius = 0;
};

// What one constraint of a kind's loop does to the positions (computed, then applied: the listing
// computes each correction before it moves any particle, so this is the same sequence of
// operations in the Gauss-Seidel orders).
template <class Real>
struct SeedCorrection {
  int count = 0;
  std::array<int, 4> particles{-1, -1, -1, -1};
  std::array<V3<Real>, 4> dx{V3<Real>::Zero(), V3<Real>::Zero(), V3<Real>::Zero(),
                             V3<Real>::Zero()};
};

template <class Real>
class PbdSeedSolver final : public Solver {
 public:
  PbdSeedSolver(const SolverOptions& options, const Model& model)
      : options_(options),
        fix_(options.seed_fixes),
        particles_count_(model.particle_count()),
        constraints_(model.constraint_count()),
        ordering_(model, options),
        backup_after_damping_(options.seed_backup == "after_damping"),
        own_masses_(options.seed_dynamic_inverse_mass || options.seed_graded_inverse_mass) {
    if (fix_(2)) bodies_ = dynamic_bodies(model);
    if (own_masses_) {
      masses_ = model;
      if (options.seed_graded_inverse_mass) masses_.inv_mass = seed_graded_inverse_masses(model);
    }
  }

  std::string name() const override { return "pbd-seed"; }

  StepReport step(const Model& model, State& state, double dt) override {
    check_step(model, state, dt, particles_count_, constraints_);
    state.lambda.assign(model.constraints.size(), std::nan(""));  // no multipliers: no forces
    skipped_ = 0;
    // The article's tuning options, from the velocities at the start of the step.
    double fastest = 0.0;
    for (int i = 0; i < particles_count_; ++i) fastest = std::max(fastest, state.v.row(i).norm());
    const int iterations = seed_iterations(options_, state.step, fastest);
    if (options_.seed_dynamic_inverse_mass)
      masses_.inv_mass = seed_dynamic_inverse_masses(model, state.v, options_.seed_fast_speed);
    // The model the listing sees: the given one, or (4.2) a copy of the one given at
    // construction with the article's inverse masses.
    const Model& seen = own_masses_ ? masses_ : model;
    // D10: the listing's float state (exact copies of float values survive the way back).
    particles_.resize(static_cast<size_t>(particles_count_));
    for (int i = 0; i < particles_count_; ++i) {
      Particle<Real>& p = particles_[static_cast<size_t>(i)];
      p.pos = state.x.row(i).transpose().cast<Real>();
      p.old_pos = p.pos;
      p.velocity = state.v.row(i).transpose().cast<Real>();
      p.inv_mass = static_cast<Real>(seen.inv_mass[static_cast<size_t>(i)]);
      p.radius = static_cast<Real>(model.radius[static_cast<size_t>(i)]);
    }
    // The shared substep driver (solver_api/substep_driver.hpp): the listing's own state is the
    // float copy above, which the listing's kinematic particles are set in (N3); the driver's
    // set_kinematic on state.x and state.v is overwritten by the copy back below. The driver
    // advances state.time and state.step after the last substep (state.step inside is this
    // step's index, as the iteration schedule and the shuffled orders read it).
    const long step_index = state.step;
    StepReport report = run_substeps(model, state, dt, options_.substeps,
                                     [&](const Substep& sub, PhaseTimer& timer, StepReport& r) {
      note_stop(r, StopReason::FixedWork);  // solver.iterations sweeps, no convergence test
      listing_step(seen, sub.h, sub.t_end, step_index, sub.index, iterations, timer, r);
    });
    for (int i = 0; i < particles_count_; ++i) {
      const Particle<Real>& p = particles_[static_cast<size_t>(i)];
      state.x.row(i) = p.pos.template cast<double>().transpose();
      state.v.row(i) = p.velocity.template cast<double>().transpose();
    }
    report.skipped = skipped_;
    return report;
  }

 private:
  // One call of the listing's PBD_Solver::Step(float dt) with dt = h; t_end = time at its end;
  // `iterations` sweeps.
  void listing_step(const Model& model, double h, double t_end, long step, int substep,
                    int iterations, PhaseTimer& timer, StepReport& report) {
    const Real dt = static_cast<Real>(h);  // D10: float dt
    // 4.4: alpha_eff = alpha^(dt / reference_dt) and g_eff = g * reference_dt / dt, when asked.
    const double alpha = options_.seed_damping_rescale
                             ? std::pow(options_.seed_damping, h / options_.seed_reference_dt)
                             : options_.seed_damping;
    const Vec3 g = options_.seed_gravity_rescale
                       ? Vec3(model.gravity * (options_.seed_reference_dt / h))
                       : model.gravity;
    const V3<Real> gravity = to_real<Real>(g);

    // N3: no listing moves kinematic particles; they are set here, before step 1, to their
    // target at the end of the step and their motion's velocity (inv_mass 0 keeps them there).
    for (const Attachment& a : model.attachments) {
      Particle<Real>& p = particles_[static_cast<size_t>(a.particle)];
      p.pos = to_real<Real>(attachment_target(model, a, t_end));
      p.velocity =
          a.motion < 0
              ? V3<Real>::Zero()
              : to_real<Real>(motion_velocity(model.motions[static_cast<size_t>(a.motion)], t_end));
    }

    // The positions at the start of the step, for the bottom_up order.
    if (ordering_.order() == ProjectionOrder::BottomUp) start_ = positions();

    // Step 1: back up the old positions (solver.seed.backup = "before_forces", the listing).
    if (!backup_after_damping_) {
      for (auto& p : particles_) {
        p.old_pos = p.pos;
      }
    }

    // Step 2: external forces.
    if (!fix_(1)) {
      if (fix_(2)) damp(model, 1.0 - alpha);  // D2 fixed: Mueller's damping, before the prediction
      for (auto& p : particles_) {
        if (p.inv_mass > 0) {
          p.pos += p.velocity * dt;    // D1: advances with the OLD velocity ...
          p.velocity += gravity * dt;  // D1: ... and this is overwritten by step 5: no gravity
        }
      }
    } else {
      // D1 fixed: Mueller's symplectic Euler, v += h g (line 5), then p = x + h v (line 7).
      for (auto& p : particles_)
        if (p.inv_mass > 0) p.velocity += gravity * dt;
      if (fix_(2)) damp(model, 1.0 - alpha);  // D2 fixed: Mueller's line 6, dampVelocities
      for (auto& p : particles_)
        if (p.inv_mass > 0) p.pos += p.velocity * dt;
    }
    if (fix_(8)) {  // the velocities before the solve, for the velocity pass (D8 fixed)
      v_before_.resize(particles_count_, 3);
      for (int i = 0; i < particles_count_; ++i)
        v_before_.row(i) =
            particles_[static_cast<size_t>(i)].velocity.template cast<double>().transpose();
    }
    timer.lap(report.time_predict);

    // The collision candidates of this step.
    build_candidates(model, t_end);
    ordering_.set_contacts(model, candidates_, start_);
    contact_lambda_.assign(candidates_.size(), 0.0);
    contact_active_.assign(candidates_.size(), 0);
    report.contacts += static_cast<int>(candidates_.size());
    timer.lap(report.time_contacts);

    // Step 3: constraint iterations, kind by kind as the listing loops. The order option applies
    // within each kind's loop.
    const int m = constraints_;
    for (int iter = 0; iter < iterations; ++iter) {
      throw_if_cancelled("a projection sweep");
      ordering_.sweep(step, substep, iter, sequence_);
      for (auto& list : by_kind_) list.clear();
      for (int j : sequence_) {
        const int kind =
            j >= m ? 3 : static_cast<int>(model.constraints[static_cast<size_t>(j)].kind);
        by_kind_[static_cast<size_t>(kind)].push_back(j);
      }
      run_loop(by_kind_[0], [&](int j, SeedCorrection<Real>& c) {
        return solve_distance(model.constraints[static_cast<size_t>(j)], c);
      });  // SolveDistanceConstraints()
      run_loop(by_kind_[1], [&](int j, SeedCorrection<Real>& c) {
        return solve_volume(model.constraints[static_cast<size_t>(j)], c);
      });  // SolveVolumeConstraints()
      run_loop(by_kind_[2], [&](int j, SeedCorrection<Real>& c) {
        return solve_bending(model, model.constraints[static_cast<size_t>(j)], c);
      });  // SolveBendingConstraints()
      run_loop(by_kind_[3], [&](int j, SeedCorrection<Real>& c) {
        return solve_collision(model, static_cast<size_t>(j - m), t_end, c);
      });  // SolveCollisionConstraints()
      ++report.iterations;
    }
    for (char a : contact_active_) report.active_contacts += a;
    timer.lap(report.time_project);

    // Step 4: position damping.
    if (!fix_(2)) {
      const Real a = static_cast<Real>(alpha);        // the listing's 0.98f
      const Real b = static_cast<Real>(1.0 - alpha);  // the listing's 0.02f
      for (auto& p : particles_) {
        if (p.inv_mass > 0) {
          p.pos = a * p.pos + b * p.old_pos;  // D2: damps every motion, rigid ones included
        }
      }
    }

    // solver.seed.backup = "after_damping": the placement the article's 3.1a warns against, the
    // backup after step 4 (step 4 itself blends with the previous step's backup, which is this
    // step's start, as the listing's). Step 5 then divides pos - old_pos = 0: every velocity is 0.
    if (backup_after_damping_) {
      for (auto& p : particles_) {
        p.old_pos = p.pos;
      }
    }

    // Step 5: velocity from the position difference.
    for (auto& p : particles_) {
      if (p.inv_mass > 0) {
        p.velocity = (p.pos - p.old_pos) / dt;
      }
    }

    // D8 fixed: friction and restitution in Mueller's velocity pass, after the solve.
    if (fix_(8)) {
      Points x(particles_count_, 3), v(particles_count_, 3);
      for (int i = 0; i < particles_count_; ++i) {
        x.row(i) = particles_[static_cast<size_t>(i)].pos.template cast<double>().transpose();
        v.row(i) = particles_[static_cast<size_t>(i)].velocity.template cast<double>().transpose();
      }
      velocity_pass(model, candidates_, contact_lambda_, x, v_before_, v, t_end, h);
      for (int i = 0; i < particles_count_; ++i)
        particles_[static_cast<size_t>(i)].velocity = v.row(i).transpose().cast<Real>();
    }
    timer.lap(report.time_velocity);
  }

  // D2 fixed: Mueller et al. 2007, sec. 3.5, with k_damping = 1 - alpha (alpha = 1: no damping,
  // as the listing's alpha = 1). Computed in double, rounded back to the listing's precision.
  void damp(const Model& model, double k) {
    Points x(particles_count_, 3), v(particles_count_, 3);
    for (int i = 0; i < particles_count_; ++i) {
      x.row(i) = particles_[static_cast<size_t>(i)].pos.template cast<double>().transpose();
      v.row(i) = particles_[static_cast<size_t>(i)].velocity.template cast<double>().transpose();
    }
    damp_velocities(bodies_, model.inv_mass, x, v, k);
    for (int i = 0; i < particles_count_; ++i)
      particles_[static_cast<size_t>(i)].velocity = v.row(i).transpose().cast<Real>();
  }

  // D11: the listing tests every particle against the collider inside every iteration
  // ("for (auto& p : particles)" in SolveCollisionConstraints); Mueller generates the collision
  // constraints once per step from the predicted positions (Algorithm 1, line 8).
  void build_candidates(const Model& model, double t_end) {
    candidates_.clear();
    if (fix_(11)) {  // D11 fixed: the contacts at the predicted positions, as pbd
      candidates_ = find_contacts(model, positions(), t_end, options_.contact_margin);
      return;
    }
    for (int pi = 0; pi < static_cast<int>(model.planes.size()); ++pi)
      for (int a = 0; a < particles_count_; ++a)
        if (model.inv_mass[static_cast<size_t>(a)] > 0.0)
          candidates_.push_back({ContactKind::Plane, a, pi});
    for (int si = 0; si < static_cast<int>(model.spheres.size()); ++si)  // N2: as the planes
      for (int a = 0; a < particles_count_; ++a)
        if (model.inv_mass[static_cast<size_t>(a)] > 0.0)
          candidates_.push_back({ContactKind::Sphere, a, si});
    for (int mi = 0; mi < static_cast<int>(model.meshes.size()); ++mi)  // N2: as the spheres
      for (int a = 0; a < particles_count_; ++a)
        if (model.inv_mass[static_cast<size_t>(a)] > 0.0)
          candidates_.push_back({ContactKind::Mesh, a, mi});
    if (model.particle_contact) {
      // N2: particle pairs are found once per step at the predicted positions (no listing;
      // testing every pair in every iteration is not an option).
      for (const Contact& c : find_contacts(model, positions(), t_end, options_.contact_margin))
        if (c.kind == ContactKind::Particle) candidates_.push_back(c);
    }
  }

  Points positions() const {
    Points x(particles_count_, 3);
    for (int i = 0; i < particles_count_; ++i)
      x.row(i) = particles_[static_cast<size_t>(i)].pos.template cast<double>().transpose();
    return x;
  }

  // A kind's loop over its constraints in the sweep's order: Gauss-Seidel (each correction
  // applied at once) or Jacobi (every correction from the positions at the start of the loop).
  template <class F>
  void run_loop(const std::vector<int>& items, F&& correction_of) {
    if (items.empty()) return;
    const bool jacobi = ordering_.jacobi();
    if (jacobi) {
      jacobi_sum_.assign(static_cast<size_t>(particles_count_), V3<Real>::Zero());
      jacobi_count_.assign(static_cast<size_t>(particles_count_), 0);
    }
    for (int j : items) {
      SeedCorrection<Real> c;
      if (!correction_of(j, c)) {
        continue;
      }
      for (int i = 0; i < c.count; ++i) {
        const size_t p = static_cast<size_t>(c.particles[static_cast<size_t>(i)]);
        if (!jacobi) {
          particles_[p].pos += c.dx[static_cast<size_t>(i)];
        } else if (!c.dx[static_cast<size_t>(i)].isZero(0)) {
          jacobi_sum_[p] += c.dx[static_cast<size_t>(i)];
          ++jacobi_count_[p];
        }
      }
    }
    if (jacobi) {
      const Real omega = static_cast<Real>(options_.jacobi_relaxation);
      for (size_t p = 0; p < jacobi_sum_.size(); ++p) {
        if (jacobi_count_[p] == 0) continue;
        const Real scale =
            options_.jacobi_averaging ? omega / static_cast<Real>(jacobi_count_[p]) : omega;
        particles_[p].pos += scale * jacobi_sum_[p];
      }
    }
  }

  // Listing 3.2 (SolveDistanceConstraints), with the stiffness k of 4.3.
  bool solve_distance(const Constraint& con, SeedCorrection<Real>& out) {
    auto& p1 = particles_[static_cast<size_t>(con.particles[0])];
    auto& p2 = particles_[static_cast<size_t>(con.particles[1])];
    const Real d0 = static_cast<Real>(con.rest);
    const Real k = static_cast<Real>(con.stiffness);  // 4.3
    Real d = length(V3<Real>(p1.pos - p2.pos));
    if (!fix_(7)) {
      if (d < static_cast<Real>(1e-6)) return skip();  // D7: absolute guard, 1 micrometre
    } else if (!(d > 0)) {
      return skip();  // D7 fixed: only the undefined gradient d = 0 is skipped
    }
    Real w1 = p1.inv_mass;
    Real w2 = p2.inv_mass;
    Real total_weight = w1 + w2;
    if (total_weight == 0) return skip();
    out.count = 2;
    out.particles = {con.particles[0], con.particles[1], -1, -1};
    if (!fix_(3)) {
      Real diff = (d - d0) / d;
      V3<Real> correction =
          static_cast<Real>(0.5) * diff * (p1.pos - p2.pos);  // D3: half, wrong sign
      out.dx[0] = k * (w1 / total_weight) * correction;       // D3: p1.pos += ... pushes apart
      out.dx[1] = -(k * (w2 / total_weight) * correction);    // D3: p2.pos -= ... when stretched
    } else {
      // D3 fixed: Mueller et al. 2007, sec. 3.3:
      // dp1 = -k w1/(w1+w2) (|p1-p2| - d0) (p1-p2)/|p1-p2|, dp2 = +k w2/(w1+w2) (...).
      const V3<Real> n = (p1.pos - p2.pos) / d;
      const Real s = (d - d0) / total_weight;
      out.dx[0] = (-k * s * w1) * n;
      out.dx[1] = (k * s * w2) * n;
    }
    return true;
  }

  // Listing 3.3 (SolveVolumeConstraints).
  bool solve_volume(const Constraint& con, SeedCorrection<Real>& out) {
    auto& a = particles_[static_cast<size_t>(con.particles[0])];
    auto& b = particles_[static_cast<size_t>(con.particles[1])];
    auto& c = particles_[static_cast<size_t>(con.particles[2])];
    auto& d = particles_[static_cast<size_t>(con.particles[3])];
    const Real v0 = static_cast<Real>(con.rest);
    V3<Real> ab = b.pos - a.pos;
    V3<Real> ac = c.pos - a.pos;
    V3<Real> ad = d.pos - a.pos;
    Real vol = dot(ab, cross(ac, ad)) / static_cast<Real>(6);
    Real diff = (vol - v0) / (vol * vol + static_cast<Real>(1e-6));  // D6: divides C by vol^2
    V3<Real> grad_b = cross(ac, ad) / static_cast<Real>(6);
    V3<Real> grad_c = cross(ad, ab) / static_cast<Real>(6);
    V3<Real> grad_d = cross(ab, ac) / static_cast<Real>(6);
    V3<Real> grad_a = fix_(5) ? V3<Real>(-(grad_b + grad_c + grad_d))             // D5 fixed
                              : V3<Real>(-cross(ac, ad) / static_cast<Real>(6));  // D5: = -grad_b
    Real denom = dot(grad_a, grad_a) * a.inv_mass + dot(grad_b, grad_b) * b.inv_mass +
                 dot(grad_c, grad_c) * c.inv_mass + dot(grad_d, grad_d) * d.inv_mass;
    if (!fix_(7)) {
      if (denom < static_cast<Real>(1e-6)) return skip();  // D7: absolute guard (m^4/kg)
    } else if (!(denom > 0)) {
      return skip();  // D7 fixed: only a zero denominator is skipped
    }
    const Real k = fix_(4) ? static_cast<Real>(con.stiffness) : static_cast<Real>(1);  // D4: no k
    out.count = 4;
    out.particles = con.particles;
    if (!fix_(6)) {
      // D6: one shared vector, each vertex moved by delta * w_i: with equal inverse masses a
      // translation, which cannot change the volume.
      V3<Real> delta =
          -diff *
          (grad_a * a.inv_mass + grad_b * b.inv_mass + grad_c * c.inv_mass + grad_d * d.inv_mass) /
          denom;
      out.dx[0] = delta * a.inv_mass;
      out.dx[1] = delta * b.inv_mass;
      out.dx[2] = delta * c.inv_mass;
      out.dx[3] = delta * d.inv_mass;
      if (fix_(4))
        for (auto& dx : out.dx) dx = k * dx;
    } else {
      // D6 fixed: Mueller et al. 2007, sec. 3.3: dx_i = -k w_i grad_i C * C / sum_j w_j |grad_j C|^2.
      const Real s = (vol - v0) / denom;
      out.dx[0] = (-k * s * a.inv_mass) * grad_a;
      out.dx[1] = (-k * s * b.inv_mass) * grad_b;
      out.dx[2] = (-k * s * c.inv_mass) * grad_c;
      out.dx[3] = (-k * s * d.inv_mass) * grad_d;
    }
    return true;
  }

  // N1: no listing in the article (its table gives only C = acos(n1.n2) - theta0): Mueller's
  // dihedral projection (sec. 4.2, appendix A), evaluated by the core in double and rounded to
  // the listing's precision. Its stiffness follows D4 (unscaled, as the volume listing, unless
  // D4 is fixed).
  bool solve_bending(const Model& model, const Constraint& con, SeedCorrection<Real>& out) {
    std::array<Vec3, 4> x;
    Weights w{};
    for (size_t i = 0; i < 4; ++i) {
      x[i] = particles_[static_cast<size_t>(con.particles[i])].pos.template cast<double>();
      w[i] = model.inv_mass[static_cast<size_t>(con.particles[i])];
    }
    const ConstraintEval e = eval_bending(x[0], x[1], x[2], x[3], con.rest);
    Correction corr;
    const double k = fix_(4) ? con.stiffness : 1.0;  // D4
    if (pbd_project(e, w, 4, k, corr) != Projection::Applied) return skip();
    out.count = 4;
    out.particles = con.particles;
    for (size_t i = 0; i < 4; ++i) out.dx[i] = corr.dx[i].cast<Real>();
    return true;
  }

  // Listing 3.4 (SolveCollisionConstraints) for planes; N2 for spheres and particle pairs in the
  // same style: push along the unit contact normal by the penetration, then the same dead
  // velocity write.
  bool solve_collision(const Model& model, size_t k, double t_end, SeedCorrection<Real>& out) {
    const Contact& con = candidates_[k];
    auto& p = particles_[static_cast<size_t>(con.a)];
    const Real restitution = static_cast<Real>(options_.seed_restitution);  // the listing's 0.2f
    out.count = 1;
    out.particles = {con.a, -1, -1, -1};
    switch (con.kind) {
      case ContactKind::Plane: {
        const PlaneCollider& plane = model.planes[static_cast<size_t>(con.b)];
        V3<Real> normal = to_real<Real>(plane.normal);  // D9: used as given, "normal为单位法向量"
        Real offset = static_cast<Real>(plane.offset);
        if (fix_(9)) {  // D9 fixed: the unit normal n/|n| and offset/|n|
          const double nn = plane.normal.norm();
          normal = to_real<Real>(Vec3(plane.normal / nn));
          offset = static_cast<Real>(plane.offset / nn);
        }
        Real dist = dot(normal, p.pos) + offset;
        if (!(dist < p.radius)) return false;
        contact_active_[k] = 1;
        V3<Real> correction = (p.radius - dist) * normal;
        dead_velocity_write(p, normal, restitution);
        out.dx[0] = correction;
        record_normal_push(model, k, out, plane.normal.normalized());
        return true;
      }
      case ContactKind::Sphere: {  // N2
        const SphereCollider& sphere = model.spheres[static_cast<size_t>(con.b)];
        const V3<Real> center = to_real<Real>(sphere_center(model, sphere, t_end));
        const V3<Real> r = p.pos - center;
        if (sphere.side == SphereSide::Bowl && dot(r, to_real<Real>(up_direction(model))) >= 0)
          return false;  // the open top half of a bowl
        const Real dist = length(r);
        if (!(dist > 0)) return skip();
        const Real R = static_cast<Real>(sphere.radius);
        const bool outside = sphere.side == SphereSide::Outside;
        const Real C = outside ? dist - (R + p.radius) : (R - p.radius) - dist;
        if (!(C < 0)) return false;
        contact_active_[k] = 1;
        const V3<Real> normal = (outside ? r : V3<Real>(-r)) / dist;
        dead_velocity_write(p, normal, restitution);
        out.dx[0] = -C * normal;
        record_normal_push(model, k, out, normal.template cast<double>());
        return true;
      }
      case ContactKind::Mesh: {  // N2: as a sphere, along the mesh's signed-distance gradient
        const MeshCollider& mesh = model.meshes[static_cast<size_t>(con.b)];
        const Vec3 x = p.pos.template cast<double>() - mesh_offset(model, mesh, t_end);
        const MeshDistance md = mesh_distance(mesh, x);
        if (md.triangle < 0) return skip();
        const Real C = static_cast<Real>(md.distance) - p.radius;
        if (!(C < 0)) return false;
        contact_active_[k] = 1;
        const V3<Real> normal = md.normal.cast<Real>();
        dead_velocity_write(p, normal, restitution);
        out.dx[0] = -C * normal;
        record_normal_push(model, k, out, md.normal);
        return true;
      }
      case ContactKind::Particle: {  // N2
        auto& q = particles_[static_cast<size_t>(con.b)];
        const V3<Real> r = p.pos - q.pos;
        const Real dist = length(r);
        if (!(dist > 0)) return skip();
        const Real C = dist - (p.radius + q.radius);
        if (!(C < 0)) return false;
        const Real W = p.inv_mass + q.inv_mass;
        if (W == 0) return skip();
        contact_active_[k] = 1;
        const V3<Real> normal = r / dist;
        dead_velocity_write(p, normal, restitution);
        dead_velocity_write(q, normal, restitution);
        out.count = 2;
        out.particles = {con.a, con.b, -1, -1};
        out.dx[0] = (p.inv_mass / W) * -C * normal;
        out.dx[1] = -((q.inv_mass / W) * -C * normal);
        record_normal_push(model, k, out, normal.template cast<double>());
        return true;
      }
      case ContactKind::Edge:  // (edge-edge: refused with it)
      case ContactKind::Triangle:  // refused by make_pbd_seed_solver: the listing has none
        throw std::logic_error("pbd-seed: a vertex-triangle contact reached the listing");
    }
    return false;
  }

  // The listing's restitution, written to the velocity inside the iteration loop.
  void dead_velocity_write(Particle<Real>& p, const V3<Real>& normal, Real restitution) {
    V3<Real> vel_normal = dot(p.velocity, normal) * normal;
    V3<Real> vel_tangent = p.velocity - vel_normal;
    if (!fix_(8)) {
      p.velocity = -restitution * vel_normal + vel_tangent;  // D8: overwritten by step 5
    }
  }

  // Bookkeeping for the velocity pass (used only with D8 fixed): the contact's multiplier is the
  // relative normal displacement it applied, divided by w_a + w_b (solver_api/velocity_pass.hpp).
  void record_normal_push(const Model& model, size_t k, const SeedCorrection<Real>& c,
                          const Vec3& unit_normal) {
    const Contact& con = candidates_[k];
    double W = model.inv_mass[static_cast<size_t>(con.a)];
    double push = unit_normal.dot(c.dx[0].template cast<double>());
    if (con.kind == ContactKind::Particle) {
      W += model.inv_mass[static_cast<size_t>(con.b)];
      push -= unit_normal.dot(c.dx[1].template cast<double>());
    }
    const double scale = ordering_.jacobi() ? options_.jacobi_relaxation : 1.0;
    if (W > 0.0) contact_lambda_[k] += scale * push / W;
  }

  bool skip() {
    ++skipped_;
    return false;
  }

  SolverOptions options_;
  SeedFixes fix_;
  int particles_count_;
  int constraints_;
  Ordering ordering_;
  std::vector<std::vector<int>> bodies_;  // for Mueller's damping (D2 fixed)
  bool backup_after_damping_;             // solver.seed.backup = "after_damping"
  bool own_masses_;                       // dynamic or graded inverse masses (4.2)
  Model masses_;                          // with own_masses_: the model with the article's
                                          // inverse masses, the listing's only model
  Points start_;                          // (n x 3) m, positions at the start of the step
                                          // (bottom_up order only)

  std::vector<Particle<Real>> particles_;  // the listing's particles
  std::vector<Contact> candidates_;        // collision candidates of the step
  std::vector<double> contact_lambda_;     // (candidates) for the velocity pass (D8 fixed)
  std::vector<char> contact_active_;       // (candidates) penetrating at some projection
  Points v_before_;                        // (n x 3) velocities after step 2 (D8 fixed)
  std::vector<int> sequence_;
  std::array<std::vector<int>, 4> by_kind_;  // distance, volume, bending, collision
  std::vector<V3<Real>> jacobi_sum_;
  std::vector<int> jacobi_count_;
  int skipped_ = 0;  // projections skipped in the current step
};

}  // namespace

std::unique_ptr<Solver> make_pbd_seed_solver(const SolverOptions& options, const Model& model) {
  if (model.surface_contact || model.self_contact)
    throw std::invalid_argument(
        "pbd-seed does not simulate vertex-triangle contact (scene.surface_contact or "
        "scene.self_contact; the listing has none): pbd and xpbd do");
  // A FEM element is a material (Pa); PBD's per-constraint stiffness k is not one.
  const bool fem_constraints = std::any_of(model.constraints.begin(), model.constraints.end(),
                                           [](const Constraint& c) { return is_fem_kind(c.kind); });
  if (!model.elements.empty() || fem_constraints)
    throw std::invalid_argument(
        "pbd-seed has no FEM material: its stiffness k is not a material; set scene.material = "
        "\"none\" or use xpbd or a reference solver (the model has " +
        std::to_string(model.elements.size()) + " FEM elements)");
  const SeedFixes fix(options.seed_fixes);
  if (fix(10)) return std::make_unique<PbdSeedSolver<double>>(options, model);  // D10 fixed
  return std::make_unique<PbdSeedSolver<float>>(options, model);                // D10: float
}

}  // namespace pbdbench
