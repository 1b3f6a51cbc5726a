// Tests of core/bvh: the closest point on a triangle against dense sampling and its optimality
// conditions; the tree's closest-point and box queries against brute force over random triangle
// soups; that it prunes; its refusals; a refit tree against one built anew on moved vertices.
#include "core/bvh.hpp"

#include <gtest/gtest.h>

#include <random>
#include <set>
#include <stdexcept>

namespace pbdbench {
namespace {

TEST(ClosestPointOnTriangle, NoSampledPointIsCloserAndTheResultLiesOnTheTriangle) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int trial = 0; trial < 300; ++trial) {
    const Vec3 a(U(rng), U(rng), U(rng)), b(U(rng), U(rng), U(rng)), c(U(rng), U(rng), U(rng));
    const Vec3 p = 2.0 * Vec3(U(rng), U(rng), U(rng));
    Vec3 bary;
    const Vec3 q = closest_point_on_triangle(p, a, b, c, &bary);
    EXPECT_GE(bary.minCoeff(), -1e-12);
    EXPECT_NEAR(bary.sum(), 1.0, 1e-12);
    EXPECT_LT((bary[0] * a + bary[1] * b + bary[2] * c - q).norm(), 1e-12);
    const double dq = (p - q).norm();
    double ds = 1e300;
    const int N = 120;
    for (int i = 0; i <= N; ++i)
      for (int j = 0; i + j <= N; ++j) {
        const double u = double(i) / N, v = double(j) / N;
        ds = std::min(ds, (p - ((1 - u - v) * a + u * b + v * c)).norm());
      }
    EXPECT_LE(dq, ds + 1e-12) << trial;
    EXPECT_GE(dq, ds - 0.05) << trial;  // the grid's spacing bounds how much closer q can be
    // Optimality: p - q is orthogonal to every edge direction along which q can still move.
    const Vec3 r = p - q;
    if (bary.minCoeff() > 1e-9) {  // interior: orthogonal to the face
      EXPECT_NEAR(r.dot(b - a), 0.0, 1e-10);
      EXPECT_NEAR(r.dot(c - a), 0.0, 1e-10);
    }
  }
}

TEST(ClosestPointOnTriangle, DegenerateTriangles) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(2, 0, 0);  // collinear
  const Vec3 q = closest_point_on_triangle(Vec3(1.5, 1, 0), a, b, c);
  EXPECT_LT((q - Vec3(1.5, 0, 0)).norm(), 1e-12);
  const Vec3 q2 = closest_point_on_triangle(Vec3(3, 4, 0), a, a, a);  // a point
  EXPECT_LT((q2 - a).norm(), 1e-12);
}

struct Soup {
  Points v;
  std::vector<std::array<int, 3>> t;
};

Soup random_soup(int triangles, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1, 1), S(-0.05, 0.05);
  Soup s;
  s.v.resize(3 * triangles, 3);
  for (int k = 0; k < triangles; ++k) {
    const Vec3 c(U(rng), U(rng), U(rng));
    for (int i = 0; i < 3; ++i) {
      s.v.row(3 * k + i) = (c + Vec3(S(rng), S(rng), S(rng))).transpose();
    }
    s.t.push_back({3 * k, 3 * k + 1, 3 * k + 2});
  }
  return s;
}

TEST(TriangleBvh, ClosestMatchesBruteForceAndPrunes) {
  const Soup s = random_soup(2000, 5);
  const TriangleBvh bvh(s.v, s.t);
  EXPECT_EQ(bvh.triangle_count(), 2000);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> U(-1.5, 1.5);
  long visits = 0;
  for (int q = 0; q < 200; ++q) {
    const Vec3 p(U(rng), U(rng), U(rng));
    double best = 1e300;
    int best_t = -1;
    for (int t = 0; t < 2000; ++t) {
      const auto& tri = s.t[static_cast<size_t>(t)];
      const double d = (p - closest_point_on_triangle(p, s.v.row(tri[0]).transpose(),
                                                      s.v.row(tri[1]).transpose(),
                                                      s.v.row(tri[2]).transpose())).norm();
      if (d < best) {
        best = d;
        best_t = t;
      }
    }
    const TriangleBvh::Hit h = bvh.closest(p);
    visits += TriangleBvh::last_visits();
    EXPECT_EQ(h.triangle, best_t) << q;
    EXPECT_NEAR(h.distance, best, 1e-14) << q;
    // Within a radius below the distance: nothing.
    EXPECT_EQ(bvh.closest(p, 0.99 * best).triangle, -1);
  }
  // 2000 triangles make about 1000 nodes; a query should look at a small part of them.
  EXPECT_LT(visits / 200, 200);
}

