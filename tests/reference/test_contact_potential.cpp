// Tests of reference/contact_potential: the barrier's, gaps' and friction's derivatives against
// central differences, the barrier's C2 continuity at d_hat, and the continuous collision check
// against dense sampling of the straight paths.
#include "reference/contact_potential.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "core/generators.hpp"
#include "tests/mesh_fixtures.hpp"

namespace pbdbench {
namespace {

using barrier::Gap;

TEST(Barrier, DerivativesMatchCentralDifferences) {
  const double dh = 1e-3;
  for (double d : {1e-6, 1e-5, 1e-4, 3e-4, 5e-4, 9e-4, 9.99e-4}) {
    // A step small against d (the log's derivatives) and against d_hat - d (the barrier's
    // third derivative ~ 3 / d_hat there).
    const double e = 1e-3 * std::min(d, dh - d);
    const double fd1 = (barrier::value(d + e, dh) - barrier::value(d - e, dh)) / (2 * e);
    const double fd2 = (barrier::first(d + e, dh) - barrier::first(d - e, dh)) / (2 * e);
    EXPECT_NEAR(barrier::first(d, dh), fd1, 1e-6 * std::abs(fd1) + 1e-12) << d;
    EXPECT_NEAR(barrier::second(d, dh), fd2, 1e-6 * std::abs(fd2) + 1e-9) << d;
  }
  // Positive, decreasing, convex below d_hat; zero with zero slope and curvature at d_hat.
  EXPECT_GT(barrier::value(5e-4, dh), 0.0);
  EXPECT_LT(barrier::first(5e-4, dh), 0.0);
  EXPECT_GT(barrier::second(5e-4, dh), 0.0);
  EXPECT_NEAR(barrier::value(dh * (1 - 1e-9), dh), 0.0, 1e-20);
  EXPECT_NEAR(barrier::first(dh * (1 - 1e-9), dh), 0.0, 1e-15);
  EXPECT_NEAR(barrier::second(dh * (1 - 1e-6), dh), 0.0, 1e-5);  // b'' ~ 3 (d_hat - d) / d_hat
  EXPECT_EQ(barrier::value(dh, dh), 0.0);
  EXPECT_TRUE(std::isinf(barrier::value(0.0, dh)));
  EXPECT_TRUE(std::isinf(barrier::value(-1e-6, dh)));
}

TEST(Barrier, FrictionMollifierDerivativesAndContinuity) {
  const double e = 1e-5;
  for (double y : {1e-8, 1e-7, 3e-6, 9e-6, 2e-5}) {
    const double s = 1e-4 * e;
    EXPECT_NEAR(barrier::f1(y, e), (barrier::f0(y + s, e) - barrier::f0(y - s, e)) / (2 * s), 1e-8);
    EXPECT_NEAR(barrier::f1_prime(y, e),
                (barrier::f1(y + s, e) - barrier::f1(y - s, e)) / (2 * s), 1e-6 / e);
  }
  // C1 at e: f0 and f1 continuous.
  EXPECT_NEAR(barrier::f0(e * (1 - 1e-12), e), e, 1e-16);
  EXPECT_NEAR(barrier::f1(e * (1 - 1e-12), e), 1.0, 1e-10);
}

// Positions of a small model: particle 0 and 1 free, a plane, three spheres.
Model contact_model() {
  Model m;
  add_particle(m, Vec3(0.1, 0.3, -0.2), 1.0, 0.02);
  add_particle(m, Vec3(0.15, 0.35, -0.1), 2.0, 0.03);
  m.planes.push_back(PlaneCollider{Vec3(0.2, 2.0, 0.1), 0.3, 0.0, 0.5});  // non-unit on purpose
  m.spheres.push_back(SphereCollider{Vec3(0.5, 0.0, 0.0), 0.2, SphereSide::Outside});
  m.spheres.push_back(SphereCollider{Vec3(0.0, 0.5, 0.0), 0.9, SphereSide::Inside});
  m.spheres.push_back(SphereCollider{Vec3(0.0, 0.8, 0.0), 0.9, SphereSide::Bowl});
  m.particle_contact = true;
  return m;
}

TEST(Barrier, GapDerivativesMatchCentralDifferences) {
  Model m = contact_model();
  Points x = m.rest_positions;
  std::vector<Contact> cs = {{ContactKind::Plane, 0, 0},  {ContactKind::Sphere, 0, 0},
                             {ContactKind::Sphere, 0, 1}, {ContactKind::Sphere, 1, 2},
                             {ContactKind::Particle, 0, 1}};
  for (const Contact& c : cs) {
    const Gap g = barrier::gap(m, c, x, 0.0);
    // Agrees with core/contacts.
    const ConstraintEval ce = eval_contact(m, c, x, 0.0);
    EXPECT_NEAR(g.d, ce.C, 1e-15);
    const int parts = g.size / 3;
    const int ids[2] = {c.a, c.b};
    for (int k = 0; k < g.size; ++k) {
      const double s = 1e-6;
      Points xp = x, xm = x;
      xp(ids[k / 3], k % 3) += s;
      xm(ids[k / 3], k % 3) -= s;
      const Gap gp = barrier::gap(m, c, xp, 0.0), gm = barrier::gap(m, c, xm, 0.0);
      EXPECT_NEAR(g.grad[k], (gp.d - gm.d) / (2 * s), 1e-8) << to_string(c.kind) << " " << k;
      for (int j = 0; j < g.size; ++j)
        EXPECT_NEAR(g.hess(j, k), (gp.grad[j] - gm.grad[j]) / (2 * s), 1e-6)
            << to_string(c.kind) << " " << j << "," << k;
    }
    EXPECT_TRUE(parts == 1 || parts == 2);
  }
}

TEST(Barrier, FrictionDerivativesMatchCentralDifferences) {
  barrier::FrictionContact f;
  f.normal = Vec3(0.3, 0.9, 0.1).normalized();
  f.lambda = 9.81;
  f.mu = 0.4;
  const Mat3 P = Mat3::Identity() - f.normal * f.normal.transpose();
  const double e = 1e-4;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  for (double scale : {1e-7, 3e-5, 9e-5, 1e-3}) {  // below and above e
    const Vec3 u = P * Vec3(U(rng), U(rng), U(rng)).normalized() * scale;
    const Vec3 g = barrier::friction_gradient(f, u, e);
    const Mat3 H = barrier::friction_hessian(f, u, e);
    for (int k = 0; k < 3; ++k) {
      // Steps within the tangent plane, where u lives (D is a function of u there).
      const Vec3 t = P.col(k);
      const double s = 1e-4 * scale;
      const double fd = (barrier::friction_value(f, u + s * t, e) -
                         barrier::friction_value(f, u - s * t, e)) / (2 * s);
      EXPECT_NEAR(g.dot(t), fd, 1e-6 * f.mu * f.lambda) << scale;
      const Vec3 fdg = (barrier::friction_gradient(f, u + s * t, e) -
                        barrier::friction_gradient(f, u - s * t, e)) / (2 * s);
      EXPECT_LT((H * t - fdg).norm(), 1e-5 * f.mu * f.lambda / e + 1e-6 * fdg.norm()) << scale;
    }
    // Positive semi-definite.
    Eigen::SelfAdjointEigenSolver<Mat3> es(H);
    EXPECT_GE(es.eigenvalues().minCoeff(), -1e-9 * es.eigenvalues().maxCoeff());
  }
}

// The smallest gap along the straight paths x0 + s (x1 - x0), s in [0, alpha], by sampling.
double sampled_min_ratio(const Model& m, const Points& x0, const Points& x1, double alpha,
                         const std::vector<Contact>& cs) {
  double worst = 1e300;
  for (const Contact& c : cs) {
    const double d0 = barrier::gap(m, c, x0, 0.0).d;
    for (int k = 0; k <= 2000; ++k) {
      const double s = alpha * k / 2000.0;
      const Points xs = x0 + s * (x1 - x0);
      worst = std::min(worst, barrier::gap(m, c, xs, 0.0).d / d0);
    }
  }
  return worst;
}

TEST(Barrier, StepBoundKeepsTheGapAndIsTight) {
  Model m = contact_model();
  std::vector<Contact> all = {{ContactKind::Plane, 0, 0},  {ContactKind::Sphere, 0, 0},
                              {ContactKind::Sphere, 1, 0}, {ContactKind::Sphere, 0, 1},
                              {ContactKind::Sphere, 1, 1}, {ContactKind::Sphere, 0, 2},
                              {ContactKind::Sphere, 1, 2}, {ContactKind::Particle, 0, 1}};
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  int bounded = 0;
  for (int trial = 0; trial < 200; ++trial) {
    Points x0 = m.rest_positions;
    Points x1 = x0;
    for (int i = 0; i < 2; ++i)
      for (int k = 0; k < 3; ++k) x1(i, k) += 0.4 * U(rng);
    // Only contacts separated at the start count (as in a step from a feasible state).
    std::vector<Contact> cs;
    for (const Contact& c : all)
      if (barrier::gap(m, c, x0, 0.0).d > 0.0) cs.push_back(c);
    const std::vector<Contact> pairs = {{ContactKind::Particle, 0, 1}};
    const double alpha = barrier::step_bound(m, x0, x1, 0.0, 0.0, pairs, 0.9);
    ASSERT_GT(alpha, 0.0);
    ASSERT_LE(alpha, 1.0);
    // No gap below 10 % of its start along [0, alpha] ...
    EXPECT_GE(sampled_min_ratio(m, x0, x1, alpha, cs), 0.1 - 1e-9) << trial;
    // ... and, when the bound cuts the step, some gap reaches 10 % at alpha (tight).
    if (alpha < 1.0) {
      ++bounded;
      const Points xa = x0 + alpha * (x1 - x0);
      double r = 1e300;
      for (const Contact& c : cs) {
        r = std::min(r, barrier::gap(m, c, xa, 0.0).d / barrier::gap(m, c, x0, 0.0).d);
      }
      EXPECT_NEAR(r, 0.1, 1e-7) << trial;
    }
  }
  EXPECT_GT(bounded, 50);  // the trials exercise the bound
}

TEST(Barrier, MeshGapDerivativesMatchCentralDifferences) {
  // The unsigned distance to a coarse icosphere minus the radius, from points around it (faces,
  // edges and vertices nearest); where a difference step changes the nearest feature the
  // Hessian is not compared (it jumps there), the gradient always (the distance is C1 outside).
  Model m;
  add_particle(m, Vec3::Zero(), 1.0, 0.02);
  m.meshes.push_back(test::collider_of(test::icosphere_mesh(1, 0.5)));
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1, 1);
  int hessians = 0;
  for (int trial = 0; trial < 300; ++trial) {
    Points x(1, 3);
    x.row(0) = Vec3(U(rng), U(rng), U(rng)).normalized().transpose() * (0.55 + 0.3 * std::abs(U(rng)));
    const Contact c{ContactKind::Mesh, 0, 0};
    const Gap g = barrier::gap(m, c, x, 0.0);
    EXPECT_NEAR(g.d, eval_contact(m, c, x, 0.0).C, 1e-15);  // outside: signed = unsigned
    EXPECT_EQ(g.size, 3);
    bool same = true;
    const MeshDistance d0 = mesh_distance(m.meshes[0], x.row(0).transpose());
    for (int k = 0; k < 3; ++k) {
      const double s = 1e-6;
      Points xp = x, xm = x;
      xp(0, k) += s;
      xm(0, k) -= s;
      const Gap gp = barrier::gap(m, c, xp, 0.0), gm = barrier::gap(m, c, xm, 0.0);
      EXPECT_NEAR(g.grad[k], (gp.d - gm.d) / (2 * s), 1e-8) << trial;
      for (const Points* y : {&xp, &xm}) {
        const MeshDistance dy = mesh_distance(m.meshes[0], y->row(0).transpose());
        same = same && dy.triangle == d0.triangle && dy.features == d0.features;
      }
      if (!same) continue;
      for (int j = 0; j < 3; ++j)
        EXPECT_NEAR(g.hess(j, k), (gp.grad[j] - gm.grad[j]) / (2 * s), 1e-5) << trial;
    }
    hessians += same ? 1 : 0;
  }
  EXPECT_GT(hessians, 250);
}

TEST(Barrier, StepBoundKeepsTheMeshGapAndIsTight) {
  // Random straight paths of a particle near a coarse icosphere, static and moving (a linear
  // motion, taken linearly between t0 and t1): along [0, alpha] the gap, sampled densely, never
  // drops below 10 % of its start, and where the bound cuts the step the gap at alpha is 10 %
  // (to the search's 1e-12 of the step, times the path's length over the gap).
  for (bool moving : {false, true}) {
    Model m;
    add_particle(m, Vec3::Zero(), 1.0, 0.02);
    m.meshes.push_back(test::collider_of(test::icosphere_mesh(1, 0.3)));
    if (moving) {
      Motion mo;
      mo.kind = MotionKind::Linear;
      mo.velocity = Vec3(0.2, -0.1, 0.3);
      m.motions.push_back(mo);
      m.meshes[0].motion = 0;
    }
    const double t0 = 0.0, t1 = 0.5;
    auto gap_at = [&](const Points& x0, const Points& x1, double s) {
      Points xs = x0 + s * (x1 - x0);
      return barrier::gap(m, {ContactKind::Mesh, 0, 0}, xs, t0 + s * (t1 - t0)).d;
    };
    std::mt19937 rng(moving ? 5 : 4);
    std::uniform_real_distribution<double> U(-1, 1);
    int bounded = 0;
    for (int trial = 0; trial < 150; ++trial) {
      Points x0(1, 3), x1(1, 3);
      x0.row(0) = Vec3(U(rng), U(rng), U(rng)).normalized().transpose() * (0.34 + 0.1 * std::abs(U(rng)));
      x1.row(0) = x0.row(0) + 0.5 * Vec3(U(rng), U(rng), U(rng)).transpose();
      const double d0 = gap_at(x0, x1, 0.0);
      ASSERT_GT(d0, 0.0);
      const double alpha = barrier::step_bound(m, x0, x1, t0, t1, {}, 0.9);
      ASSERT_GT(alpha, 0.0);
      double worst = 1e300;
      for (int k = 0; k <= 2000; ++k) worst = std::min(worst, gap_at(x0, x1, alpha * k / 2000.0) / d0);
      EXPECT_GE(worst, 0.1 - 1e-9) << trial;
      if (alpha < 1.0) {
        ++bounded;
        const double len = (x1 - x0).norm() + (moving ? 0.5 * Vec3(0.2, -0.1, 0.3).norm() : 0.0);
        EXPECT_NEAR(gap_at(x0, x1, alpha) / d0, 0.1, 1e-9 * (1.0 + len / d0)) << trial;
      }
    }
    EXPECT_GT(bounded, 20) << moving;  // the trials exercise the bound
  }
}


// ---- Surfaces: point-triangle and edge-edge pairs (SurfaceBarrier) ------------------------------

namespace surface_tests {

// Two bodies of two triangles each (a unit square split along a diagonal), body 1 above body 0
// at height h, turned by `angle` about the vertical and shifted by (sx, sz).
Model two_squares(double h, double angle, double sx, double sz, double radius) {
  Model m;
  const double c = std::cos(angle), s = std::sin(angle);
  for (int body = 0; body < 2; ++body)
    for (int k = 0; k < 4; ++k) {
      const double u = (k == 1 || k == 2) ? 0.5 : -0.5, w = k >= 2 ? 0.5 : -0.5;
      Vec3 p = body == 0 ? Vec3(u, 0.0, w) : Vec3(c * u - s * w + sx, h, s * u + c * w + sz);
      add_particle(m, p, 1.0, radius);
    }
  m.triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}};
  m.particle_body = {0, 0, 0, 0, 1, 1, 1, 1};
  m.surface_contact = true;
  return m;
}

