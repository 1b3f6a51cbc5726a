#include "solvers/compiled_projection.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/cancel.hpp"
#include "core/constraint_functions.hpp"
#include "core/surface_contact.hpp"
#include "solvers/kernels.hpp"
#include "solvers/pbd_material.hpp"
#include "solvers/projection_kernels.hpp"
#include "solvers/projection_wide.hpp"
#include "solvers/staged_tasks.hpp"
#include "solvers/sweep_threads.hpp"

namespace pbdbench {

namespace {

constexpr int kKinds = kConstraintKindCount;
// Items per chunk: the unit a thread takes within a level or colour. Fixed, so that the work a
// chunk does never depends on the thread count.
constexpr int kChunk = 512;
// A sweep runs in threads only when its groups (levels, colours) average this many items: below
// it the barriers between groups cost more than the parallel work saves.
constexpr int kParallelGroup = 2048;

// A run of items of one kind and one kernel variant, independent of each other (the rule and
// jacobi fields of ChunkSpec are set when it runs).
using Chunk = ChunkSpec;

// Items that may run in any order among themselves: a level or a colour.
struct Group {
  std::vector<Chunk> chunks;
  int items = 0;
};

// A contact compiled for the substep, in T.
template <class T>
struct ContactItem {
  ContactKind kind = ContactKind::Plane;
  std::int32_t a = -1, b = -1;   // particles (b: Particle contacts only)
  T wa = 0, wb = 0;              // inverse masses, 1/kg
  V3<T> g{};                     // Plane: the unit normal; Sphere: the centre at t_end, m
  T r = 0;                       // Plane: offset / |n| - r_a; Sphere: R + r_a (outside) or
                                 // R - r_a (inside); Particle: r_a + r_b; m
  T sign = 1;                    // Sphere: +1 outside, -1 inside (C = sign (|x - c| - r))
  bool valid = true;             // Plane: |n| > 0
  const MeshCollider* mesh = nullptr;  // Mesh: the collider (g: its offset at t_end; r: r_a);
                                       // C and grad from its signed distance at every projection
  std::array<std::int32_t, 3> t{-1, -1, -1};  // Triangle: its vertices; Edge: b, c, d (the
                                              // first edge a-b, the second c-d); r: the thickness
  std::array<T, 3> wt{0, 0, 0};               // their inverse masses, 1/kg
};

// Corrections per contact in the Jacobi buffer: up to four particles (vertex-triangle, edge-edge).
constexpr int kContactDx = 12;

template <class T>
class Program final : public CompiledProjection {
 public:
  Program(const Model& model, const SolverOptions& options, ProjectionRule rule,
          const Ordering& ordering, bool one_by_one, int width)
      : compiled_model_(&model),
        rule_(rule),
        width_(std::min(width, static_cast<int>(widest_vector_width()))),
        order_(options.order),
        threads_(resolve_threads(options.threads), options.threads == 0),
        relaxation_(options.jacobi_relaxation),
        averaging_(options.jacobi_averaging),
        particles_(model.particle_count()),
        items_(model.constraint_count()) {
    if (particles_ > std::numeric_limits<std::int32_t>::max() / kStride)
      throw std::length_error("compiled projection: more particles than offsets of 32 bits address");
    bool negative_mass = false;
    moving_.resize(static_cast<size_t>(particles_));
    for (int p = 0; p < particles_; ++p) {
      const double w = model.inv_mass[static_cast<size_t>(p)];
      moving_[static_cast<size_t>(p)] = w != 0.0;
      negative_mass = negative_mass || w < 0.0;
    }
    // The visiting order of the model's items, grouped.
    std::vector<int> group_of(static_cast<size_t>(items_), 0);
    switch (order_) {
      case ProjectionOrder::Sequential:
      case ProjectionOrder::Reversed: levels(model, order_ == ProjectionOrder::Reversed, group_of); break;
      case ProjectionOrder::Colored:
        if (negative_mass) per_item_ = true;
        else for (int j = 0; j < items_; ++j) group_of[static_cast<size_t>(j)] = ordering.colors()[static_cast<size_t>(j)];
        break;
      case ProjectionOrder::Jacobi: break;  // one group
      default: per_item_ = true;
    }
    if (one_by_one && order_ != ProjectionOrder::Jacobi) per_item_ = true;
    if (rule_ == ProjectionRule::Pbd) {
      pbd_derived_ = options.pbd_material == PbdMaterial::Compliance;
      pbd_iterations_ = options.iterations;
      if (pbd_derived_) pbd_inverse_mass_sums_ = pbd_inverse_mass_sums(model);
      else pbd_stiffness_ = pbd_stiffness(model, options, {}, 0.0);
    }
    build_blocks(model, group_of);
    for (int k = 0; k < kKinds; ++k) views_[static_cast<size_t>(k)] = view(blocks_[static_cast<size_t>(k)]);
    // The fourth scalar of a particle is its inverse mass (projection_kernels.hpp, kStride),
    // read by the kernels with its coordinates; load() writes only the coordinates.
    P_.assign(static_cast<size_t>(kStride) * static_cast<size_t>(particles_), T(0));
    for (int p = 0; p < particles_; ++p)
      P_[static_cast<size_t>(kStride * p + 3)] = static_cast<T>(model.inv_mass[static_cast<size_t>(p)]);
    if (damped_) X0_ = P_;
    if (order_ == ProjectionOrder::Jacobi) build_jacobi(model);
  }

  void set_substep(const Model& model, double h) override {
    // The rest values: the model is immutable (core/model.hpp), so they change only when the
    // step is given another model than the one compiled (relax.frames' working copy, whose
    // values change between steps).
    const bool same = &model == compiled_model_;
    if (!same || !rest_compiled_) refresh_rest(model);
    rest_compiled_ = same;
    if (h == h_) return;
    if (rule_ == ProjectionRule::Xpbd) set_coefficients(h);
    else if (pbd_derived_) set_pbd_stiffness(model, h);
  }

  // pbd: the projection's coefficients for stiffness k (a_i = k w_i / (w0 + w1), the share of
  // the correction particle i takes, for distance; k for the other kinds).
  static void pbd_coefficients(const Model& model, const Constraint& c, double k,
                               std::array<T, KindBlock<T>::kCoefficients>& coef) {
    if (c.kind == ConstraintKind::Distance) {
      const double w0 = model.inv_mass[static_cast<size_t>(c.particles[0])];
      const double w1 = model.inv_mass[static_cast<size_t>(c.particles[1])];
      const double wsum = w0 + w1;
      coef[0] = static_cast<T>(k * w0 / wsum);
      coef[1] = static_cast<T>(k * w1 / wsum);
    } else {
      coef[0] = static_cast<T>(k);
    }
  }

