// A bounding volume hierarchy over a static triangle mesh: the building block of a mesh collider
// (core/mesh_collider.hpp) and of vertex-triangle contact (core/surface_contact.hpp). Axis-aligned boxes, split at the median of the triangles' centroids along the box's
// longest axis, at most kLeafSize triangles a leaf. Built once; queries are const and
// thread-safe. A mesh whose vertices move (a cloth, a soft body) may be refit instead of rebuilt:
// the same tree, its boxes recomputed bottom-up from the moved vertices (every box still bounds
// its triangles, so a query finds the same triangles as a tree built anew; only the pruning, the
// tree's quality, may degrade: box_area() measures it).
//
// The closest point on a triangle is found by the Voronoi-region test of Ericson, "Real-Time
// Collision Detection" (2005), sec. 5.1.5: the point's region (a vertex, an edge, or the face)
// from the signs of dot products, then the projection onto that feature.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "core/types.hpp"

namespace pbdbench {

// The point of triangle (a, b, c) closest to p; `bary` (when given) gets its barycentric
// coordinates (u, v, w), u a + v b + w c. A degenerate triangle (a segment or a point) is handled
// by the same regions (its face region is empty).
Vec3 closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                               Vec3* bary = nullptr);

class TriangleBvh {
 public:
  static constexpr int kLeafSize = 4;

  struct Box {
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    void grow(const Vec3& p) { lo = lo.cwiseMin(p); hi = hi.cwiseMax(p); }
    void grow(const Box& b) { lo = lo.cwiseMin(b.lo); hi = hi.cwiseMax(b.hi); }
    // Squared distance from p to the box (0 inside).
    double squared_distance(const Vec3& p) const;
    bool overlaps(const Box& b) const;
  };

  struct Hit {
    int triangle = -1;          // -1: none within the search radius
    Vec3 point = Vec3::Zero();  // the closest point on the mesh
    Vec3 bary = Vec3::Zero();   // its barycentric coordinates in `triangle`
    double distance = 0.0;      // |p - point|
  };

  TriangleBvh() = default;
  // Copies the vertices and triangles. Throws std::invalid_argument for a vertex index out of
  // range or a non-finite vertex.
  TriangleBvh(const Points& vertices, const std::vector<std::array<int, 3>>& triangles);

  int triangle_count() const { return static_cast<int>(triangles_.size()); }
  int vertex_count() const { return static_cast<int>(vertices_.rows()); }

  // Moves the mesh to `vertices` (as many rows as before; the same triangles) and recomputes
  // every box bottom-up: a leaf's from its triangles, a node's from its children. The tree's
  // shape (which triangles share a leaf) is kept. Throws std::invalid_argument for another
  // vertex count or a non-finite vertex (the tree is then unchanged).
  void refit(const Points& vertices);

  // The sum of the surface areas of all the nodes' boxes, m^2: the expected cost of a query
  // grows with it (the surface area heuristic); a refit tree's against a fresh one's tells how
  // far its quality has degraded.
  double box_area() const;
  const Box& bounds() const;  // of the whole mesh (an empty box for no triangles)

  // The closest point of the mesh to p among the triangles within max_distance of it (ties: the
  // lowest triangle index). hit.triangle = -1 when none is.
  Hit closest(const Vec3& p, double max_distance = 1e300) const;

  // Calls visit(triangle) for every triangle whose box overlaps `box`, in increasing order of
  // node visits (deterministic).
  void overlapping(const Box& box, const std::function<void(int)>& visit) const;

  // Nodes visited by the last closest() on this thread (for the tests' check that the tree
  // prunes).
  static long last_visits();

 private:
  struct Node {
    Box box;
    int left = -1, right = -1;  // children, or -1 for a leaf
    int first = 0, count = 0;   // a leaf's range in order_
  };
  int build(int first, int count);

  Points vertices_;
  std::vector<std::array<int, 3>> triangles_;
  std::vector<int> order_;  // triangle indices, grouped by leaf
  std::vector<Box> tri_box_;
  std::vector<Vec3> centroid_;
  std::vector<Node> nodes_;  // nodes_[0] is the root
};

}  // namespace pbdbench