// Every allowed pair by brute force with its gap, for comparison with near().
std::vector<std::pair<int, double>> brute_force_gaps(const Model& m, const Points& x) {
  std::vector<std::pair<int, double>> out;  // (kind, gap)
  for (int p = 0; p < m.particle_count(); ++p)
    for (int t = 0; t < 4; ++t) {
      const auto& tri = m.triangles[static_cast<size_t>(t)];
      if (m.particle_body[static_cast<size_t>(p)] == m.particle_body[static_cast<size_t>(tri[0])]) continue;
      double r = 0.0;
      for (int v : tri) r = std::max(r, m.radius[static_cast<size_t>(v)]);
      out.push_back({0, proximity::point_triangle_distance(x.row(p).transpose(), x.row(tri[0]).transpose(),
                                                           x.row(tri[1]).transpose(), x.row(tri[2]).transpose()) -
                            (m.radius[static_cast<size_t>(p)] + r)});
    }
  const int edges[5][2] = {{0, 1}, {1, 2}, {0, 2}, {2, 3}, {0, 3}};
  for (const auto& e : edges)
    for (const auto& f : edges)
      out.push_back({1, proximity::edge_edge_distance(x.row(e[0]).transpose(), x.row(e[1]).transpose(),
                                                      x.row(f[0] + 4).transpose(), x.row(f[1] + 4).transpose()) -
                            2.0 * m.radius[0]});
  return out;
}