TEST(TriangleBvh, OverlappingMatchesBruteForce) {
  const Soup s = random_soup(500, 3);
  const TriangleBvh bvh(s.v, s.t);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> U(-1, 1), W(0.01, 0.4);
  for (int q = 0; q < 100; ++q) {
    TriangleBvh::Box box;
    const Vec3 c(U(rng), U(rng), U(rng));
    const Vec3 w(W(rng), W(rng), W(rng));
    box.lo = c - w;
    box.hi = c + w;
    std::set<int> got, want;
    bvh.overlapping(box, [&](int t) { EXPECT_TRUE(got.insert(t).second); });
    for (int t = 0; t < 500; ++t) {
      TriangleBvh::Box tb;
      for (int k = 0; k < 3; ++k) tb.grow(Vec3(s.v.row(s.t[static_cast<size_t>(t)][k]).transpose()));
      if (tb.overlaps(box)) want.insert(t);
    }
    EXPECT_EQ(got, want) << q;
  }
}

TEST(TriangleBvh, RefitFindsWhatARebuildFinds) {
  // A soup moved three times (each vertex by up to 0.3 m, then the whole soup stretched 1.5
  // times along x): the refit tree and a tree built anew at the moved vertices give the same
  // triangles for every box query and the same closest triangle for every point; refitting to
  // the original vertices gives back the original tree's boxes (box_area).
  Soup s = random_soup(800, 11);
  TriangleBvh refit(s.v, s.t);
  const double area0 = refit.box_area();
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> U(-1, 1), W(0.01, 0.3);
  Points v = s.v;
  for (int round = 0; round < 3; ++round) {
    for (Eigen::Index i = 0; i < v.rows(); ++i) v.row(i) += 0.3 * Vec3(U(rng), U(rng), U(rng)).transpose();
    if (round == 2) v.col(0) *= 1.5;
    refit.refit(v);
    const TriangleBvh fresh(v, s.t);
    EXPECT_GT(refit.box_area(), fresh.box_area()) << round;  // a refit tree is looser
    long differ = 0;
    for (int q = 0; q < 200; ++q) {
      TriangleBvh::Box box;
      const Vec3 c(U(rng), U(rng), U(rng)), w(W(rng), W(rng), W(rng));
      box.lo = c - w;
      box.hi = c + w;
      std::set<int> a, b;
      refit.overlapping(box, [&](int t) { a.insert(t); });
      fresh.overlapping(box, [&](int t) { b.insert(t); });
      EXPECT_EQ(a, b) << round << ", " << q;
      differ += static_cast<long>(a.size());
      const TriangleBvh::Hit ha = refit.closest(c), hb = fresh.closest(c);
      EXPECT_EQ(ha.triangle, hb.triangle);
      EXPECT_EQ(ha.distance, hb.distance);
    }
    EXPECT_GT(differ, 0);  // the queries do find triangles
  }
  refit.refit(s.v);
  EXPECT_EQ(refit.box_area(), area0);
  Points bad = s.v;
  bad(0, 0) = std::nan("");
  EXPECT_THROW(refit.refit(bad), std::invalid_argument);
  EXPECT_THROW(refit.refit(s.v.topRows(3)), std::invalid_argument);
  EXPECT_EQ(refit.box_area(), area0);  // unchanged by a refused refit
}

TEST(TriangleBvh, EmptyAndRefused) {
  const TriangleBvh empty(Points(0, 3), {});
  EXPECT_EQ(empty.closest(Vec3::Zero()).triangle, -1);
  Points v(3, 3);
  v << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  EXPECT_THROW(TriangleBvh(v, {{0, 1, 3}}), std::invalid_argument);
  v(1, 0) = std::nan("");
  EXPECT_THROW(TriangleBvh(v, {{0, 1, 2}}), std::invalid_argument);
}

}  // namespace
}  // namespace pbdbench
