// Vertex–triangle contact (issue 17): a particle against a surface triangle of the model (the
// triangles of Model::triangles: a cloth's, a tet body's boundary, an imported surface).
//   - Between bodies (Model::surface_contact, the scenario key scene.surface_contact): every
//     particle against the triangles of every other body (Model::particle_body), both moving.
//   - Within a body (Model::self_contact, scene.self_contact): a particle against its own body's
//     triangles, for bodies without tets only (a cloth folding onto itself; a tet body's own
//     vertices are held apart by its elements, and its interior vertices lie within the
//     thickness of its own boundary). A triangle with a vertex that is the particle or one of
//     its neighbours (sharing a triangle with it) is skipped: those are the cloth's own fabric.
// Edge–edge contact is not modelled.
//
// The gap of particle p against triangle (a, b, c) is the distance from x_p to the triangle's
// closest point q = u x_a + v x_b + w x_c (Ericson 2005, sec. 5.1.5) minus the thickness
// r_p + max(r_a, r_b, r_c): unsigned, so a cloth is two-sided. Its gradient, with n = (x_p - q) /
// |x_p - q|: n for p and -u n, -v n, -w n for a, b, c (q minimises the distance over the
// triangle, so moving (u, v, w) does not change it to first order).
#pragma once

#include <array>
#include <utility>
#include <vector>

#include "core/model.hpp"

namespace pbdbench {

struct PointTriangle {
  double distance = 0.0;        // |x_p - q|, m
  Vec3 normal = Vec3::UnitY();  // (x_p - q) / distance; the triangle's unit normal when 0
  Vec3 bary = Vec3::Zero();     // (u, v, w) of q
};

PointTriangle point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// Whether vertex-triangle contact is on at all (between bodies or within one).
inline bool vertex_triangle_contact(const Model& model) {
  return model.surface_contact || model.self_contact;
}

// r_p + max of the triangle's vertices' radii (m): the gap at which they touch.
double surface_contact_thickness(const Model& model, int particle, int triangle);

// The body of a particle: Model::particle_body's entry, 0 when that is empty.
int particle_body(const Model& model, int particle);

// Whether the pair (particle, triangle) is one that vertex-triangle contact considers, by the
// rules above (bodies, self-contact, neighbours); positions play no part. For tests and tools:
// find_surface_contacts applies the same rules with its tables built once per call.
bool surface_pair_allowed(const Model& model, int particle, int triangle);

// The (particle, triangle) pairs whose gap at x is below margin, by the rules above: at least one
// of the four particles dynamic, positions finite. A BVH over the triangles at x (core/bvh.hpp),
// built anew at every call (the solvers call once per substep), is the broad phase. Sorted by
// (particle, triangle). Empty unless Model::surface_contact or Model::self_contact is set.
std::vector<std::pair<int, int>> find_surface_contacts(const Model& model, const Points& x,
                                                       double margin);

}  // namespace pbdbench