TEST(SurfaceBarrier, NearFindsExactlyThePairsBelowTheMargin) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int trial = 0; trial < 40; ++trial) {
    const Model m = two_squares(0.05 + 0.2 * (U(rng) + 1), U(rng), 0.6 * U(rng), 0.6 * U(rng), 0.01);
    const barrier::SurfaceBarrier sb(m);
    ASSERT_TRUE(sb.enabled());
    Points x = m.rest_positions;
    for (Eigen::Index i = 0; i < x.rows(); ++i) x.row(i) += 0.03 * Vec3(U(rng), U(rng), U(rng)).transpose();
    for (double margin : {0.02, 0.1, 0.3}) {
      int expected[2] = {0, 0};
      for (const auto& [kind, g] : brute_force_gaps(m, x))
        if (g < margin) ++expected[kind];
      int found[2] = {0, 0};
      for (const barrier::SurfacePair& p : sb.near(x, margin)) {
        ++found[p.kind == proximity::PairKind::EdgeEdge];
        EXPECT_LT(barrier::SurfaceBarrier::gap(p, x), margin);
      }
      EXPECT_EQ(found[0], expected[0]) << trial;
      EXPECT_EQ(found[1], expected[1]) << trial;
    }
  }
}

TEST(SurfaceBarrier, TermDerivativesMatchCentralDifferences) {
  const double d_hat = 0.05;
  int checked[2] = {0, 0}, mollified = 0;
  // Crossed squares (edges at an angle) and nearly parallel ones (the mollifier active).
  const double setups[2][3] = {{0.7, 0.13, 0.21}, {0.004, 0.02, 0.01}};
  for (const auto& setup : setups) {
    const Model m = two_squares(0.04, setup[0], setup[1], setup[2], 0.005);
    const barrier::SurfaceBarrier sb(m);
    Points x = m.rest_positions;
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> U(-1, 1);
    for (Eigen::Index i = 0; i < x.rows(); ++i) x.row(i) += 0.002 * Vec3(U(rng), U(rng), U(rng)).transpose();
    for (const barrier::SurfacePair& p : sb.near(x, d_hat)) {
      const barrier::SurfaceTerm t = barrier::SurfaceBarrier::term(p, x, d_hat);
      ASSERT_GT(t.gap, 0.0);
      EXPECT_NEAR(t.value, barrier::SurfaceBarrier::energy(p, x, d_hat), 1e-11 * std::abs(t.value));
      const double h = 1e-7;
      proximity::Vec12 g_fd;
      proximity::Mat12 H_fd;
      for (int k = 0; k < 12; ++k) {
        Points xp = x, xm = x;
        xp(p.v[static_cast<size_t>(k / 3)], k % 3) += h;
        xm(p.v[static_cast<size_t>(k / 3)], k % 3) -= h;
        g_fd[k] = (barrier::SurfaceBarrier::energy(p, xp, d_hat) - barrier::SurfaceBarrier::energy(p, xm, d_hat)) / (2 * h);
        H_fd.col(k) = (barrier::SurfaceBarrier::term(p, xp, d_hat).grad - barrier::SurfaceBarrier::term(p, xm, d_hat).grad) / (2 * h);
      }
      const double gs = t.grad.cwiseAbs().maxCoeff(), Hs = t.hess.cwiseAbs().maxCoeff();
      EXPECT_LT((t.grad - g_fd).cwiseAbs().maxCoeff(), 1e-6 * gs + 1e-12);
      EXPECT_LT((t.hess - H_fd).cwiseAbs().maxCoeff(), 1e-5 * Hs + 1e-9);
      ++checked[p.kind == proximity::PairKind::EdgeEdge];
      if (p.kind == proximity::PairKind::EdgeEdge &&
          proximity::edge_edge_mollifier(x.row(p.v[0]).transpose(), x.row(p.v[1]).transpose(),
                                         x.row(p.v[2]).transpose(), x.row(p.v[3]).transpose(), p.eps_x)
                  .value < 1.0)
        ++mollified;
    }
  }
  EXPECT_GT(checked[0], 4);
  EXPECT_GT(checked[1], 4);
  EXPECT_GT(mollified, 0);
}

