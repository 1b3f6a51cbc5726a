// Tests of core/proximity: each distance type's classification, value (against the exact
// minimum distance), gradient and Hessian (against central finite differences); the mollifier's
// derivatives; the conservative CCD on crossing, near-miss and random paths (never a step past
// the gap it promises, checked by dense sampling of the exact gap along the path).
#include "core/proximity.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <random>

namespace pbdbench::proximity {
namespace {

using X = std::array<Vec3, 4>;

// Central differences of f's value (gradient) and of its gradient (Hessian), step h.
void check_derivatives(const std::function<Distance(const X&)>& f, const X& x, const char* what) {
  const Distance d = f(x);
  const double h = 1e-6;
  Vec12 g_fd;
  Mat12 H_fd;
  for (int k = 0; k < 12; ++k) {
    X xp = x, xm = x;
    xp[static_cast<size_t>(k / 3)][k % 3] += h;
    xm[static_cast<size_t>(k / 3)][k % 3] -= h;
    const Distance dp = f(xp), dm = f(xm);
    g_fd[k] = (dp.d - dm.d) / (2 * h);
    H_fd.col(k) = (dp.grad - dm.grad) / (2 * h);
  }
  const double gs = std::max(1.0, d.grad.cwiseAbs().maxCoeff());
  const double Hs = std::max(1.0, d.hess.cwiseAbs().maxCoeff());
  EXPECT_LT((d.grad - g_fd).cwiseAbs().maxCoeff(), 1e-7 * gs) << what;
  EXPECT_LT((d.hess - H_fd).cwiseAbs().maxCoeff(), 1e-5 * Hs) << what;
  EXPECT_LT((d.hess - d.hess.transpose()).cwiseAbs().maxCoeff(), 1e-12 * Hs) << what;
}

X jitter(X x, std::mt19937& rng, double size) {
  std::uniform_real_distribution<double> U(-size, size);
  for (Vec3& v : x) v += Vec3(U(rng), U(rng), U(rng));
  return x;
}

TEST(Proximity, PointTriangleEachTypeMatchesTheDistanceAndFiniteDifferences) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  const struct {
    Vec3 p;
    PointTriangleType type;
  } cases[] = {
      {{0.2, 0.3, 0.5}, PointTriangleType::P_T},    {{-0.3, -0.4, 0.2}, PointTriangleType::P_T0},
      {{1.4, -0.2, 0.3}, PointTriangleType::P_T1},  {{-0.2, 1.5, 0.1}, PointTriangleType::P_T2},
      {{0.5, -0.4, 0.3}, PointTriangleType::P_E01}, {{0.8, 0.8, 0.2}, PointTriangleType::P_E12},
      {{-0.4, 0.5, 0.3}, PointTriangleType::P_E20},
  };
  std::mt19937 rng(5);
  for (const auto& cs : cases)
    for (int trial = 0; trial < 5; ++trial) {
      const X x = jitter({cs.p, a, b, c}, rng, 0.05);
      ASSERT_EQ(point_triangle_type(x[0], x[1], x[2], x[3]), cs.type) << static_cast<int>(cs.type);
      const Distance d = point_triangle(x[0], x[1], x[2], x[3]);
      EXPECT_EQ(d.type, static_cast<int>(cs.type));
      EXPECT_NEAR(d.d, point_triangle_distance(x[0], x[1], x[2], x[3]), 1e-13);
      check_derivatives(
          [&](const X& y) { return point_triangle(y[0], y[1], y[2], y[3], cs.type); }, x,
          "point-triangle");
    }
}

TEST(Proximity, EdgeEdgeEachTypeMatchesTheDistanceAndFiniteDifferences) {
  const Vec3 a0(0, 0, 0), a1(1, 0, 0);
  const struct {
    Vec3 b0, b1;
    EdgeEdgeType type;
  } cases[] = {
      {{0.5, 0.5, -0.5}, {0.5, 0.5, 0.5}, EdgeEdgeType::EA_EB},
      {{-0.3, 0.5, -0.5}, {-0.3, 0.5, 0.5}, EdgeEdgeType::EA0_EB},
      {{1.3, 0.5, -0.5}, {1.3, 0.5, 0.5}, EdgeEdgeType::EA1_EB},
      {{0.5, 0.5, 0.3}, {0.5, 0.5, 1.3}, EdgeEdgeType::EA_EB0},
      {{0.5, 0.5, -1.3}, {0.5, 0.5, -0.3}, EdgeEdgeType::EA_EB1},
      {{-0.3, 0.5, 0.3}, {-0.3, 0.5, 1.3}, EdgeEdgeType::EA0_EB0},
      {{-0.3, 0.5, -1.3}, {-0.3, 0.5, -0.3}, EdgeEdgeType::EA0_EB1},
      {{1.3, 0.5, 0.3}, {1.3, 0.5, 1.3}, EdgeEdgeType::EA1_EB0},
      {{1.3, 0.5, -1.3}, {1.3, 0.5, -0.3}, EdgeEdgeType::EA1_EB1},
  };
  std::mt19937 rng(7);
  for (const auto& cs : cases)
    for (int trial = 0; trial < 5; ++trial) {
      const X x = jitter({a0, a1, cs.b0, cs.b1}, rng, 0.05);
      ASSERT_EQ(edge_edge_type(x[0], x[1], x[2], x[3]), cs.type) << static_cast<int>(cs.type);
      const Distance d = edge_edge(x[0], x[1], x[2], x[3]);
      EXPECT_EQ(d.type, static_cast<int>(cs.type));
      EXPECT_NEAR(d.d, edge_edge_distance(x[0], x[1], x[2], x[3]), 1e-13);
      check_derivatives([&](const X& y) { return edge_edge(y[0], y[1], y[2], y[3], cs.type); },
                        x, "edge-edge");
    }
}

TEST(Proximity, ExactDistancesAreMinimaOverSampledPoints) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int trial = 0; trial < 100; ++trial) {
    X x;
    for (Vec3& v : x) v = Vec3(U(rng), U(rng), U(rng));
    const double dee = edge_edge_distance(x[0], x[1], x[2], x[3]);
    double best = 1e300;
    for (int i = 0; i <= 200; ++i)
      for (int j = 0; j <= 200; ++j) {
        const Vec3 pa = x[0] + (i / 200.0) * (x[1] - x[0]), pb = x[2] + (j / 200.0) * (x[3] - x[2]);
        best = std::min(best, (pa - pb).norm());
      }
    EXPECT_LE(dee, best + 1e-12);
    EXPECT_GE(dee, best - 0.02);  // the sampling's resolution
  }
}