  // pbd with solver.pbd.material = compliance: each constraint's k for the substep h, derived
  // from its compliance (solvers/pbd_material.hpp).
  void set_pbd_stiffness(const Model& model, double h) {
    h_ = h;
    for (int kind = 0; kind < kKinds; ++kind) {
      KindBlock<T>& b = blocks_[static_cast<size_t>(kind)];
      for (int s = 0; s < b.count; ++s) {
        const size_t z = static_cast<size_t>(s);
        const size_t j = static_cast<size_t>(b.item[z]);
        const double k = pbd_stiffness_from_compliance(b.compliance[z], pbd_inverse_mass_sums_[j], h,
                                                       pbd_iterations_);
        b.stiffness[z] = k;
        std::array<T, KindBlock<T>::kCoefficients> coef{};
        pbd_coefficients(model, model.constraints[j], k, coef);
        for (size_t n = 0; n < coef.size(); ++n) b.coef[n][z] = coef[n];
      }
    }
  }

  void refresh_rest(const Model& model) {
    for (int k = 0; k < kKinds; ++k) {
      KindBlock<T>& b = blocks_[static_cast<size_t>(k)];
      for (int s = 0; s < b.count; ++s) {
        const double rest = model.constraints[static_cast<size_t>(b.item[static_cast<size_t>(s)])].rest;
        b.rest_double[static_cast<size_t>(s)] = rest;
        b.rest[static_cast<size_t>(s)] = static_cast<T>(rest);
      }
    }
  }

  void set_coefficients(double h) {
    h_ = h;
    for (int k = 0; k < kKinds; ++k) {
      KindBlock<T>& b = blocks_[static_cast<size_t>(k)];
      for (int s = 0; s < b.count; ++s) {
        const size_t z = static_cast<size_t>(s);
        const XpbdCoefficients c = xpbd_coefficients(b.compliance[z], b.damping[z], h);
        b.coef[0][z] = static_cast<T>(c.alpha_tilde);
        b.coef[1][z] = static_cast<T>(c.gamma);
        if (b.kind == ConstraintKind::Distance) {
          // D = (1 + gamma)(w0 + w1) + alpha~, in T as the kernel would; 0 marks D <= 0 (skipped).
          // The inverse masses are the positions' fourth scalars (projection_kernels.hpp, kStride).
          const T w = P_[static_cast<size_t>(b.offset[0][z] + 3)] + P_[static_cast<size_t>(b.offset[1][z] + 3)];
          const T D = (T(1) + b.coef[1][z]) * w + b.coef[0][z];
          b.coef[2][z] = D > T(0) ? T(1) / D : T(0);
        }
      }
    }
  }

  void begin_substep(const Model& model, const Points& p, const Points& x_n,
                     const std::vector<Contact>& contacts, double t_end,
                     const Ordering& ordering) override {
    load(p, P_);
    if (damped_) load(x_n, X0_);
    for (KindBlock<T>& b : blocks_) std::fill(b.lambda.begin(), b.lambda.end(), T(0));
    // Contacts.
    contacts_.resize(contacts.size());
    for (size_t k = 0; k < contacts.size(); ++k) contacts_[k] = compile_contact(model, contacts[k], t_end);
    contact_lambda_.assign(contacts.size(), T(0));
    contact_active_.assign(contacts.size(), 0);
    const int c = static_cast<int>(contacts.size());
    contact_order_.resize(static_cast<size_t>(c));
    contact_start_.assign(groups_.size() + 1, 0);
    if (order_ == ProjectionOrder::Colored && !per_item_) {
      // Counting sort of the contacts by colour (stable: by index within a colour).
      const std::vector<int>& colors = ordering.colors();
      int count = static_cast<int>(groups_.size());
      for (int k = 0; k < c; ++k) count = std::max(count, colors[static_cast<size_t>(items_ + k)] + 1);
      contact_start_.assign(static_cast<size_t>(count) + 1, 0);
      for (int k = 0; k < c; ++k) ++contact_start_[static_cast<size_t>(colors[static_cast<size_t>(items_ + k)]) + 1];
      for (int g = 0; g < count; ++g) contact_start_[static_cast<size_t>(g) + 1] += contact_start_[static_cast<size_t>(g)];
      std::vector<int> next(contact_start_.begin(), contact_start_.end() - 1);
      for (int k = 0; k < c; ++k)
        contact_order_[static_cast<size_t>(next[static_cast<size_t>(colors[static_cast<size_t>(items_ + k)])]++)] = k;
    } else {
      for (int k = 0; k < c; ++k)
        contact_order_[static_cast<size_t>(k)] = order_ == ProjectionOrder::Reversed ? c - 1 - k : k;
    }
    if (order_ == ProjectionOrder::Jacobi) {
      contact_dx_.assign(kContactDx * contacts.size(), T(0));
      contact_dlambda_.assign(contacts.size(), T(0));
    }
  }

  int threads() const override { return sweeps_threaded() ? threads_.most() : 1; }

  // The sweeps run as tasks on threads: coloured or Jacobi, compiled, large enough (parallel_).
  // Sequential and reversed never do (their dependency levels are too small to share).
  bool sweeps_threaded() const {
    return parallel_ && !per_item_ && order_ != ProjectionOrder::Sequential && order_ != ProjectionOrder::Reversed;
  }

