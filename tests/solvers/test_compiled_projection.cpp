// Tests of solvers/compiled_projection.cpp: the compiled sweeps against the per-item path (the
// reference implementation: core/constraint_functions.hpp and solvers/kernels.hpp item by item),
// in every order, both rules and both precisions; the same bits at any thread count and, kernel
// by kernel (solvers/projection_kernels.hpp), in every register width; and the
// sequential order's levels against the one-by-one order of the same kernels.
#include <gtest/gtest.h>

#include <bit>

#include <algorithm>
#include <cmath>
#include <random>
#include <cstdint>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "core/fem.hpp"
#include "core/generators.hpp"
#include "solver_test_util.hpp"
#include "solvers/projection_wide.hpp"
#include "solvers/step_common.hpp"

namespace pbdbench::test {
namespace {

std::unique_ptr<Solver> make(const SolverOptions& o, const Model& m, ProjectionPath path) {
  return o.name == "pbd" ? make_pbd_solver(o, m, path) : make_xpbd_solver(o, m, path);
}

// A hanging cloth of n x n particles (stretch, shear, dihedral bending), pinned at two corners,
// compliant for xpbd.
Model cloth(int n, bool bending = true) {
  Model m = empty_model(Vec3(0.0, -9.81, 0.0));
  ClothSpec spec;
  spec.nx = spec.ny = n;
  spec.bending = bending;
  spec.origin = Vec3(-0.5, 1.0, 0.0);
  spec.stretch = {1e-4, 1.0, 0.0};
  spec.shear_params = {1e-3, 0.9, 0.01};
  spec.bending_params = {10.0, 0.1, 0.0};
  add_cloth(m, spec);
  for (int p : {0, n - 1}) {
    m.inv_mass[static_cast<size_t>(p)] = 0.0;
    m.attachments.push_back({p, Vec3(m.rest_positions.row(p)), -1});
  }
  return m;
}

// A clamped beam of stable neo-Hookean elements (xpbd's FEM kinds) alone.
Model fem_beam() {
  Model m = empty_model(Vec3(0.0, -9.81, 0.0));
  TetBlockSpec spec;
  spec.cells = {4, 1, 1};
  spec.size = Vec3(0.4, 0.1, 0.1);
  spec.edges = false;
  spec.volumes = false;
  add_tet_block(m, spec);
  fem::add_fem_elements(m, m.tets, Material::StableNeoHookean, 1e6, 0.3);
  for (int p = 0; p < m.particle_count(); ++p)
    if (m.rest_positions(p, 0) < 1e-9) {
      m.inv_mass[static_cast<size_t>(p)] = 0.0;
      m.attachments.push_back({p, Vec3(m.rest_positions.row(p)), -1});
    }
  return m;
}

struct Case {
  std::string name;
  Model model;
  double dt;
  int iterations, substeps;
  double margin;
  Vec3 v0;  // initial velocity of the dynamic particles
};

std::vector<Case> cases() {
  return {{"mixed", mixed_scene(), 1.0 / 60.0, 5, 2, 0.01, Vec3(0.3, -0.6, 0.2)},
          {"cloth", cloth(12), 1.0 / 60.0, 10, 1, 0.0, Vec3(0.0, 0.0, 0.3)},
          {"beam", fem_beam(), 1.0 / 60.0, 2, 8, 0.0, Vec3(0.0, -0.2, 0.0)}};
}

// |a - b| over x, v and the multipliers, relative to the largest |b| of each (1 m, 1 m/s at
// least), as one number.
double relative_difference(const State& a, const State& b) {
  const double x = max_abs_diff(a.x, b.x) / std::max(1.0, b.x.cwiseAbs().maxCoeff());
  const double v = max_abs_diff(a.v, b.v) / std::max(1.0, b.v.cwiseAbs().maxCoeff());
  double l = 0.0, scale = 1.0;
  for (size_t j = 0; j < a.lambda.size(); ++j) {
    if (std::isnan(b.lambda[j])) continue;
    l = std::max(l, std::abs(a.lambda[j] - b.lambda[j]));
    scale = std::max(scale, std::abs(b.lambda[j]));
  }
  return std::max({x, v, l / scale});
}

// From states along the per-item path's run, one step of each path: the compiled step agrees
// with the per-item one to the round-off of the operations they order differently (the compiled
// kernels precompute w_i / sum w and 1 / D): `tolerance` relative. Returns the largest difference.
double compare_paths(const Case& c, SolverOptions o, double tolerance) {
  o.contact_margin = c.margin;
  auto reference = make(o, c.model, ProjectionPath::PerItem);
  auto compiled = make(o, c.model, ProjectionPath::Compiled);
  State s = rest_state(c.model);
  for (int i = 0; i < c.model.particle_count(); ++i)
    if (c.model.inv_mass[static_cast<size_t>(i)] > 0.0) s.v.row(i) = c.v0.transpose();
  double worst = 0.0;
  for (int n = 0; n < 12; ++n) {
    State a = s, b = s;
    const StepReport ra = reference->step(c.model, a, c.dt);
    const StepReport rb = compiled->step(c.model, b, c.dt);
    const double d = relative_difference(b, a);
    worst = std::max(worst, d);
    EXPECT_LE(d, tolerance) << c.name << " step " << n;
    // The xpbd residuals: sums of terms that cancel (M (x - x~) against grad C^T lambda), so
    // their round-off is relative to the terms, not to the result: 1e-6 of the larger plus an
    // absolute 1e-9.
    if (o.name == "xpbd" && o.precision == Precision::Double) {
      EXPECT_NEAR(rb.residual_g, ra.residual_g, 1e-9 + 1e-6 * std::abs(ra.residual_g)) << c.name << " step " << n;
      EXPECT_NEAR(rb.residual_h, ra.residual_h, 1e-9 + 1e-6 * std::abs(ra.residual_h)) << c.name << " step " << n;
    }
    EXPECT_EQ(rb.iterations, ra.iterations);
    EXPECT_EQ(rb.contacts, ra.contacts);
    // In float the bending's validity test (sin^2 theta >= 1e-12) meets float round-off near
    // flat, where the two paths may decide differently.
    if (o.precision == Precision::Double) {
      EXPECT_EQ(rb.skipped, ra.skipped) << c.name << " step " << n;
    }
    s = a;
  }
  return worst;
}

TEST(CompiledProjection, MatchesThePerItemPathInEveryOrder) {
  // Double: the kernels' different grouping of the same operations, amplified over a step's
  // sweeps: 1e-10 relative is a million ulps, far below any change of the physics (a wrong sign
  // or a missing term moves the result by 1e-3 or more), far above what was measured.
  double worst = 0.0;
  for (const Case& c : cases())
    for (const std::string name : {"pbd", "xpbd"}) {
      if (name == "pbd" && !c.model.elements.empty()) continue;  // pbd refuses FEM
      for (ProjectionOrder order : all_orders())
        for (int variant = 0; variant < 3; ++variant) {
          if (variant == 2 && name != "pbd") continue;
          SCOPED_TRACE(c.name + " " + name + " " + to_string(order) + " variant " +
                       std::to_string(variant));
          SolverOptions o = options_for(name, c.iterations, c.substeps);
          o.order = order;
          if (variant == 1) {
            o.pbd_stiffness_correction = true;
            o.jacobi_relaxation = 0.7;
            o.jacobi_averaging = false;
          }
          // pbd's default material: k derived from the compliances for the substep.
          if (variant == 2) o.pbd_material = PbdMaterial::Compliance;
          worst = std::max(worst, compare_paths(c, o, 1e-10));
        }
    }
  std::cout << "[ measured ] largest relative difference, compiled against per-item, one step: "
            << worst << "\n";
}

TEST(CompiledProjection, FloatMatchesThePerItemPathToFloatRoundoff) {
  // Float: the compiled path computes in float, the per-item path in double rounded to float at
  // every write; one step apart they differ by float round-off (6e-8) over the step's
  // operations: 1e-4 relative. Two things are discontinuous in round-off and are left out: the
  // dihedral angle of a nearly flat cloth (its validity test, sin^2 theta >= 1e-12, decided
  // differently by the two: the cloth here has no bending; the mixed scene's bending is far
  // from flat), and Jacobi's averaging, which divides by the number of non-zero corrections (a
  // constraint at rest has C = 0 in one path and C = 1e-9 in the other: averaging off here, and
  // the relaxation 0.1, which keeps unaveraged Jacobi stable on these scenes).
  std::vector<Case> all = cases();
  all[1] = {"cloth", cloth(12, false), 1.0 / 60.0, 10, 1, 0.0, Vec3(0.0, 0.0, 0.3)};
  for (const Case& c : all)
    for (const std::string name : {"pbd", "xpbd"}) {
      if (name == "pbd" && !c.model.elements.empty()) continue;
      for (ProjectionOrder order : all_orders()) {
        SCOPED_TRACE(c.name + " " + name + " " + to_string(order));
        SolverOptions o = options_for(name, c.iterations, c.substeps);
        o.order = order;
        o.precision = Precision::Float;
        o.jacobi_averaging = false;
        o.jacobi_relaxation = 0.1;
        compare_paths(c, o, 1e-4);
      }
    }
}

// FNV-1a over the bits of x, v and lambda.
std::uint64_t state_hash(const State& s) {
  std::uint64_t h = 1469598103934665603ull;
  auto eat = [&](const double* p, size_t n) {
    const auto* b = reinterpret_cast<const unsigned char*>(p);
    for (size_t i = 0; i < sizeof(double) * n; ++i) {
      h ^= b[i];
      h *= 1099511628211ull;
    }
  };
  eat(s.x.data(), static_cast<size_t>(s.x.size()));
  eat(s.v.data(), static_cast<size_t>(s.v.size()));
  eat(s.lambda.data(), s.lambda.size());
  return h;
}

TEST(CompiledProjection, TheSameBitsAtAnyThreadCount) {
  // A 130 x 130 cloth: its colours hold thousands of items each, so the colored order runs in
  // threads (and Jacobi always does with threads > 1). 1, 2 and 3 threads give the same bits, and
  // xpbd's residuals (in threads too in colored order) the same bits.
  const Model m = cloth(130);
  for (const std::string name : {"pbd", "xpbd"})
    for (ProjectionOrder order : {ProjectionOrder::Colored, ProjectionOrder::Jacobi,
                                  ProjectionOrder::Sequential})
      for (Precision precision : {Precision::Double, Precision::Float}) {
        SCOPED_TRACE(name + " " + to_string(order) + " " + to_string(precision));
        std::uint64_t first = 0;
        double first_g = 0.0, first_h = 0.0;
        for (int threads : {1, 2, 3, 0}) {  // 0: each sweep on the cores or on one (sweep_threads.hpp)
          SolverOptions o = options_for(name, 3, 1);
          o.order = order;
          o.precision = precision;
          o.threads = threads;
          auto sv = make_solver(o, m);
          // The threads a step runs on (what the run's logging asks): sequential never threads.
          const int most = order == ProjectionOrder::Sequential ? 1 : resolve_threads(threads);
          EXPECT_EQ(sv->threads(), most);
          State s = rest_state(m);
          StepReport r;
          for (int n = 0; n < 2; ++n) r = sv->step(m, s, 1.0 / 60.0);
          const std::uint64_t h = state_hash(s);
          if (threads == 1) {
            first = h;
            first_g = r.residual_g;
            first_h = r.residual_h;
          }
          EXPECT_EQ(h, first) << threads << " threads";
          if (name == "xpbd") {
            EXPECT_GT(r.residual_g, 0.0);
            EXPECT_GT(r.residual_h, 0.0);
          }
          EXPECT_EQ(std::bit_cast<std::uint64_t>(r.residual_g), std::bit_cast<std::uint64_t>(first_g)) << threads << " threads";
          EXPECT_EQ(std::bit_cast<std::uint64_t>(r.residual_h), std::bit_cast<std::uint64_t>(first_h)) << threads << " threads";
        }
      }
}

TEST(CompiledProjection, LevelsAndColoursAreTheOneByOneOrderBitForBit) {
  // Sequential and reversed run in dependency levels, colored colour by colour with the kinds
  // grouped: each must give the bits of the same kernels visiting the items one by one in the
  // ordering's sequence, in both precisions, with contacts (the mixed scene) and without.
  for (const Case& c : cases())
    for (const std::string name : {"pbd", "xpbd"}) {
      if (name == "pbd" && !c.model.elements.empty()) continue;
      for (ProjectionOrder order : {ProjectionOrder::Sequential, ProjectionOrder::Reversed,
                                    ProjectionOrder::Colored})
        for (Precision precision : {Precision::Double, Precision::Float}) {
          SCOPED_TRACE(c.name + " " + name + " " + to_string(order) + " " + to_string(precision));
          SolverOptions o = options_for(name, c.iterations, c.substeps);
          o.order = order;
          o.precision = precision;
          o.contact_margin = c.margin;
          auto batched = make(o, c.model, ProjectionPath::Compiled);
          auto single = make(o, c.model, ProjectionPath::CompiledOneByOne);
          State a = rest_state(c.model);
          for (int i = 0; i < c.model.particle_count(); ++i)
            if (c.model.inv_mass[static_cast<size_t>(i)] > 0.0) a.v.row(i) = c.v0.transpose();
          State b = a;
          for (int n = 0; n < 12; ++n) {
            batched->step(c.model, a, c.dt);
            single->step(c.model, b, c.dt);
          }
          EXPECT_EQ(state_hash(a), state_hash(b));
          EXPECT_EQ(max_abs_diff(a.x, b.x), 0.0);
        }
    }
}


// ---------------------------------------------------------------------------------------------
// The kernels of solvers/projection_kernels.hpp in every register width this processor has (16
// bytes always; AVX2 and AVX-512 where present): the same bits. A block of `count` items of one
// kind, each on particles of its own (as the items of a colour), at random positions, rest
// values, coefficients and multipliers; 37 items, so that every width ends with a partial pack.
struct KernelCase {
  ConstraintKind kind;
  int arity;
  std::vector<double> P, X0;                        // (n x kStride), each row's fourth its w
  std::array<std::vector<std::int32_t>, 4> offset;  // kStride x particle index
  std::vector<double> rest, lambda, compliance;
  std::array<std::vector<double>, 3> coef;
  std::array<std::vector<double>, 9> rest_inverse;
  BlockView<double> view() {
    BlockView<double> v;
    for (int i = 0; i < arity; ++i) v.offset[i] = offset[static_cast<size_t>(i)].data();
    v.rest = rest.data();
    for (int c = 0; c < 3; ++c) v.coef[c] = coef[static_cast<size_t>(c)].data();
    for (int k = 0; k < 9; ++k) v.rest_inverse[k] = rest_inverse[static_cast<size_t>(k)].data();
    v.lambda = lambda.data();
    return v;
  }
};

KernelCase kernel_case(ConstraintKind kind, int count, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0), pos(0.05, 1.0);
  KernelCase c;
  c.kind = kind;
  c.arity = kind == ConstraintKind::Distance ? 2 : 4;
  const int n = c.arity * count;
  c.P.assign(static_cast<size_t>(kStride * n), 0.0);
  c.X0.assign(c.P.size(), 0.0);
  for (int p = 0; p < n; ++p)
    for (int a = 0; a < 3; ++a) {
      c.P[static_cast<size_t>(kStride * p + a)] = u(rng);
      c.X0[static_cast<size_t>(kStride * p + a)] = c.P[static_cast<size_t>(kStride * p + a)] + 0.01 * u(rng);
    }
  for (int i = 0; i < c.arity; ++i)
    for (int s = 0; s < count; ++s) {
      c.offset[static_cast<size_t>(i)].push_back(kStride * (c.arity * s + i));
      c.P[static_cast<size_t>(kStride * (c.arity * s + i) + 3)] = s % 7 == 3 && i == 1 ? 0.0 : pos(rng);
    }
  for (int s = 0; s < count; ++s) {
    c.rest.push_back(kind == ConstraintKind::Bending ? 2.0 * pos(rng) : pos(rng));
    c.lambda.push_back(s % 5 == 0 ? 0.0 : 0.1 * u(rng));
    c.compliance.push_back(s % 3 == 0 ? 0.0 : 1e-3 * pos(rng));
    for (auto& k : c.coef) k.push_back(pos(rng));
    for (auto& k : c.rest_inverse) k.push_back(u(rng));
  }
  return c;
}

// The register widths this processor runs: 16 always, 32 and 64 where it has them.
std::vector<int> widths() {
  std::vector<int> w = {16};
  if (static_cast<int>(widest_vector_width()) >= 32) w.push_back(32);
  if (static_cast<int>(widest_vector_width()) >= 64) w.push_back(64);
  return w;
}

// Lanes::position and Lanes::store (solvers/projection_kernels.hpp) in packs of every width, 64
// bytes included (GCC's generic vectors, lowered to the registers this file is compiled for, so
// that the 8-lane shuffles are checked on any processor): lane k holds the coordinates of the
// particle at offset idx[k] (x, y, z, and its fourth scalar w), full and partial packs; a store
// writes x, y, z and w of the lanes asked for, and no other particle.
template <class T, int Bytes, bool Partial>
void check_lanes(int n_active) {
  using W = Pack<T, Bytes>;
  using Ln = Lanes<T, W, Partial>;
  constexpr int kW = W::kWidth;
  const int particles = 3 * kW + 5;
  std::vector<T> P(static_cast<size_t>(kStride * particles), T(0));
  for (int p = 0; p < particles; ++p)
    for (int a = 0; a < 4; ++a) P[static_cast<size_t>(kStride * p + a)] = static_cast<T>(10 * p + a + 1);
  // The lanes' particles: distinct, out of order.
  std::vector<std::int32_t> idx;
  for (int k = 0; k < kW; ++k) idx.push_back(kStride * ((7 * k + 3) % particles));
  Ln ln;
  if constexpr (Partial) ln.n = n_active;
  W w;
  const V3<W> x = ln.position(P.data(), idx.data(), w);
  const V3<W> x_only = ln.position(P.data(), idx.data());
  for (int k = 0; k < kW; ++k) {
    const int p = idx[static_cast<size_t>(Partial && k >= n_active ? 0 : k)] / kStride;
    EXPECT_EQ(x.x[k], static_cast<T>(10 * p + 1)) << Bytes << " bytes, lane " << k;
    EXPECT_EQ(x.y[k], static_cast<T>(10 * p + 2)) << Bytes << " bytes, lane " << k;
    EXPECT_EQ(x.z[k], static_cast<T>(10 * p + 3)) << Bytes << " bytes, lane " << k;
    EXPECT_EQ(w[k], static_cast<T>(10 * p + 4)) << Bytes << " bytes, lane " << k;
    EXPECT_EQ(x_only.x[k], x.x[k]);
    EXPECT_EQ(x_only.y[k], x.y[k]);
    EXPECT_EQ(x_only.z[k], x.z[k]);
  }
  // Store lane k's particle moved by -(k + 1) in x, -(k + 1) / 2 in y, -(k + 1) / 4 in z, and w
  // by -(k + 1) / 8 (a store writes the w it is given), for the lanes of a mask that leaves out
  // lane 1 (and every lane, below).
  for (const int mask : {(1 << kW) - 1 - 2, (1 << kW) - 1}) {
    std::vector<T> Q = P;
    V3<W> y{W(T(0)), W(T(0)), W(T(0))};
    W yw(T(0));
    for (int k = 0; k < kW; ++k) {
      y.x.set(k, x.x[k] - static_cast<T>(k + 1));
      y.y.set(k, x.y[k] - static_cast<T>(k + 1) / 2);
      y.z.set(k, x.z[k] - static_cast<T>(k + 1) / 4);
      yw.set(k, w[k] - static_cast<T>(k + 1) / 8);
    }
    ln.store(Q.data(), idx.data(), y, yw, mask);
    std::vector<T> expected = P;
    for (int k = 0; k < (Partial ? n_active : kW); ++k) {
      if (!((mask >> k) & 1)) continue;
      const size_t o = static_cast<size_t>(idx[static_cast<size_t>(k)]);
      expected[o] = y.x[k];
      expected[o + 1] = y.y[k];
      expected[o + 2] = y.z[k];
      expected[o + 3] = yw[k];
    }
    EXPECT_EQ(Q, expected) << Bytes << " bytes, " << (Partial ? n_active : kW) << " lanes, mask " << mask;
  }
}

TEST(ProjectionKernels, LanesGatherAndStoreEachLanesParticle) {
  check_lanes<double, 16, false>(0);
  check_lanes<double, 32, false>(0);
  check_lanes<double, 64, false>(0);
  check_lanes<float, 16, false>(0);
  check_lanes<float, 32, false>(0);
  check_lanes<float, 64, false>(0);
  for (int n = 1; n < 2; ++n) check_lanes<double, 16, true>(n);
  for (int n = 1; n < 4; ++n) check_lanes<double, 32, true>(n);
  for (int n = 1; n < 8; ++n) check_lanes<double, 64, true>(n);
  for (int n = 1; n < 4; ++n) check_lanes<float, 16, true>(n);
  for (int n = 1; n < 8; ++n) check_lanes<float, 32, true>(n);
  for (int n = 1; n < 16; ++n) check_lanes<float, 64, true>(n);
}

TEST(ProjectionKernels, EveryWidthGivesTheSameBits) {
  constexpr int kCount = 37;
  const std::vector<int> ws = widths();
  std::cout << "register widths compared: " << ws.size() << " (widest " << ws.back() << " bytes)\n";
  int compared = 0;
  for (const ConstraintKind kind : {ConstraintKind::Distance, ConstraintKind::Volume, ConstraintKind::Bending})
    for (const ProjectionRule rule : {ProjectionRule::Pbd, ProjectionRule::Xpbd})
      for (const bool damped : {false, true})
        for (const bool jacobi : {false, true}) {
          if (damped && rule == ProjectionRule::Pbd) continue;
          std::vector<double> first_P, first_lambda, first_dx, first_dl;
          long first_skipped = -1;
          for (const int w : ws) {
            KernelCase c = kernel_case(kind, kCount, 7u);
            std::vector<double> dx(static_cast<size_t>(c.arity * 3 * kCount), -1.0), dl(kCount, -1.0);
            JacobiBuffers<double> J;
            if (jacobi) J = {dx.data(), dl.data(), kCount};
            ChunkSpec spec;
            spec.rule = rule;
            spec.kind = kind;
            spec.anchored = true;  // some items have a particle with w = 0
            spec.damped = damped;
            spec.jacobi = jacobi;
            spec.begin = 0;
            spec.end = kCount;
            const BlockView<double> v = c.view();
            long skipped = 0;
            if (w == 16) skipped = project_chunk<double, Pack<double, 16>>(spec, v, c.P.data(), c.X0.data(), J);
            if (w == 32) skipped = project_chunk_avx2(spec, v, c.P.data(), c.X0.data(), J);
            if (w == 64) skipped = project_chunk_avx512(spec, v, c.P.data(), c.X0.data(), J);
            if (first_skipped < 0) {
              first_P = c.P;
              first_lambda = c.lambda;
              first_dx = dx;
              first_dl = dl;
              first_skipped = skipped;
              // The kernel moved something (Jacobi: into its buffers).
              if (jacobi) EXPECT_NE(dx, std::vector<double>(dx.size(), -1.0));
              else EXPECT_NE(c.P, kernel_case(kind, kCount, 7u).P);
              continue;
            }
            const std::string what = std::to_string(static_cast<int>(kind)) + (rule == ProjectionRule::Xpbd ? " xpbd" : " pbd") +
                                     (damped ? " damped" : "") + (jacobi ? " jacobi" : "") + ", width " + std::to_string(w);
            EXPECT_EQ(skipped, first_skipped) << what;
            // Bit for bit (EXPECT_EQ on vectors of doubles compares with ==; memcmp also sees
            // the sign of a zero).
            EXPECT_EQ(0, std::memcmp(c.P.data(), first_P.data(), c.P.size() * sizeof(double))) << what;
            EXPECT_EQ(0, std::memcmp(c.lambda.data(), first_lambda.data(), c.lambda.size() * sizeof(double))) << what;
            EXPECT_EQ(0, std::memcmp(dx.data(), first_dx.data(), dx.size() * sizeof(double))) << what;
            EXPECT_EQ(0, std::memcmp(dl.data(), first_dl.data(), dl.size() * sizeof(double))) << what;
            ++compared;
          }
        }
  // The residuals (xpbd's eqs. 8 and 9) in every width, and against the per-item formula.
  for (const ConstraintKind kind : {ConstraintKind::Distance, ConstraintKind::Volume, ConstraintKind::Bending}) {
    std::vector<double> first_terms, first_g;
    for (const int w : ws) {
      KernelCase c = kernel_case(kind, kCount, 11u);
      const int n = c.arity * kCount;
      std::vector<char> moving(static_cast<size_t>(n), 1);
      moving[5] = 0;  // a pinned particle: its g is not written
      std::vector<double> terms(kCount, -1.0), g(static_cast<size_t>(3 * n), 0.5);
      ResidualArgs<double> r;
      r.P = c.P.data();
      r.compliance = c.compliance.data();
      r.lambda = c.lambda.data();
      r.moving = moving.data();
      r.h2 = 1e-4;
      r.terms = terms.data();
      r.g = g.data();
      const BlockView<double> v = c.view();
      if (w == 16) residual_chunk<Pack<double, 16>>(kind, v, 0, kCount, r);
      if (w == 32) residual_chunk_avx2(kind, v, 0, kCount, r);
      if (w == 64) residual_chunk_avx512(kind, v, 0, kCount, r);
      EXPECT_EQ(g[3 * 5], 0.5);
      if (first_terms.empty()) {
        first_terms = terms;
        first_g = g;
        // h_j = C_j + alpha_j / h^2 lambda_j, C_j by the stencil of one item at a time; g of a
        // particle: 0.5 - lambda_j grad C_j (each particle belongs to one item).
        for (int s = 0; s < kCount; ++s) {
          std::array<V3<double>, 4> x;
          for (int i = 0; i < c.arity; ++i) x[static_cast<size_t>(i)] = load3(c.P.data(), c.offset[static_cast<size_t>(i)][static_cast<size_t>(s)] / kStride);
          const StencilEval<double> e =
              kind == ConstraintKind::Distance ? distance_stencil(x[0], x[1], c.rest[static_cast<size_t>(s)])
              : kind == ConstraintKind::Volume ? volume_stencil(x[0], x[1], x[2], x[3], c.rest[static_cast<size_t>(s)])
                                               : bending_stencil(x[0], x[1], x[2], x[3], c.rest[static_cast<size_t>(s)]);
          const double lam = c.lambda[static_cast<size_t>(s)];
          EXPECT_EQ(terms[static_cast<size_t>(s)], e.C + c.compliance[static_cast<size_t>(s)] / 1e-4 * lam);
          for (int i = 0; i < c.arity; ++i) {
            const int q = c.offset[static_cast<size_t>(i)][static_cast<size_t>(s)] / kStride;
            if (q == 5) continue;
            const V3<double>& gr = e.grad[static_cast<size_t>(i)];
            EXPECT_EQ(g[static_cast<size_t>(3 * q)], lam == 0.0 ? 0.5 : 0.5 - lam * gr.x);
            EXPECT_EQ(g[static_cast<size_t>(3 * q + 2)], lam == 0.0 ? 0.5 : 0.5 - lam * gr.z);
          }
        }
        continue;
      }
      EXPECT_EQ(0, std::memcmp(terms.data(), first_terms.data(), terms.size() * sizeof(double))) << w;
      EXPECT_EQ(0, std::memcmp(g.data(), first_g.data(), g.size() * sizeof(double))) << w;
      ++compared;
    }
  }
  if (ws.size() > 1) {
    EXPECT_EQ(compared, static_cast<int>(ws.size() - 1) * (3 * 6 + 3));
  }
}

}  // namespace
}  // namespace pbdbench::test
