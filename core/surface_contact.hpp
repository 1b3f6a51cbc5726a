// Contact between surfaces: vertex–triangle, a particle against a surface triangle of
// the model (the triangles of Model::triangles: a cloth's, a tet body's boundary, an imported
// surface), and edge–edge, an edge of those triangles against another, under the same switches
// and rules.
//   - Between bodies (Model::surface_contact, the scenario key scene.surface_contact): every
//     particle against the triangles of every other body (Model::particle_body), both moving.
//   - Within a body (Model::self_contact, scene.self_contact): a particle against its own body's
//     triangles, for bodies without tets only (a cloth folding onto itself; a tet body's own
//     vertices are held apart by its elements, and its interior vertices lie within the
//     thickness of its own boundary). A triangle with a vertex that is the particle or one of
//     its neighbours (sharing a triangle with it) is skipped: those are the cloth's own fabric.
// Edge–edge: every unique edge of the triangles (surface_edges) against every other, between
// bodies with Model::surface_contact, within a body without tets with Model::self_contact; a
// pair sharing a vertex, or (within a body) with a vertex of one a neighbour of a vertex of the
// other, is skipped. Without it, two edges cross where no vertex comes near a triangle (a cloth's
// edge through a block's edge, a fold's edge through another): vertex–triangle contact alone
// does not see them.
//
// The gap of particle p against triangle (a, b, c) is the distance from x_p to the triangle's
// closest point q = u x_a + v x_b + w x_c (Ericson 2005, sec. 5.1.5) minus the thickness
// r_p + max(r_a, r_b, r_c): unsigned, so a cloth is two-sided. Its gradient, with n = (x_p - q) /
// |x_p - q|: n for p and -u n, -v n, -w n for a, b, c (q minimises the distance over the
// triangle, so moving (u, v, w) does not change it to first order).
//
// The gap of edges (a, b) and (c, d) is the distance between their closest points P = (1 - s) x_a
// + s x_b and Q = (1 - t) x_c + t x_d (Ericson 2005, sec. 5.1.9) minus the thickness
// max(r_a, r_b) + max(r_c, r_d) (as the vertex–triangle one's: a particle's radius on each
// side, the larger of a feature's); unsigned. Its gradient, with n = (P - Q) / |P - Q|:
// (1 - s) n, s n, -(1 - t) n, -t n for a, b, c, d (P and Q minimise the distance over the
// segments; where s or t is clamped at an end, it stays there to first order).
//
// The memory of a search is bounded (as particle contacts', core/contacts.cpp): a search that
// finds more than contact_pair_limit(n) pairs (vertex-triangle: n the particles; edge-edge: n the
// surface edges) throws ContactPairLimit instead of going on. At most kMaxPairsPerElement pairs
// per element on average: a particle within its thickness of 64 triangles not its own fabric,
// or an edge of 64 edges, means the thickness (radius plus contact margin) spans several mesh
// spacings, the surfaces lie inside one another, and the pairs grow with the square of the
// count (a 64 x 64 self-contact cloth with a radius of its size: 70 million edge pairs, 5 GB).
// kPairSlack pairs (about 20 MB with their contacts) are always allowed, so that a small dense
// scene is never refused. Below the limit the contacts are all of them, in the same order: the
// limit changes no result; it only stops a search that would exhaust the memory, and the
// message says which search, how many elements and the limit.
#pragma once

#include <array>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/bvh.hpp"
#include "core/model.hpp"