  void sweeps(int iterations, long step, int substep, const Ordering& ordering,
              StepReport& report) override {
    long skipped = 0;
    if (sweeps_threaded()) {
      // One sweep per run of the threads, so that a cancellation is seen between sweeps, each
      // on the threads threads_ gives it (solvers/sweep_threads.hpp), timed for its choice.
      for (int sweep = 0; sweep < iterations; ++sweep) {
        throw_if_cancelled("a projection sweep");
        const int threads = threads_.next();
        const auto t0 = std::chrono::steady_clock::now();
        skipped += threaded_sweeps(1, threads);
        threads_.record(threads, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        ++report.iterations;
      }
      report.skipped += static_cast<int>(skipped);
      return;
    }
    for (int sweep = 0; sweep < iterations; ++sweep) {
      throw_if_cancelled("a projection sweep");
      if (per_item_) {
        ordering.sweep(step, substep, sweep, sequence_);
        skipped += sweep_items();
      } else if (order_ == ProjectionOrder::Jacobi) {
        skipped += sweep_jacobi();
      } else {
        skipped += sweep_groups();
      }
      ++report.iterations;
    }
    report.skipped += static_cast<int>(skipped);
  }

  // Macklin et al. 2016, eqs. 8 and 9: g -= J^T lambda into g, and sum h_j^2, h_j = C_j +
  // alpha~_j lambda_j, kind by kind in slot order. With threads (colored order), the items of
  // one kind and one colour run as tasks of a stage, stage after stage in slot order: a colour's
  // items share no moving particle, so every moving particle's g receives its terms in the order
  // of the serial loop, and each h_j is kept and summed afterwards in slot order: the same bits
  // at any thread count. The g of a particle that does not move is not written (the residual
  // sums g over the moving particles only; items of one colour may share a pinned particle).
  double constraint_residuals(const Model& model, const Points& p, Points& g) const override {
    residual_positions_.resize(static_cast<size_t>(kStride) * static_cast<size_t>(particles_));
    for (int i = 0; i < particles_; ++i) {
      for (int a = 0; a < 3; ++a) residual_positions_[static_cast<size_t>(kStride * i + a)] = p(i, a);
      residual_positions_[static_cast<size_t>(kStride * i + 3)] = 0.0;
    }
    for (int k = 0; k < kKinds; ++k)
      residual_terms_[static_cast<size_t>(k)].resize(static_cast<size_t>(blocks_[static_cast<size_t>(k)].count));
    if (parallel_ && order_ == ProjectionOrder::Colored) {
      std::vector<Task> tasks;
      std::vector<int> wait;
      for (int k = 0; k < kKinds; ++k) {
        for (const Group& grp : groups_) {
          const int stage = static_cast<int>(tasks.size());
          for (const Chunk& ch : grp.chunks)
            if (static_cast<int>(ch.kind) == k) {
              tasks.push_back({Task::ChunkOf, ch.begin, ch.end, k});
              wait.push_back(stage);
            }
        }
      }
      run_staged(threads_.chosen(), wait, [&](int t, int) {
        const Task& task = tasks[static_cast<size_t>(t)];
        residual_terms(task.c, task.a, task.b, g);
      });
    } else {
      for (int k = 0; k < kKinds; ++k) residual_terms(k, 0, blocks_[static_cast<size_t>(k)].count, g);
    }
    double h2 = 0.0;
    for (int k = 0; k < kKinds; ++k)
      for (const double hj : residual_terms_[static_cast<size_t>(k)]) h2 += hj * hj;
    // Items never applied have lambda = 0: their C alone.
    for (int j : dead_items_) {
      const double C = eval_constraint(model, model.constraints[static_cast<size_t>(j)], p).C;
      h2 += C * C;
    }
    return h2;
  }

  // The items [begin, end) of kind k at residual_positions_: h_j into residual_terms_[k], and
  // g -= lambda_j grad C_j for the moving particles, lane by lane in slot order
  // (solvers/projection_kernels.hpp, residual_chunk), in the widest packs this run may use.
  void residual_terms(int k, int begin, int end, Points& g) const {
    const KindBlock<T>& b = blocks_[static_cast<size_t>(k)];
    if (begin >= end) return;
    BlockView<double> v;
    for (int i = 0; i < b.arity; ++i) v.offset[i] = b.offset[static_cast<size_t>(i)].data();
    v.rest = b.rest_double.data();
    for (int n = 0; n < 9; ++n) v.rest_inverse[n] = b.rest_inverse_double[static_cast<size_t>(n)].data();
    ResidualArgs<T> r;
    r.P = residual_positions_.data();
    r.compliance = b.compliance.data();
    r.lambda = b.lambda.data();
    r.moving = moving_.data();
    r.h2 = h_ * h_;
    r.terms = residual_terms_[static_cast<size_t>(k)].data();
    r.g = g.data();
    const auto kind = static_cast<ConstraintKind>(k);
    if (width_ == static_cast<int>(VectorWidth::Avx512)) return residual_chunk_avx512(kind, v, begin, end, r);
    if (width_ == static_cast<int>(VectorWidth::Avx2)) return residual_chunk_avx2(kind, v, begin, end, r);
    residual_chunk<Pack<double, 16>>(kind, v, begin, end, r);
  }

  void end_substep(Points& p, std::vector<double>* lambda, std::vector<double>& contact_lambda,
                   std::vector<char>& contact_active) const override {
    for (int i = 0; i < particles_; ++i)
      for (int a = 0; a < 3; ++a)
        p(i, a) = static_cast<double>(P_[static_cast<size_t>(kStride * i + a)]);
    if (lambda != nullptr) {
      lambda->assign(static_cast<size_t>(items_), 0.0);
      for (const KindBlock<T>& b : blocks_)
        for (int s = 0; s < b.count; ++s)
          (*lambda)[static_cast<size_t>(b.item[static_cast<size_t>(s)])] = static_cast<double>(b.lambda[static_cast<size_t>(s)]);
    }
    contact_lambda.assign(contact_lambda_.begin(), contact_lambda_.end());
    contact_active = contact_active_;
  }

 private:
  // ---- setup -------------------------------------------------------------------------------

  // Dependency levels of the model's items in the sequential (or reversed) order.
  void levels(const Model& model, bool reversed, std::vector<int>& level) const {
    std::vector<int> last(static_cast<size_t>(particles_), -1);
    for (int n = 0; n < items_; ++n) {
      const int j = reversed ? items_ - 1 - n : n;
      const Constraint& c = model.constraints[static_cast<size_t>(j)];
      int l = 0;
      for (int i = 0; i < arity(c.kind); ++i) {
        const int p = c.particles[static_cast<size_t>(i)];
        if (moving_[static_cast<size_t>(p)]) l = std::max(l, last[static_cast<size_t>(p)] + 1);
      }
      level[static_cast<size_t>(j)] = l;
      for (int i = 0; i < arity(c.kind); ++i) {
        const int p = c.particles[static_cast<size_t>(i)];
        if (moving_[static_cast<size_t>(p)]) last[static_cast<size_t>(p)] = l;
      }
    }
  }

  bool anchored(const Model& model, const Constraint& c) const {
    for (int i = 0; i < arity(c.kind); ++i)
      if (!moving_[static_cast<size_t>(c.particles[static_cast<size_t>(i)])]) return true;
    (void)model;
    return false;
  }

  // Whether a model item is never applied: a pbd distance constraint with w0 + w1 <= 0, or an
  // xpbd one that is also rigid (its denominator (1 + gamma)(w0 + w1) + alpha~ is then <= 0 at
  // every h). Other kinds decide at each projection.
  bool dead(const Model& model, const Constraint& c) const {
    if (c.kind != ConstraintKind::Distance) return false;
    const double w = model.inv_mass[static_cast<size_t>(c.particles[0])] +
                     model.inv_mass[static_cast<size_t>(c.particles[1])];
    if (rule_ == ProjectionRule::Pbd) return !(w > 0.0);
    return !(w > 0.0) && !(c.compliance > 0.0);
  }

  void build_blocks(const Model& model, const std::vector<int>& group_of) {
    // Sort key: group, kind, anchored, damped, index (per_item_: the model's order).
    struct Key {
      int group, kind, anchored, damped, index;
    };
    std::vector<Key> keys;
    keys.reserve(static_cast<size_t>(items_));
    slot_.assign(static_cast<size_t>(items_), {-1, -1});
    for (int j = 0; j < items_; ++j) {
      const Constraint& c = model.constraints[static_cast<size_t>(j)];
      if (dead(model, c)) {
        ++dead_;
        dead_items_.push_back(j);
        continue;
      }
      const bool damp = rule_ == ProjectionRule::Xpbd && c.damping != 0.0;
      damped_ = damped_ || damp;
      keys.push_back({per_item_ ? 0 : group_of[static_cast<size_t>(j)], static_cast<int>(c.kind),
                      anchored(model, c) ? 1 : 0, damp ? 1 : 0, j});
    }
    if (!per_item_)
      std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) {
        if (a.group != b.group) return a.group < b.group;
        if (a.kind != b.kind) return a.kind < b.kind;
        if (a.anchored != b.anchored) return a.anchored < b.anchored;
        if (a.damped != b.damped) return a.damped < b.damped;
        return a.index < b.index;
      });
    for (int k = 0; k < kKinds; ++k) {
      blocks_[static_cast<size_t>(k)].kind = static_cast<ConstraintKind>(k);
      blocks_[static_cast<size_t>(k)].arity = arity(static_cast<ConstraintKind>(k));
    }
    int groups = 0;
    for (const Key& key : keys) groups = std::max(groups, key.group + 1);
    groups_.assign(static_cast<size_t>(groups), {});
    for (const Key& key : keys) {
      const Constraint& c = model.constraints[static_cast<size_t>(key.index)];
      KindBlock<T>& b = blocks_[static_cast<size_t>(key.kind)];
      const int s = b.count++;
      slot_[static_cast<size_t>(key.index)] = {key.kind, s};
      b.item.push_back(key.index);
      b.rest.push_back(static_cast<T>(c.rest));
      b.rest_double.push_back(c.rest);
      for (int i = 0; i < b.arity; ++i)
        b.offset[static_cast<size_t>(i)].push_back(kStride * c.particles[static_cast<size_t>(i)]);
      // pbd: the explicit k (solver.pbd.material = stiffness), or 1 until set_substep derives
      // it from the compliance for its h (solvers/pbd_material.hpp).
      const double k = rule_ != ProjectionRule::Pbd || pbd_derived_
                           ? 1.0
                           : pbd_stiffness_[static_cast<size_t>(key.index)];
      b.stiffness.push_back(k);
      b.compliance.push_back(c.compliance);
      b.damping.push_back(c.damping);
      std::array<T, KindBlock<T>::kCoefficients> coef{};
      if (rule_ == ProjectionRule::Pbd) pbd_coefficients(model, c, k, coef);
      for (size_t n = 0; n < coef.size(); ++n) b.coef[n].push_back(coef[n]);
      if (is_fem_kind(c.kind)) {
        const FemElement& e = model.elements[static_cast<size_t>(c.element)];
        for (int r = 0; r < 3; ++r) {
          for (int col = 0; col < 3; ++col) {
            b.rest_inverse[static_cast<size_t>(3 * r + col)].push_back(static_cast<T>(e.rest_inverse(r, col)));
            b.rest_inverse_double[static_cast<size_t>(3 * r + col)].push_back(e.rest_inverse(r, col));
          }
        }
      }
      b.lambda.push_back(T(0));
      // Chunks: a new one when the group, kind or variant changes, or the chunk is full.
      Group& g = groups_[static_cast<size_t>(key.group)];
      ++g.items;
      if (g.chunks.empty() || static_cast<int>(g.chunks.back().kind) != key.kind ||
          g.chunks.back().anchored != (key.anchored != 0) || g.chunks.back().damped != (key.damped != 0) ||
          g.chunks.back().end - g.chunks.back().begin >= kChunk) {
        Chunk ch;
        ch.rule = rule_;
        ch.kind = static_cast<ConstraintKind>(key.kind);
        ch.anchored = key.anchored != 0;
        ch.damped = key.damped != 0;
        ch.jacobi = order_ == ProjectionOrder::Jacobi;
        ch.begin = ch.end = s;
        g.chunks.push_back(ch);
      }
      g.chunks.back().end = s + 1;
    }
    int total = 0;
    for (const Group& g : groups_) total += g.items;
    parallel_ = threads_.most() > 1 && !per_item_ && !groups_.empty() &&
                total / static_cast<int>(groups_.size()) >= kParallelGroup;
    if (order_ == ProjectionOrder::Jacobi) parallel_ = threads_.most() > 1 && total >= kParallelGroup;
  }

