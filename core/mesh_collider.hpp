// A triangle mesh as a collider: its placed vertices and triangles, a BVH over them
// (core/bvh.hpp, the broad phase) and the signed distance of a point to it (the narrow phase:
// the closest point on the nearest triangle, Ericson 2005, sec. 5.1.5).
//
// The sign is that of the angle-weighted pseudo-normal of the closest feature (Baerentzen and
// Aanaes 2005, "Signed distance computation using the angle weighted pseudonormal", IEEE TVCG
// 11(3)): the face's normal when the closest point is inside a face, the sum of the normals of
// the faces sharing an edge, or the angle-weighted sum of those around a vertex. For a closed,
// consistently outward-wound mesh this is the inside/outside test (negative inside). For an open
// mesh it says on which side of the nearest face the point lies; across the extension of a
// boundary edge the sign flips, so an open mesh is a one-sided shell near its faces only.
//
// A kinematic mesh moves rigidly by the offset of a scripted motion (a translation, as a moving
// sphere's centre); the distance at time t is that of x - offset(t) to the mesh at rest.
#pragma once

#include <array>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/bvh.hpp"
#include "core/types.hpp"

namespace pbdbench {

struct MeshCollider {
  std::string file;  // the OBJ it was read from (messages only)
  Points vertices;   // (V x 3) m, placed, at t = 0 (before the motion's offset)
  std::vector<std::array<int, 3>> triangles;
  std::vector<Vec3> face_normal;                // (T) unit, (b - a) x (c - a) normalised
  std::vector<std::array<Vec3, 3>> edge_normal; // (T) pseudo-normal of edge (k, k+1 mod 3)
  std::vector<Vec3> vertex_normal;              // (V) angle-weighted pseudo-normal
  TriangleBvh bvh;
  bool closed = false;  // every edge shared by exactly two triangles, wound consistently
  double restitution = 0.0;
  double friction = 0.0;
  int motion = -1;  // index into Model::motions, or -1 for a static mesh
};

// What make_mesh_collider refuses; `triangle` is the offending triangle's index, or -1.
class MeshColliderError : public std::invalid_argument {
 public:
  MeshColliderError(int triangle, const std::string& what)
      : std::invalid_argument(what), triangle_(triangle) {}
  int triangle() const { return triangle_; }

 private:
  int triangle_;
};

// Builds the normals and the BVH. Throws MeshColliderError naming the triangle (its index) for a
// vertex index out of range or a degenerate triangle (area at most 1e-12 times the square of the
// bounding box's diagonal: its normal is undefined), and (triangle -1) for a non-finite vertex or
// a mesh without triangles.
MeshCollider make_mesh_collider(Points vertices, std::vector<std::array<int, 3>> triangles);

// The signed distance of p (in the mesh's rest frame: x - offset(t)) to the mesh and its
// derivatives. `features` is 3 (face), 2 (edge) or 1 (vertex): the closest point's feature.
struct MeshDistance {
  double distance = 0.0;           // signed, m (negative behind the surface)
  double unsigned_distance = 0.0;  // |p - point|
  Vec3 point = Vec3::Zero();       // the closest point of the mesh
  Vec3 normal = Vec3::UnitY();     // the gradient of the signed distance: sign (p - point) /
                                   // |p - point|, or the pseudo-normal when p is on the surface
  Vec3 direction = Vec3::UnitY();  // the gradient of the unsigned distance, (p - point) / |p -
                                   // point| (the pseudo-normal when p is on the surface)
  Mat3 hessian = Mat3::Zero();     // of the unsigned distance: 0 in a face, (I - t t^T - g g^T)
                                   // / d at an edge of direction t, (I - g g^T) / d at a vertex
  int triangle = -1;
  int features = 3;
};

// The distance to the nearest triangle within max_distance; triangle = -1 when there is none.
MeshDistance mesh_distance(const MeshCollider& mesh, const Vec3& p, double max_distance = 1e300);

}  // namespace pbdbench