namespace pbdbench {

inline constexpr std::size_t kMaxPairsPerElement = 64;
inline constexpr std::size_t kPairSlack = 1000000;

// The most pairs a search over `elements` particles (or edges) may hold.
constexpr std::size_t contact_pair_limit(std::size_t elements) {
  return kMaxPairsPerElement * elements + kPairSlack;
}

// Thrown by a search that exceeds contact_pair_limit: "edge-edge contacts: more than ...".
class ContactPairLimit : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The message of ContactPairLimit for `what` ("edge-edge contacts"), `elements` of `unit`
// ("edges") at contact margin `margin` (m).
std::string contact_pair_limit_message(const std::string& what, std::size_t elements,
                                       const std::string& unit, double margin);

struct PointTriangle {
  double distance = 0.0;        // |x_p - q|, m
  Vec3 normal = Vec3::UnitY();  // (x_p - q) / distance; the triangle's unit normal when 0
  Vec3 bary = Vec3::Zero();     // (u, v, w) of q
};

PointTriangle point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

struct SegmentSegment {
  double distance = 0.0;        // |P - Q|, m
  Vec3 normal = Vec3::UnitY();  // (P - Q) / distance; when 0, the unit (b - a) x (d - c) (y
                                // when the segments are parallel or a point)
  double s = 0.0, t = 0.0;      // P = (1 - s) a + s b, Q = (1 - t) c + t d, both in [0, 1]
};

// The closest points of segments (a, b) and (c, d). A segment of zero length is its point.
SegmentSegment segment_segment(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

// The unique edges of Model::triangles, (i, j) with i < j, sorted.
std::vector<std::array<int, 2>> surface_edges(const Model& model);

// max(r_a, r_b) + max(r_c, r_d) (m): the gap at which edges (a, b) and (c, d) touch.
double edge_contact_thickness(const Model& model, const std::array<int, 4>& particles);

// Whether edge-edge contact considers edges e and f (of surface_edges), by the rules above.
bool edge_pair_allowed(const Model& model, const std::array<int, 2>& e, const std::array<int, 2>& f);

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

// The broad phase kept from one call to the next (a solver's substeps): the BVH over the model's
// triangles, refit to the new positions (TriangleBvh::refit) instead of built anew. The rule:
// it is rebuilt when it holds other triangles or another vertex count than the call's (another
// model), and when, after a refit, the sum of its boxes' surface areas exceeds kRebuildFactor
// times that sum when it was last built (the boxes have grown apart: the pruning degrades);
// otherwise refit. A call with a non-finite position uses no cache (a fresh BVH over the finite
// triangles, as without one) and leaves it to be rebuilt. Refit or rebuilt, the tree's boxes
// bound the same triangles, so the contacts found are the same (tested): the cache changes the
// cost, never the result.
class SurfaceContactCache {
 public:
  static constexpr double kRebuildFactor = 1.5;

  long builds() const { return builds_; }  // trees built (the first call's included)
  long refits() const { return refits_; }  // calls served by a refit

  // The trees for `model`'s triangles and for its edges (surface_edges, as the segments
  // (i, j, j)) at x (all finite): refit or rebuilt by the rule above.
  const TriangleBvh& triangles(const Model& model, const Points& x);
  const TriangleBvh& edges(const Model& model, const Points& x);
  const std::vector<std::array<int, 2>>& edge_list(const Model& model);
  void clear() { tri_.valid = edge_.valid = false; }

 private:
  struct Tree {
    TriangleBvh bvh;
    std::vector<std::array<int, 3>> triangles;  // those the tree was built for
    double built_area = 0.0;                    // its box_area() when built
    bool valid = false;
  };
  const TriangleBvh& update(Tree& tree, const std::vector<std::array<int, 3>>& triangles,
                            const Points& x);
  Tree tri_, edge_;
  std::vector<std::array<int, 3>> edge_source_;  // the model triangles edge_list_ came from
  std::vector<std::array<int, 2>> edge_list_;
  std::vector<std::array<int, 3>> edge_segments_;
  long builds_ = 0, refits_ = 0;
};

// The (particle, triangle) pairs whose gap at x is below margin, by the rules above: at least one
// of the four particles dynamic, positions finite. A BVH over the triangles at x (core/bvh.hpp)
// is the broad phase: built anew at every call, or, with a cache, refit from the last call's
// (the solvers keep one per solver: they call once per substep). Sorted by (particle, triangle).
// Empty unless Model::surface_contact or Model::self_contact is set. Throws ContactPairLimit
// past contact_pair_limit(particles).
std::vector<std::pair<int, int>> find_surface_contacts(const Model& model, const Points& x,
                                                       double margin,
                                                       SurfaceContactCache* cache = nullptr);

// The edge pairs (a, b, c, d: edges (a, b) and (c, d) of surface_edges, the first before the
// second in its order) whose gap at x is below margin, by the rules above: at least one of the
// four particles dynamic, positions finite. The broad phase is a BVH over the edges (built anew,
// or with a cache refit as above). Sorted. Empty unless Model::surface_contact or
// Model::self_contact is set, and Model::edge_contact (on by default) is. Throws
// ContactPairLimit past contact_pair_limit(surface edges).
std::vector<std::array<int, 4>> find_edge_contacts(const Model& model, const Points& x,
                                                   double margin,
                                                   SurfaceContactCache* cache = nullptr);

}  // namespace pbdbench