TEST(Proximity, ParallelEdgesGetAPointTypeWithTheExactDistance) {
  const Vec3 a0(0, 0, 0), a1(1, 0, 0), b0(0.3, 0.2, 0), b1(1.6, 0.2, 0);
  const EdgeEdgeType t = edge_edge_type(a0, a1, b0, b1);
  EXPECT_NE(t, EdgeEdgeType::EA_EB);
  EXPECT_NEAR(edge_edge(a0, a1, b0, b1).d, 0.2, 1e-14);
  EXPECT_NEAR(edge_edge_distance(a0, a1, b0, b1), 0.2, 1e-14);
}

TEST(Proximity, MollifierIsOneAwayFromParallelAndItsDerivativesMatch) {
  const Vec3 a0(0, 0, 0), a1(1, 0, 0);
  // Crossing edges at right angles: c = 1 >> eps_x = 1e-3: the mollifier is 1.
  EXPECT_EQ(edge_edge_mollifier(a0, a1, {0.5, 0.5, -0.5}, {0.5, 0.5, 0.5}, 1e-3).value, 1.0);
  // Nearly parallel (c < eps_x): value in (0, 1), derivatives against finite differences.
  const X x = {a0, a1, Vec3(0.2, 0.3, -0.01), Vec3(1.2, 0.3, 0.015)};
  const double eps = mollifier_threshold(a0, a1, x[2], x[3]);
  const Mollifier m = edge_edge_mollifier(x[0], x[1], x[2], x[3], eps);
  EXPECT_GT(m.value, 0.0);
  EXPECT_LT(m.value, 1.0);
  check_derivatives(
      [&](const X& y) {
        const Mollifier my = edge_edge_mollifier(y[0], y[1], y[2], y[3], eps);
        Distance d;
        d.d = my.value;
        d.grad = my.grad;
        d.hess = my.hess;
        return d;
      },
      x, "mollifier");
}

// The smallest gap over dense samples of [0, alpha], and whether it stays >= keep g0.
double min_gap_along(PairKind kind, const X& x0, const X& dx, double thickness, double alpha) {
  double g = 1e300;
  const int N = 4000;
  for (int i = 0; i <= N; ++i) {
    const double s = alpha * i / N;
    X x;
    for (size_t k = 0; k < 4; ++k) x[k] = x0[k] + s * dx[k];
    const double d = kind == PairKind::PointTriangle ? point_triangle_distance(x[0], x[1], x[2], x[3])
                                                     : edge_edge_distance(x[0], x[1], x[2], x[3]);
    g = std::min(g, d - thickness);
  }
  return g;
}

