// Tests of core/mesh_collider: the signed distance of a point to a triangle mesh (closed forms
// for one triangle's regions, the sign inside and outside closed meshes), its gradient and the
// unsigned distance's Hessian against central differences, and what make_mesh_collider refuses.
#include <gtest/gtest.h>

#include <cmath>

#include "core/mesh_collider.hpp"
#include "tests/mesh_fixtures.hpp"
#include "tests/core/test_support.hpp"

namespace pbdbench {
namespace {

using test::near;

TEST(MeshDistance, OneTriangleRegionsMatchClosedForms) {
  // The triangle (0,0,0), (1,0,0), (0,1,0) in the plane z = 0, normal +z.
  test::TriMesh t;
  t.vertices = test::to_points({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)});
  t.triangles = {{0, 1, 2}};
  const MeshCollider m = test::collider_of(t);
  EXPECT_FALSE(m.closed);
  // Face region: the height above (or below) the plane, signed by the normal.
  MeshDistance d = mesh_distance(m, Vec3(0.2, 0.3, 0.5));
  EXPECT_EQ(d.features, 3);
  EXPECT_NEAR(d.distance, 0.5, 1e-15);
  EXPECT_TRUE(near(d.normal, Vec3(0, 0, 1), test::kRoundoff));
  d = mesh_distance(m, Vec3(0.2, 0.3, -0.25));
  EXPECT_NEAR(d.distance, -0.25, 1e-15);
  EXPECT_TRUE(near(d.normal, Vec3(0, 0, 1), test::kRoundoff));  // the gradient still points out
  // Edge region (the hypotenuse x + y = 1): the distance to the line.
  d = mesh_distance(m, Vec3(1.0, 1.0, 0.3));
  EXPECT_EQ(d.features, 2);
  EXPECT_NEAR(d.unsigned_distance, std::sqrt(0.5 + 0.09), 1e-15);
  EXPECT_GT(d.distance, 0.0);
  // Vertex region.
  d = mesh_distance(m, Vec3(-1.0, -2.0, 2.0));
  EXPECT_EQ(d.features, 1);
  EXPECT_NEAR(d.unsigned_distance, 3.0, 1e-15);
  EXPECT_TRUE(near(d.point, Vec3::Zero(), test::kRoundoff));
  // Beyond max_distance: no triangle.
  EXPECT_EQ(mesh_distance(m, Vec3(0.2, 0.2, 5.0), 1.0).triangle, -1);
}

TEST(MeshDistance, SignIsInsideOutsideForClosedMeshes) {
  const MeshCollider cube = test::collider_of(test::cube_mesh(0.5));
  EXPECT_TRUE(cube.closed);
  EXPECT_NEAR(mesh_distance(cube, Vec3(0.1, 0.2, -0.1)).distance, -0.3, 1e-15);
  EXPECT_NEAR(mesh_distance(cube, Vec3(0.9, 0.0, 0.0)).distance, 0.4, 1e-15);
  // Outside near a convex edge and a corner: positive, the distance to the edge and the corner.
  EXPECT_NEAR(mesh_distance(cube, Vec3(0.8, 0.9, 0.0)).distance, std::hypot(0.3, 0.4), 1e-15);
  EXPECT_NEAR(mesh_distance(cube, Vec3(0.6, 0.6, 0.6)).distance, 0.1 * std::sqrt(3.0), 1e-15);

  // The icosphere against the sphere it approximates: the same sign everywhere, the distance
  // within the mesh's sagitta R (1 - cos(theta)) of the sphere's (theta: the largest angle from a
  // face's centre to its vertices, below 0.2 rad at 3 levels).
  const double R = 0.7;
  const MeshCollider ico = test::collider_of(test::icosphere_mesh(3, R));
  EXPECT_TRUE(ico.closed);
  EXPECT_EQ(ico.triangles.size(), 1280u);
  test::Random rng(17);
  const double sagitta = R * (1.0 - std::cos(0.2));
  for (int k = 0; k < 500; ++k) {
    const Vec3 p = rng.vec(-1.2, 1.2);
    const double analytic = p.norm() - R;
    const double d = mesh_distance(ico, p).distance;
    EXPECT_NEAR(d, analytic, sagitta) << test::str(p);
    if (std::abs(analytic) > sagitta) {
      EXPECT_EQ(d > 0.0, analytic > 0.0) << test::str(p);
    }
  }
}

TEST(MeshDistance, GradientAndHessianMatchCentralDifferences) {
  // Points around a coarse icosphere (faces, edges and vertices all nearest somewhere) and a
  // cube, inside and outside; the signed distance's gradient and the unsigned distance's
  // Hessian (the gradient of `direction`) against central differences. Points within 10 h of
  // a region boundary of the closest feature could straddle it; the distance is C1 across
  // those outside a convex mesh, and the Hessian is checked only where the feature stays.
  for (int which = 0; which < 2; ++which) {
    const MeshCollider m = which == 0 ? test::collider_of(test::icosphere_mesh(1, 0.5))
                                      : test::collider_of(test::cube_mesh(0.4));
    test::Random rng(which + 3);
    int checked = 0, hessians = 0;
    for (int k = 0; k < 400; ++k) {
      const Vec3 p = rng.vec(-0.9, 0.9);
      const MeshDistance d = mesh_distance(m, p);
      if (std::abs(d.distance) < 1e-3) continue;  // on the surface the gradient jumps (inside)
      const double h = test::kFdStep;
      Vec3 fd;
      Mat3 fdh;
      bool same_feature = true;
      for (int a = 0; a < 3; ++a) {
        Vec3 e = Vec3::Zero();
        e[a] = h;
        const MeshDistance dp = mesh_distance(m, p + e), dm = mesh_distance(m, p - e);
        fd[a] = (dp.distance - dm.distance) / (2 * h);
        fdh.col(a) = (dp.direction - dm.direction) / (2 * h);
        same_feature = same_feature && dp.triangle == d.triangle && dm.triangle == d.triangle &&
                       dp.features == d.features && dm.features == d.features;
      }
      if (d.distance < 0.0 && !same_feature) continue;  // inside: the medial axis is a kink
      ++checked;
      EXPECT_TRUE(near(d.normal, fd, test::kFdTol))
          << "at " << test::str(p) << ": " << test::str(d.normal) << " vs " << test::str(fd);
      if (!same_feature) continue;
      ++hessians;
      EXPECT_LE((d.hessian - fdh).norm(), 1e-5 * (1.0 + d.hessian.norm())) << test::str(p);
    }
    EXPECT_GT(checked, 300);
    EXPECT_GT(hessians, 250);
  }
}

TEST(MeshCollider, RefusesWhatHasNoDistance) {
  test::TriMesh t = test::square_mesh(1.0, 0.0);
  t.triangles.push_back({0, 1, 4});
  try {
    test::collider_of(t);
    FAIL() << "index out of range accepted";
  } catch (const MeshColliderError& e) {
    EXPECT_EQ(e.triangle(), 2);
  }
  t = test::square_mesh(1.0, 0.0);
  t.triangles.push_back({0, 1, 1});  // zero area
  try {
    test::collider_of(t);
    FAIL() << "degenerate triangle accepted";
  } catch (const MeshColliderError& e) {
    EXPECT_EQ(e.triangle(), 2);
    EXPECT_NE(std::string(e.what()).find("degenerate"), std::string::npos);
  }
  t = test::square_mesh(1.0, 0.0);
  t.vertices(1, 1) = std::nan("");
  EXPECT_THROW(test::collider_of(t), MeshColliderError);
  t = test::square_mesh(1.0, 0.0);
  t.triangles.clear();
  EXPECT_THROW(test::collider_of(t), MeshColliderError);
}

}  // namespace
}  // namespace pbdbench
