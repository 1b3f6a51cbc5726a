// Triangle meshes for the mesh-collider tests (core, solvers, reference): a square of two
// triangles, a cube and an icosphere, all wound outward (counter-clockwise seen from outside).
#pragma once

#include <array>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "core/mesh_collider.hpp"
#include "core/types.hpp"

namespace pbdbench::test {

struct TriMesh {
  Points vertices;
  std::vector<std::array<int, 3>> triangles;
};

inline Points to_points(const std::vector<Vec3>& v) {
  Points p(static_cast<Eigen::Index>(v.size()), 3);
  for (size_t i = 0; i < v.size(); ++i) p.row(static_cast<Eigen::Index>(i)) = v[i].transpose();
  return p;
}

// The square [-h, h]^2 in the plane y = height, normal +y, as two triangles.
inline TriMesh square_mesh(double h, double height) {
  TriMesh m;
  m.vertices = to_points({Vec3(-h, height, -h), Vec3(h, height, -h), Vec3(h, height, h), Vec3(-h, height, h)});
  m.triangles = {{0, 2, 1}, {0, 3, 2}};  // (v2 - v0) x (v1 - v0) along +y
  return m;
}

// The cube [-h, h]^3 centred at c, 12 triangles, outward.
inline TriMesh cube_mesh(double h, const Vec3& c = Vec3::Zero()) {
  TriMesh m;
  std::vector<Vec3> v;
  for (int i = 0; i < 8; ++i)
    v.push_back(c + h * Vec3((i & 1) ? 1 : -1, (i & 2) ? 1 : -1, (i & 4) ? 1 : -1));
  m.vertices = to_points(v);
  // Each face as a quad (a, b, c, d) counter-clockwise from outside.
  const int quads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  for (const auto& q : quads) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
  }
  return m;
}

// The icosahedron subdivided `levels` times, vertices on the sphere of radius R about c.
inline TriMesh icosphere_mesh(int levels, double R, const Vec3& c = Vec3::Zero()) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                         {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (Vec3& p : v) p.normalize();
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[static_cast<size_t>(a)] + v[static_cast<size_t>(b)]).normalized());
      const int id = static_cast<int>(v.size()) - 1;
      mid[key] = id;
      return id;
    };
    std::vector<std::array<int, 3>> g;
    for (const auto& tri : f) {
      const int a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), cc = midpoint(tri[2], tri[0]);
      g.push_back({tri[0], a, cc});
      g.push_back({tri[1], b, a});
      g.push_back({tri[2], cc, b});
      g.push_back({a, b, cc});
    }
    f = std::move(g);
  }
  for (Vec3& p : v) p = c + R * p;
  TriMesh m;
  m.vertices = to_points(v);
  m.triangles = f;
  return m;
}

inline MeshCollider collider_of(const TriMesh& m) { return make_mesh_collider(m.vertices, m.triangles); }

}  // namespace pbdbench::test