TEST(ProximityCcd, APointCrossingATriangleIsStoppedBeforeIt) {
  // The point falls through the middle of the triangle (crossing at s = 0.5 of the step).
  const X x0 = {Vec3(0.25, 0.25, 0.5), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  const X dx = {Vec3(0, 0, -1), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  for (double thickness : {0.0, 0.1}) {
    const double g0 = 0.5 - thickness, keep = 0.05;
    const CcdResult r = conservative_ccd(PairKind::PointTriangle, x0, dx, thickness, keep, 1.0);
    EXPECT_LT(r.alpha, (0.5 - thickness) / 1.0);
    EXPECT_GE(min_gap_along(PairKind::PointTriangle, x0, dx, thickness, r.alpha), keep * g0 * (1 - 1e-12));
    EXPECT_GT(r.alpha, 0.8 * (1 - 2 * keep) * g0);  // not needlessly short: it stops near 2 keep g0
  }
}

TEST(ProximityCcd, CrossingEdgesAreStoppedBeforeTheyMeet) {
  // Edge b sweeps down through edge a (they cross at s = 0.4), the triangle moving too.
  const X x0 = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 0.4, -0.5), Vec3(0.5, 0.4, 0.5)};
  const X dx = {Vec3(0, 0.5, 0), Vec3(0, 0.5, 0), Vec3(0, -0.5, 0.1), Vec3(0, -0.5, 0.1)};
  const CcdResult r = conservative_ccd(PairKind::EdgeEdge, x0, dx, 0.0, 0.05, 1.0);
  EXPECT_LT(r.alpha, 0.4);
  EXPECT_GE(min_gap_along(PairKind::EdgeEdge, x0, dx, 0.0, r.alpha), 0.05 * 0.4 * (1 - 1e-12));
}

TEST(ProximityCcd, NearMissesTakeTheWholeStep) {
  // The point passes beside the triangle's edge at 0.2 (thickness 0.05): never within 2 keep g0.
  const X x0 = {Vec3(-0.2, 0.5, 0.5), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  const X dx = {Vec3(0, 0, -1), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  EXPECT_EQ(conservative_ccd(PairKind::PointTriangle, x0, dx, 0.05, 0.05, 1.0).alpha, 1.0);
  // Edge b slides past the end of edge a at 0.1.
  const X e0 = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1.1, 0.5, -0.5), Vec3(1.1, 0.5, 0.5)};
  const X de = {Vec3::Zero(), Vec3::Zero(), Vec3(0, -1, 0), Vec3(0, -1, 0)};
  EXPECT_EQ(conservative_ccd(PairKind::EdgeEdge, e0, de, 0.0, 0.05, 1.0).alpha, 1.0);
  // A common translation never closes a gap.
  const X t = {Vec3(1, 2, 3), Vec3(1, 2, 3), Vec3(1, 2, 3), Vec3(1, 2, 3)};
  EXPECT_EQ(conservative_ccd(PairKind::EdgeEdge, x0, t, 0.0, 0.05, 1.0).alpha, 1.0);
}

TEST(ProximityCcd, RandomPathsNeverPassTheGapTheyPromise) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> U(-1, 1);
  int stopped = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const PairKind kind = trial % 2 ? PairKind::EdgeEdge : PairKind::PointTriangle;
    X x0, dx;
    for (Vec3& v : x0) v = Vec3(U(rng), U(rng), U(rng));
    for (Vec3& v : dx) v = 2.0 * Vec3(U(rng), U(rng), U(rng));
    const double d0 = kind == PairKind::PointTriangle ? point_triangle_distance(x0[0], x0[1], x0[2], x0[3])
                                                      : edge_edge_distance(x0[0], x0[1], x0[2], x0[3]);
    const double thickness = 0.3 * d0;
    const double g0 = d0 - thickness, keep = 0.05;
    const CcdResult r = conservative_ccd(kind, x0, dx, thickness, keep, 1.0);
    EXPECT_GE(min_gap_along(kind, x0, dx, thickness, r.alpha), keep * g0 * (1 - 1e-9)) << trial;
    if (r.alpha < 1.0) {
      ++stopped;
      // It stopped because the gap fell to 2 keep g0: the samples up to there never went below
      // keep g0, and the gap at alpha is within a factor 2 of it.
      X x;
      for (size_t k = 0; k < 4; ++k) x[k] = x0[k] + r.alpha * dx[k];
      const double d = kind == PairKind::PointTriangle ? point_triangle_distance(x[0], x[1], x[2], x[3])
                                                       : edge_edge_distance(x[0], x[1], x[2], x[3]);
      EXPECT_LE(d - thickness, 2.0 * keep * g0 * (1 + 1e-12)) << trial;
    }
  }
  EXPECT_GT(stopped, 40);  // the random paths do include closing ones
}

}  // namespace
}  // namespace pbdbench::proximity
