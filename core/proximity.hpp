// Distances between surface primitives with their derivatives, and a conservative continuous
// collision check: the geometry of incremental potential contact between surfaces (Li et al.
// 2020, "Incremental Potential Contact", ACM TOG 39(4), sec. 4.1 and appendix; Li, Kaufman and
// Jiang 2021, "Codimensional Incremental Potential Contact" / "Additive CCD"). Pure functions of
// positions; used by ref-be's barrier between bodies (reference/contact_potential.hpp).
//
// Distances are unsigned (a cloth is two-sided). A pair's distance is the minimum over its two
// primitives (point and triangle, or two segments); IPC writes it piecewise by the closest
// feature, its "distance type", each piece a smooth function of the 12 coordinates:
//   point-triangle: P-T0, P-T1, P-T2 (point-point), P-E01, P-E12, P-E20 (point-line), P-T
//     (point-plane);
//   edge-edge: EA0-EB0, EA0-EB1, EA1-EB0, EA1-EB1 (point-point), EA-EB0, EA-EB1, EA0-EB, EA1-EB
//     (point-line), EA-EB (line-line).
// Within a type's region the type's formula equals the true distance, and the pieces meet with
// continuous value and gradient (the closest point moves continuously), so b(d) is C1 across
// them (IPC's argument). The derivatives are those of the type's formula, computed exactly by
// second-order forward-mode differentiation (value, gradient and Hessian carried through every
// operation), and tested against finite differences per type (tests/core/test_proximity.cpp).
//
// Nearly parallel edges: the line-line distance degenerates as the edges' cross product
// vanishes, and the type switches abruptly there; IPC multiplies the edge-edge barrier by the
// mollifier (Li et al. 2020, eq. 23)
//   m(c) = -c^2 / eps_x^2 + 2 c / eps_x for c < eps_x, 1 otherwise,  c = |(a1 - a0) x (b1 - b0)|^2,
//   eps_x = 1e-3 |a1 - a0|^2 |b1 - b0|^2 at rest,
// which goes to 0 with c (C1 at eps_x), so the product vanishes where the type is ambiguous.
#pragma once

#include <array>

#include <Eigen/Core>

#include "core/types.hpp"

namespace pbdbench::proximity {

using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;

enum class PointTriangleType : int { P_T0, P_T1, P_T2, P_E01, P_E12, P_E20, P_T };
enum class EdgeEdgeType : int {
  EA0_EB0, EA0_EB1, EA1_EB0, EA1_EB1,  // point-point
  EA_EB0, EA_EB1, EA0_EB, EA1_EB,      // point-line (the named point against the other line)
  EA_EB                                // line-line
};

// The closest feature of triangle (a, b, c) to p (the Voronoi region of core/bvh's
// closest_point_on_triangle). A degenerate triangle gets an edge or vertex type.
PointTriangleType point_triangle_type(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// The closest features of segments (a0, a1) and (b0, b1): line-line where the closest points are
// interior to both, else point-line or point-point. Parallel segments (|(a1-a0) x (b1-b0)|^2 <=
// 1e-20 |a1-a0|^2 |b1-b0|^2) get the point-line or point-point type of the nearest endpoint.
EdgeEdgeType edge_edge_type(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1);

// The parameters of the closest points of two segments: a0 + s (a1 - a0) and b0 + t (b1 - b0).
void edge_edge_closest(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, double& s,
                       double& t);

// The exact minimum distances (m): point to triangle (closest point), segment to segment.
double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);
double edge_edge_distance(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1);

// A distance with its derivatives over the 12 coordinates (p, a, b, c) or (a0, a1, b0, b1).
struct Distance {
  double d = 0.0;  // unsigned, m
  Vec12 grad = Vec12::Zero();
  Mat12 hess = Mat12::Zero();
  int type = 0;    // the PointTriangleType or EdgeEdgeType used
};

// The distance by the given type's formula (for tests: any type, anywhere it is defined), and by
// the pair's own type. d > 0 needed for the derivatives (the distance is not smooth at 0).
Distance point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                        PointTriangleType type);
Distance point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);
Distance edge_edge(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1,
                   EdgeEdgeType type);
Distance edge_edge(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1);

// The mollifier m(c) above with its derivatives over (a0, a1, b0, b1); eps_x > 0.
struct Mollifier {
  double value = 1.0;
  Vec12 grad = Vec12::Zero();
  Mat12 hess = Mat12::Zero();
};
double mollifier_threshold(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1);
Mollifier edge_edge_mollifier(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1,
                              double eps_x);

// Continuous collision check by conservative advancement (in the manner of additive CCD, Li,
// Kaufman and Jiang 2021): the four vertices move on straight lines x_i + s dx_i, s in [0, limit].
// The distance between the primitives (the true minimum, of point_triangle_distance or
// edge_edge_distance) changes with s at most at the rate L = |dx_0'| + max_{i>0} |dx_i'|
// (point-triangle) or max_{i<2} |dx_i'| + max_{i>=2} |dx_i'| (edge-edge), dx' the displacements
// less their mean (a common translation changes no distance): every point of a primitive is a
// convex combination of its vertices. From gap g = distance - thickness at s, the gap stays
// above keep g0 + 0.1 (g - keep g0) over [s, s + 0.9 (g - keep g0) / L]; the check advances
// by such intervals, evaluating the exact gap at each end.
//
// Returns alpha in [0, limit] with the guarantee: the gap stays >= keep * g0 > 0 for every s in
// [0, alpha] (g0 the gap at s = 0, which must be > 0; keep in (0, 1)). It stops at limit, or
// at the first s where the gap has fallen to 2 keep g0 or below (the primitives are closing;
// returns that s), or after max_iterations advances (returns the s reached: safe, conservative).
enum class PairKind : int { PointTriangle, EdgeEdge };
struct CcdResult {
  double alpha = 0.0;
  int iterations = 0;
};
CcdResult conservative_ccd(PairKind kind, const std::array<Vec3, 4>& x0,
                           const std::array<Vec3, 4>& dx, double thickness, double keep,
                           double limit, int max_iterations = 100000);

}  // namespace pbdbench::proximity