TEST(SurfaceBarrier, StepBoundKeepsEveryGapOnRandomPaths) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> U(-1, 1);
  const double d_hat = 0.1, keep = 0.05;
  int cut = 0;
  for (int trial = 0; trial < 30; ++trial) {
    const Model m = two_squares(0.05, U(rng), 0.3 * U(rng), 0.3 * U(rng), 0.005);
    const barrier::SurfaceBarrier sb(m);
    const Points x0 = m.rest_positions;
    Points x1 = x0;
    for (Eigen::Index i = 0; i < x1.rows(); ++i) x1.row(i) += 0.1 * Vec3(U(rng), U(rng), U(rng)).transpose();
    const double alpha = sb.step_bound(x0, x1, d_hat, keep, 1.0);
    if (alpha < 1.0) ++cut;
    const auto g0 = brute_force_gaps(m, x0);
    for (int i = 0; i <= 2000; ++i) {
      const Points x = x0 + (alpha * i / 2000.0) * (x1 - x0);
      const auto g = brute_force_gaps(m, x);
      for (size_t k = 0; k < g.size(); ++k)
        if (g0[k].second < d_hat) {
          ASSERT_GE(g[k].second, keep * g0[k].second * (1 - 1e-9)) << trial;
        } else {
          ASSERT_GT(g[k].second, 0.0) << trial;
        }
    }
  }
  EXPECT_GT(cut, 5);  // the random paths do cross
}

}  // namespace surface_tests

}  // namespace
}  // namespace pbdbench