  // Jacobi: the buffer offsets of each kind, and for each moving particle the buffer entries of
  // its corrections in item order.
  void build_jacobi(const Model& model) {
    int offset = 0;
    for (int k = 0; k < kKinds; ++k) {
      jacobi_offset_[static_cast<size_t>(k)] = offset;
      offset += 3 * blocks_[static_cast<size_t>(k)].arity * blocks_[static_cast<size_t>(k)].count;
    }
    jacobi_dx_.assign(static_cast<size_t>(offset), T(0));
    for (int k = 0; k < kKinds; ++k)
      jacobi_dlambda_[static_cast<size_t>(k)].assign(static_cast<size_t>(blocks_[static_cast<size_t>(k)].count), T(0));
    incident_start_.assign(static_cast<size_t>(particles_) + 1, 0);
    for (int j = 0; j < items_; ++j) {
      if (slot_[static_cast<size_t>(j)].kind < 0) continue;
      const Constraint& c = model.constraints[static_cast<size_t>(j)];
      for (int i = 0; i < arity(c.kind); ++i) ++incident_start_[static_cast<size_t>(c.particles[static_cast<size_t>(i)]) + 1];
    }
    for (int p = 0; p < particles_; ++p) incident_start_[static_cast<size_t>(p) + 1] += incident_start_[static_cast<size_t>(p)];
    incident_.resize(static_cast<size_t>(incident_start_.back()));
    incident_stride_.resize(incident_.size());
    std::vector<int> next(incident_start_.begin(), incident_start_.end() - 1);
    for (int j = 0; j < items_; ++j) {
      const auto [kind, s] = slot_[static_cast<size_t>(j)];
      if (kind < 0) continue;
      const Constraint& c = model.constraints[static_cast<size_t>(j)];
      const int count = blocks_[static_cast<size_t>(kind)].count;
      for (int i = 0; i < arity(c.kind); ++i) {
        const int p = c.particles[static_cast<size_t>(i)];
        const size_t e = static_cast<size_t>(next[static_cast<size_t>(p)]++);
        incident_[e] = jacobi_offset_[static_cast<size_t>(kind)] + 3 * i * count + s;
        incident_stride_[e] = count;
      }
    }
    jacobi_sum_.assign(static_cast<size_t>(3 * particles_), T(0));
    jacobi_count_.assign(static_cast<size_t>(particles_), 0);
  }

