// Contacts: inequality constraints C(x) >= 0 between particles and colliders, or between two
// particles. They are found anew each step from the positions a solver predicts; the same
// finder serves the metrics (penetration depth and count) with margin 0.
#pragma once

#include <array>
#include <vector>

#include "core/constraint_functions.hpp"
#include "core/model.hpp"

namespace pbdbench {

class SurfaceContactCache;  // core/surface_contact.hpp

enum class ContactKind : std::uint8_t { Plane, Sphere, Particle, Mesh, Triangle, Edge };

// "plane", "sphere", "particle", "mesh", "triangle", "edge"
const char* to_string(ContactKind kind);

struct Contact {
  ContactKind kind = ContactKind::Plane;
  int a = -1;  // the particle
  int b = -1;  // Plane: index into Model::planes; Sphere: into Model::spheres;
               // Particle: the second particle (a < b); Mesh: into Model::meshes;
               // Triangle: into Model::triangles (vertex-triangle contact, a not one of its
               // vertices); Edge: edge (a, b) against edge (c, d) (edge-edge contact, a < b,
               // c < d, (a, b) before (c, d))
  int c = -1, d = -1;  // Edge only
};

// All candidate contacts whose C(x) < margin, for particles with inv_mass > 0 (and, for particle
// pairs, at least one of them dynamic), at time t (moving spheres). Particle pairs joined by a
// constraint are skipped. The order is deterministic: planes, then spheres, then meshes, then
// particle pairs, then (with Model::surface_contact or self_contact) vertex-triangle pairs, then
// edge-edge pairs, each sorted by (a, b) (edges: by (a, b, c, d)). Particle pairs are found with a uniform grid, not by
// testing all pairs; a mesh is tested only for the particles within margin + radius of its
// bounding box (its BVH then finds the nearest triangle). `surface_cache` (optional) keeps the
// vertex-triangle broad phase between calls (refit, not rebuilt; the same contacts).
std::vector<Contact> find_contacts(const Model& model, const Points& x, double t, double margin,
                                   SurfaceContactCache* surface_cache = nullptr);

// Evaluate a contact (C >= 0 is separated; C < 0 is penetration, in metres). Uses the unit plane
// normal. grad[0] is with respect to particle a; grad[1] with respect to particle b for particle
// contacts.
//   Plane:    C = (n . x_a + offset) / |n| - r_a
//   Sphere:   Outside: |x_a - c(t)| - (R + r_a);  Inside/Bowl: (R - r_a) - |x_a - c(t)|
//   Particle: C = |x_a - x_b| - (r_a + r_b)
//   Triangle: C = |x_a - q| - (r_a + max r of the triangle's vertices), q the triangle's closest
//             point u x_0 + v x_1 + w x_2 (core/surface_contact.hpp); grad[0] = n = (x_a - q) /
//             |x_a - q|, grad[1..3] = -u n, -v n, -w n for the triangle's vertices
//   Edge:     C = |P - Q| - (max(r_a, r_b) + max(r_c, r_d)), P = (1 - s) x_a + s x_b and
//             Q = (1 - t) x_c + t x_d the closest points of the two edges (core/surface_contact.hpp);
//             grad = (1 - s) n, s n, -(1 - t) n, -t n for a, b, c, d, n = (P - Q) / |P - Q|
//   Mesh:     C = s(x_a - offset(t)) - r_a, s the mesh's signed distance (core/mesh_collider.hpp:
//             the closest point of the nearest triangle, signed by the feature's pseudo-normal);
//             grad = its gradient, the unit direction from the closest point (sign included)
ConstraintEval eval_contact(const Model& model, const Contact& contact, const Points& x, double t);

// The particles a contact involves, in the order of eval_contact's gradients: a (colliders); a,
// b (particle pairs); a and the triangle's three vertices (vertex-triangle); a, b, c, d
// (edge-edge). Returns the count.
int contact_particles(const Model& model, const Contact& contact, std::array<int, 4>& out);

// Restitution and friction coefficients that apply to a contact (vertex-triangle: the particles'
// restitution, Model::surface_friction).
double contact_restitution(const Model& model, const Contact& contact);
double contact_friction(const Model& model, const Contact& contact);

// Velocity of the collider surface at the contact (m/s): zero for planes and fixed spheres, the
// sphere's (or mesh's) motion velocity for moving spheres (meshes), the other particle's velocity for particle pairs
// (taken from v); zero for vertex-triangle and edge-edge contacts (see velocity_pass).
Vec3 contact_surface_velocity(const Model& model, const Contact& contact, const Points& v,
                              double t);

}  // namespace pbdbench