  ContactItem<T> compile_contact(const Model& model, const Contact& contact, double t) const {
    ContactItem<T> c;
    c.kind = contact.kind;
    c.a = contact.a;
    c.wa = static_cast<T>(model.inv_mass[static_cast<size_t>(contact.a)]);
    const double ra = model.radius[static_cast<size_t>(contact.a)];
    const auto v3t = [](const Vec3& v) { return V3<T>{static_cast<T>(v.x()), static_cast<T>(v.y()), static_cast<T>(v.z())}; };
    switch (contact.kind) {
      case ContactKind::Plane: {
        const PlaneCollider& p = model.planes[static_cast<size_t>(contact.b)];
        const double nn = p.normal.norm();
        c.valid = nn > 0.0;
        if (c.valid) {
          c.g = v3t(p.normal / nn);
          c.r = static_cast<T>(p.offset / nn - ra);
        }
        break;
      }
      case ContactKind::Sphere: {
        const SphereCollider& s = model.spheres[static_cast<size_t>(contact.b)];
        c.g = v3t(sphere_center(model, s, t));
        c.sign = s.side == SphereSide::Outside ? T(1) : T(-1);
        c.r = static_cast<T>(s.side == SphereSide::Outside ? s.radius + ra : s.radius - ra);
        break;
      }
      case ContactKind::Particle:
        c.b = contact.b;
        c.wb = static_cast<T>(model.inv_mass[static_cast<size_t>(contact.b)]);
        c.r = static_cast<T>(ra + model.radius[static_cast<size_t>(contact.b)]);
        break;
      case ContactKind::Triangle: {
        const auto& tri = model.triangles[static_cast<size_t>(contact.b)];
        for (int k = 0; k < 3; ++k) {
          c.t[static_cast<size_t>(k)] = tri[static_cast<size_t>(k)];
          c.wt[static_cast<size_t>(k)] = static_cast<T>(model.inv_mass[static_cast<size_t>(tri[static_cast<size_t>(k)])]);
        }
        c.r = static_cast<T>(surface_contact_thickness(model, contact.a, contact.b));
        break;
      }
      case ContactKind::Edge: {
        const std::array<int, 3> others{contact.b, contact.c, contact.d};
        for (int k = 0; k < 3; ++k) {
          c.t[static_cast<size_t>(k)] = others[static_cast<size_t>(k)];
          c.wt[static_cast<size_t>(k)] = static_cast<T>(model.inv_mass[static_cast<size_t>(others[static_cast<size_t>(k)])]);
        }
        c.r = static_cast<T>(edge_contact_thickness(model, {contact.a, contact.b, contact.c, contact.d}));
        break;
      }
      case ContactKind::Mesh: {
        const MeshCollider& m = model.meshes[static_cast<size_t>(contact.b)];
        c.mesh = &m;
        c.g = v3t(mesh_offset(model, m, t));
        c.r = static_cast<T>(ra);
        break;
      }
    }
    return c;
  }

  static void load(const Points& x, std::vector<T>& out) {
    const Eigen::Index n = x.rows();
    for (Eigen::Index i = 0; i < n; ++i)
      for (int a = 0; a < 3; ++a) out[static_cast<size_t>(kStride * i + a)] = static_cast<T>(x(i, a));
  }

  // ---- kernels -----------------------------------------------------------------------------

  // A chunk through the widest kernels this run may use; a chunk of one item (the one-by-one
  // orders) in 16-byte packs, the narrowest.
  long run_chunk(const Chunk& ch) {
    const size_t k = static_cast<size_t>(ch.kind);
    const BlockView<T> b = views_[k];
    const JacobiBuffers<T> J = ch.jacobi ? jacobi_buffers(static_cast<int>(k)) : JacobiBuffers<T>{};
    T* P = P_.data();
    const T* X0 = X0_.data();
    if (ch.end - ch.begin > 1) {
      if (width_ == static_cast<int>(VectorWidth::Avx512)) return project_chunk_avx512(ch, b, P, X0, J);
      if (width_ == static_cast<int>(VectorWidth::Avx2)) return project_chunk_avx2(ch, b, P, X0, J);
    }
    return project_chunk<T, Pack<T, 16>>(ch, b, P, X0, J);
  }

  JacobiBuffers<T> jacobi_buffers(int kind) {
    JacobiBuffers<T> J;
    J.dx = jacobi_dx_.data() + jacobi_offset_[static_cast<size_t>(kind)];
    J.dlambda = rule_ == ProjectionRule::Xpbd ? jacobi_dlambda_[static_cast<size_t>(kind)].data() : nullptr;
    J.count = blocks_[static_cast<size_t>(kind)].count;
    return J;
  }

  // Contact k: C at the current positions, its projection (pbd: k = 1; xpbd: the multiplier kept
  // >= 0), whether it is violated. With Jacobi the correction goes to contact_dx_ (12 per contact)
  // and the multiplier's change to contact_dlambda_. Returns 1 when skipped.
  static Vec3 dv(const V3<T>& v) {
    return Vec3(static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z));
  }

  template <bool Jacobi>
  int project_contact(int k) {
    ContactItem<T>& c = contacts_[static_cast<size_t>(k)];
    T* P = P_.data();
    const V3<T> xa = load3(P, c.a);
    V3<T> xb{};
    T C = 0;
    V3<T> ga{}, gb{};
    // Triangle, Edge: the gradient of t[k] is -bary[k] gn, gn the unit normal (Triangle: the
    // closest point's coordinates, gn = ga; Edge: -s, 1 - t, t, ga = (1 - s) gn).
    std::array<T, 3> bary{T(0), T(0), T(0)};
    V3<T> gn{};
    bool valid = c.valid;
    switch (c.kind) {
      case ContactKind::Plane:
        C = dot(c.g, xa) + c.r;
        ga = c.g;
        break;
      case ContactKind::Sphere: {
        const V3<T> d = xa - c.g;
        const T dist = lane_sqrt(dot(d, d));
        C = c.sign * (dist - c.r);
        valid = dist > T(0);
        if (valid) ga = (c.sign / dist) * d;
        break;
      }
      case ContactKind::Particle: {
        xb = load3(P, c.b);
        const V3<T> d = xa - xb;
        const T dist = lane_sqrt(dot(d, d));
        C = dist - c.r;
        valid = dist > T(0);
        if (valid) {
          ga = (T(1) / dist) * d;
          gb = -ga;
        }
        break;
      }
      case ContactKind::Triangle: {
        // The closest point in double, as the mesh's; grad: n for a, -bary_k n for the vertices.
        const PointTriangle pt = point_triangle(dv(xa), dv(load3(P, c.t[0])), dv(load3(P, c.t[1])),
                                                dv(load3(P, c.t[2])));
        C = static_cast<T>(pt.distance) - c.r;
        ga = V3<T>{static_cast<T>(pt.normal.x()), static_cast<T>(pt.normal.y()),
                   static_cast<T>(pt.normal.z())};
        for (int k = 0; k < 3; ++k) bary[static_cast<size_t>(k)] = static_cast<T>(pt.bary[k]);
        gn = ga;
        break;
      }
      case ContactKind::Edge: {
        // The closest points in double, as the triangle's.
        const SegmentSegment ss = segment_segment(dv(xa), dv(load3(P, c.t[0])), dv(load3(P, c.t[1])),
                                                  dv(load3(P, c.t[2])));
        C = static_cast<T>(ss.distance) - c.r;
        gn = V3<T>{static_cast<T>(ss.normal.x()), static_cast<T>(ss.normal.y()),
                   static_cast<T>(ss.normal.z())};
        ga = static_cast<T>(1.0 - ss.s) * gn;
        bary = {static_cast<T>(-ss.s), static_cast<T>(1.0 - ss.t), static_cast<T>(ss.t)};
        break;
      }
      case ContactKind::Mesh: {
        // The signed distance in double (the BVH's precision), its value and gradient in T.
        const V3<T> d = xa - c.g;
        const MeshDistance md = mesh_distance(
            *c.mesh, Vec3(static_cast<double>(d.x), static_cast<double>(d.y), static_cast<double>(d.z)));
        valid = md.triangle >= 0;
        C = static_cast<T>(md.distance) - c.r;
        ga = V3<T>{static_cast<T>(md.normal.x()), static_cast<T>(md.normal.y()),
                   static_cast<T>(md.normal.z())};
        break;
      }
    }
    if constexpr (Jacobi) {
      for (int i = 0; i < kContactDx; ++i) contact_dx_[static_cast<size_t>(kContactDx * k + i)] = T(0);
      contact_dlambda_[static_cast<size_t>(k)] = T(0);
    }
    if (!valid) return 1;
    if (!(C < T(0))) return 0;
    contact_active_[static_cast<size_t>(k)] = 1;
    T wsum = c.wa * dot(ga, ga) + c.wb * dot(gb, gb);
    const bool four = c.kind == ContactKind::Triangle || c.kind == ContactKind::Edge;
    if (four)
      for (int i = 0; i < 3; ++i)
        wsum = wsum + c.wt[static_cast<size_t>(i)] * bary[static_cast<size_t>(i)] * bary[static_cast<size_t>(i)] * dot(gn, gn);
    if (!(wsum > T(0))) return 1;
    T dlambda;
    T& lambda = contact_lambda_[static_cast<size_t>(k)];
    if (rule_ == ProjectionRule::Pbd) {
      dlambda = -(C / wsum);
    } else {
      dlambda = std::max(lambda - C / wsum, T(0)) - lambda;
    }
    const V3<T> da = (c.wa * dlambda) * ga;
    const V3<T> db = (c.wb * dlambda) * gb;
    // Triangle, Edge: particle t_k moves by w_k dlambda (-bary_k n).
    std::array<V3<T>, 3> dt{};
    if (four)
      for (int i = 0; i < 3; ++i)
        dt[static_cast<size_t>(i)] = (-(c.wt[static_cast<size_t>(i)] * dlambda * bary[static_cast<size_t>(i)])) * gn;
    if constexpr (Jacobi) {
      T* q = contact_dx_.data() + kContactDx * k;
      q[0] = da.x, q[1] = da.y, q[2] = da.z;
      q[3] = db.x, q[4] = db.y, q[5] = db.z;
      if (four)
        for (int i = 0; i < 3; ++i) {
          q[3 + 3 * i] = dt[static_cast<size_t>(i)].x;
          q[4 + 3 * i] = dt[static_cast<size_t>(i)].y;
          q[5 + 3 * i] = dt[static_cast<size_t>(i)].z;
        }
      contact_dlambda_[static_cast<size_t>(k)] = dlambda;
    } else {
      lambda = lambda + dlambda;
      if (c.wa != T(0)) store3(P, c.a, xa + da);
      if (c.kind == ContactKind::Particle && c.wb != T(0)) store3(P, c.b, load3(P, c.b) + db);
      if (four)
        for (int i = 0; i < 3; ++i)
          if (c.wt[static_cast<size_t>(i)] != T(0))
            store3(P, c.t[static_cast<size_t>(i)], load3(P, c.t[static_cast<size_t>(i)]) + dt[static_cast<size_t>(i)]);
    }
    return 0;
  }

  // ---- sweeps ------------------------------------------------------------------------------

  long sweep_items() {
    long skipped = 0;
    for (int j : sequence_) {
      if (j >= items_) {
        skipped += project_contact<false>(j - items_);
        continue;
      }
      const auto [kind, s] = slot_[static_cast<size_t>(j)];
      if (kind < 0) {
        ++skipped;
        continue;
      }
      Chunk ch;
      ch.rule = rule_;
      ch.kind = static_cast<ConstraintKind>(kind);
      ch.anchored = true;
      ch.damped = damped_;
      ch.begin = s;
      ch.end = s + 1;
      skipped += run_chunk(ch);
    }
    return skipped;
  }

  long contacts_of_group(size_t g) {
    long skipped = 0;
    if (g + 1 >= contact_start_.size()) return 0;
    for (int n = contact_start_[g]; n < contact_start_[g + 1]; ++n)
      skipped += project_contact<false>(contact_order_[static_cast<size_t>(n)]);
    return skipped;
  }

  // ---- the serial sweeps ----------------------------------------------------------------

  long sweep_groups() {
    long skipped = dead_;
    const bool colored = order_ == ProjectionOrder::Colored;
    const size_t ngroups = group_count();
    if (order_ == ProjectionOrder::Reversed)
      for (int k : contact_order_) skipped += project_contact<false>(k);
    for (size_t g = 0; g < ngroups; ++g) {
      if (g < groups_.size())
        for (const Chunk& ch : groups_[g].chunks) skipped += run_chunk(ch);
      if (colored) skipped += contacts_of_group(g);
    }
    if (order_ == ProjectionOrder::Sequential)
      for (int k : contact_order_) skipped += project_contact<false>(k);
    return skipped;
  }

  long sweep_jacobi() {
    long skipped = dead_;
    for (const Chunk& ch : jacobi_chunks()) skipped += run_chunk(ch);
    for (int k = 0; k < static_cast<int>(contacts_.size()); ++k) skipped += project_contact<true>(k);
    jacobi_gather(0, particles_);
    jacobi_contacts();
    jacobi_apply(0, particles_);
    for (int k = 0; k < kKinds; ++k) jacobi_lambda(k, 0, blocks_[static_cast<size_t>(k)].count);
    jacobi_contact_lambda();
    return skipped;
  }

  // Levels or colours, with the colours that only contacts have.
  size_t group_count() const {
    if (order_ != ProjectionOrder::Colored) return groups_.size();
    return std::max(groups_.size(), contact_start_.size() - 1);
  }

  const std::vector<Chunk>& jacobi_chunks() const { return groups_.empty() ? no_chunks_ : groups_[0].chunks; }

  // ---- Jacobi's phases ----------------------------------------------------------------------

  // Particles [lo, hi): the sum and the number of their non-zero corrections, in item order.
  void jacobi_gather(int lo, int hi) {
    for (int p = lo; p < hi; ++p) {
      T sx = 0, sy = 0, sz = 0;
      int count = 0;
      for (int e = incident_start_[static_cast<size_t>(p)]; e < incident_start_[static_cast<size_t>(p) + 1]; ++e) {
        const T* d = jacobi_dx_.data() + incident_[static_cast<size_t>(e)];
        const int n = incident_stride_[static_cast<size_t>(e)];
        if (d[0] == T(0) && d[n] == T(0) && d[2 * n] == T(0)) continue;
        sx = sx + d[0], sy = sy + d[n], sz = sz + d[2 * n];
        ++count;
      }
      jacobi_sum_[static_cast<size_t>(3 * p)] = sx;
      jacobi_sum_[static_cast<size_t>(3 * p + 1)] = sy;
      jacobi_sum_[static_cast<size_t>(3 * p + 2)] = sz;
      jacobi_count_[static_cast<size_t>(p)] = count;
    }
  }

  // The contacts' corrections after the model's (items m.. come last).
  void jacobi_contacts() {
    for (size_t k = 0; k < contacts_.size(); ++k) {
      const ContactItem<T>& c = contacts_[k];
      const T* d = contact_dx_.data() + kContactDx * k;
      const int sides = c.kind == ContactKind::Particle                                    ? 2
                        : c.kind == ContactKind::Triangle || c.kind == ContactKind::Edge ? 4
                                                                                          : 1;
      for (int side = 0; side < sides; ++side) {
        const T* q = d + 3 * side;
        if (q[0] == T(0) && q[1] == T(0) && q[2] == T(0)) continue;
        const size_t p = static_cast<size_t>(side == 0                            ? c.a
                                             : c.kind == ContactKind::Particle ? c.b
                                                                               : c.t[static_cast<size_t>(side - 1)]);
        jacobi_sum_[3 * p] = jacobi_sum_[3 * p] + q[0];
        jacobi_sum_[3 * p + 1] = jacobi_sum_[3 * p + 1] + q[1];
        jacobi_sum_[3 * p + 2] = jacobi_sum_[3 * p + 2] + q[2];
        ++jacobi_count_[p];
      }
    }
  }

  // x_p += omega (sum) / (count, with averaging) for the particles [lo, hi).
  void jacobi_apply(int lo, int hi) {
    const T omega = static_cast<T>(relaxation_);
    for (int p = lo; p < hi; ++p) {
      const int count = jacobi_count_[static_cast<size_t>(p)];
      if (count == 0) continue;
      const T scale = averaging_ ? omega / static_cast<T>(count) : omega;
      T* x = P_.data() + kStride * p;
      x[0] = x[0] + scale * jacobi_sum_[static_cast<size_t>(3 * p)];
      x[1] = x[1] + scale * jacobi_sum_[static_cast<size_t>(3 * p + 1)];
      x[2] = x[2] + scale * jacobi_sum_[static_cast<size_t>(3 * p + 2)];
    }
  }

  // lambda += omega dlambda for the slots [lo, hi) of a kind (xpbd).
  void jacobi_lambda(int kind, int lo, int hi) {
    if (rule_ != ProjectionRule::Xpbd) return;
    const T omega = static_cast<T>(relaxation_);
    KindBlock<T>& b = blocks_[static_cast<size_t>(kind)];
    const T* dl = jacobi_dlambda_[static_cast<size_t>(kind)].data();
    for (int s = lo; s < hi; ++s) b.lambda[static_cast<size_t>(s)] = b.lambda[static_cast<size_t>(s)] + omega * dl[s];
  }

  void jacobi_contact_lambda() {
    const T omega = static_cast<T>(relaxation_);
    for (size_t k = 0; k < contacts_.size(); ++k)
      contact_lambda_[k] = contact_lambda_[k] + omega * contact_dlambda_[k];
  }

  // ---- the threaded sweeps ----------------------------------------------------------------

  // A unit of work of a threaded sweep (solvers/staged_tasks.hpp).
  struct Task {
    enum Kind : std::uint8_t { ChunkOf, ContactsOf, Gather, Contacts, Apply, Lambda, ContactLambda } kind;
    int a = 0, b = 0, c = 0;  // ChunkOf: group, chunk; ContactsOf: group; Gather/Apply: particles
                              // [a, b); Lambda: kind c, slots [a, b)
  };

  // `iterations` sweeps as tasks in stages: a colour's chunks and contacts, colour after colour;
  // Jacobi's items, then its particles' sums, the contacts' sums, the updates.
  long threaded_sweeps(int iterations, int threads) {
    tasks_.clear();
    wait_.clear();
    int stage = 0;  // tasks before the current stage
    const auto add = [&](Task t) {
      tasks_.push_back(t);
      wait_.push_back(stage);
    };
    const auto next_stage = [&] { stage = static_cast<int>(tasks_.size()); };
    const bool colored = order_ == ProjectionOrder::Colored;
    for (int it = 0; it < iterations; ++it) {
      if (order_ == ProjectionOrder::Jacobi) {
        const std::vector<Chunk>& chunks = jacobi_chunks();
        for (int n = 0; n < static_cast<int>(chunks.size()); ++n) add({Task::ChunkOf, 0, n});
        add({Task::Contacts, 0, 0});
        next_stage();
        for (int p = 0; p < particles_; p += kChunk) add({Task::Gather, p, std::min(particles_, p + kChunk)});
        next_stage();
        add({Task::Contacts, 1, 0});
        next_stage();
        for (int p = 0; p < particles_; p += kChunk) add({Task::Apply, p, std::min(particles_, p + kChunk)});
        for (int k = 0; k < kKinds; ++k)
          for (int s = 0; s < blocks_[static_cast<size_t>(k)].count; s += kChunk)
            add({Task::Lambda, s, std::min(blocks_[static_cast<size_t>(k)].count, s + kChunk), k});
        add({Task::ContactLambda});
        next_stage();
        continue;
      }
      for (size_t g = 0; g < group_count(); ++g) {
        if (g < groups_.size())
          for (int n = 0; n < static_cast<int>(groups_[g].chunks.size()); ++n) add({Task::ChunkOf, static_cast<int>(g), n});
        if (colored && g + 1 < contact_start_.size() && contact_start_[g] < contact_start_[g + 1])
          add({Task::ContactsOf, static_cast<int>(g)});
        next_stage();
      }
    }
    skipped_by_thread_.assign(static_cast<size_t>(threads), 0);
    run_staged(threads, wait_, [&](int k, int thread) {
      const Task& t = tasks_[static_cast<size_t>(k)];
      long sk = 0;
      switch (t.kind) {
        case Task::ChunkOf: {
          const std::vector<Chunk>& chunks = order_ == ProjectionOrder::Jacobi ? jacobi_chunks() : groups_[static_cast<size_t>(t.a)].chunks;
          sk = run_chunk(chunks[static_cast<size_t>(t.b)]);
          break;
        }
        case Task::ContactsOf: sk = contacts_of_group(static_cast<size_t>(t.a)); break;
        case Task::Contacts:
          if (t.a == 0)
            for (int c = 0; c < static_cast<int>(contacts_.size()); ++c) sk += project_contact<true>(c);
          else
            jacobi_contacts();
          break;
        case Task::Gather: jacobi_gather(t.a, t.b); break;
        case Task::Apply: jacobi_apply(t.a, t.b); break;
        case Task::Lambda: jacobi_lambda(t.c, t.a, t.b); break;
        case Task::ContactLambda: jacobi_contact_lambda(); break;
      }
      skipped_by_thread_[static_cast<size_t>(thread)] += sk;
    });
    long skipped = dead_ * iterations;
    for (long sk : skipped_by_thread_) skipped += sk;
    return skipped;
  }

  struct Slot {
    int kind = -1;  // -1: a dead item
    int slot = -1;
  };

  const Model* compiled_model_;  // the model compiled (compared by address only)
  bool rest_compiled_ = true;    // the rest values are compiled_model_'s
  ProjectionRule rule_;
  int width_;  // register bytes the kernels may use (solvers/projection_wide.hpp)
  ProjectionOrder order_;
  SweepThreads threads_;  // solver.threads: the most, and for 0 the count of each sweep
  double relaxation_;
  bool averaging_;
  int particles_;
  int items_;
  double h_ = 0.0;  // the h of the xpbd coefficients (pbd: of the derived k), 0 before the
                    // first substep
  bool pbd_derived_ = false;                   // pbd, solver.pbd.material = compliance
  int pbd_iterations_ = 1;                     // n of the derivation
  std::vector<double> pbd_inverse_mass_sums_;  // (m) S of each model constraint, when derived
  std::vector<double> pbd_stiffness_;          // (m) the explicit k (or k'), when not derived
  bool per_item_ = false;
  bool parallel_ = false;
  bool damped_ = false;
  long dead_ = 0;  // model items never applied (skipped in every sweep)
  std::vector<int> dead_items_;  // their indices
  mutable std::vector<double> residual_positions_;  // (n x kStride) scratch of constraint_residuals
  mutable std::array<std::vector<double>, kKinds> residual_terms_;  // [kind] (count): its h_j
  std::vector<char> moving_;  // (n) inv_mass != 0
  std::array<KindBlock<T>, kKinds> blocks_;
  std::array<BlockView<T>, kKinds> views_;  // of blocks_, taken once they are built
  std::vector<Slot> slot_;     // (m) where each model item is compiled
  std::vector<Group> groups_;  // levels or colours, in visiting order
  std::vector<Chunk> no_chunks_;
  std::vector<int> sequence_;  // per-item orders: this sweep's sequence
  std::vector<T> P_;           // (n x kStride) m, the positions being projected
  std::vector<T> X0_;          // (n x kStride) m, the substep's starting positions (damping)
  // The substep's contacts.
  std::vector<ContactItem<T>> contacts_;
  std::vector<T> contact_lambda_;
  std::vector<char> contact_active_;
  std::vector<int> contact_order_;  // visiting order (Colored: by colour)
  std::vector<int> contact_start_;  // Colored: contacts of colour g are contact_order_[start[g], start[g+1])
  // Jacobi.
  std::array<int, kKinds> jacobi_offset_{};
  std::vector<T> jacobi_dx_;
  std::array<std::vector<T>, kKinds> jacobi_dlambda_;
  std::vector<int> incident_start_, incident_;  // per moving particle: its corrections' offsets
  std::vector<int> incident_stride_;            // and the distance between their components
  std::vector<T> jacobi_sum_;
  std::vector<int> jacobi_count_;
  std::vector<T> contact_dx_, contact_dlambda_;
  // Threaded sweeps.
  std::vector<Task> tasks_;
  std::vector<int> wait_;
  std::vector<long> skipped_by_thread_;
};

}  // namespace

std::unique_ptr<CompiledProjection> compile_projection(const Model& model,
                                                       const SolverOptions& options,
                                                       ProjectionRule rule,
                                                       const Ordering& ordering,
                                                       bool one_by_one, int width) {
  for (const Constraint& c : model.constraints)
    if (is_strain_kind(c.kind))
      throw std::invalid_argument(std::string("compile_projection: the ") + to_string(c.kind) +
                                  " constraints are vector constraints, projected item by item "
                                  "(solvers/xpbd.cpp)");
  if (options.precision == Precision::Float)
    return std::make_unique<Program<float>>(model, options, rule, ordering, one_by_one, width);
  return std::make_unique<Program<double>>(model, options, rule, ordering, one_by_one, width);
}

VectorWidth widest_vector_width() {
  static const VectorWidth widest = [] {
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f")) return VectorWidth::Avx512;
    if (__builtin_cpu_supports("avx2")) return VectorWidth::Avx2;
    return VectorWidth::Sse2;
  }();
  return widest;
}

}  // namespace pbdbench
