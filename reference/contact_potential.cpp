// The IPC barrier, lagged friction and the continuous collision check. contact_potential.hpp.
#include "reference/contact_potential.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace pbdbench::barrier {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

double value(double d, double d_hat) {
  if (!(d > 0.0)) return kInf;
  if (d >= d_hat) return 0.0;
  const double s = d - d_hat;
  return -s * s * std::log(d / d_hat);
}

double first(double d, double d_hat) {
  if (!(d > 0.0)) return kNaN;
  if (d >= d_hat) return 0.0;
  const double s = d - d_hat;
  return -2.0 * s * std::log(d / d_hat) - s * s / d;
}

double second(double d, double d_hat) {
  if (!(d > 0.0)) return kNaN;
  if (d >= d_hat) return 0.0;
  const double s = d - d_hat;
  return -2.0 * std::log(d / d_hat) - 4.0 * s / d + s * s / (d * d);
}

double f0(double y, double e) {
  if (y >= e) return y;
  return y * y / e - y * y * y / (3.0 * e * e) + e / 3.0;
}

double f1(double y, double e) {
  if (y >= e) return 1.0;
  const double r = y / e;
  return 2.0 * r - r * r;
}

double f1_prime(double y, double e) {
  if (y >= e) return 0.0;
  return 2.0 / e - 2.0 * y / (e * e);
}

namespace {

// The unit up direction that decides a bowl's open half.
bool below_centre(const Model& model, const Vec3& x, const Vec3& c) {
  return (x - c).dot(up_direction(model)) < 0.0;
}

// Gap and derivatives of the distance |p| - R (sign +1) or R - |p| (sign -1) with respect to p.
void radial(const Vec3& p, double R, double sign, double& d, Vec3& g, Mat3& H) {
  const double r = p.norm();
  d = sign * (r - R);
  const Vec3 n = r > 0.0 ? Vec3(p / r) : Vec3(Vec3::UnitY());
  g = sign * n;
  H = r > 0.0 ? Mat3(sign * (Mat3::Identity() - n * n.transpose()) / r) : Mat3(Mat3::Zero());
}

}  // namespace

Gap gap(const Model& model, const Contact& c, const Points& x, double t) {
  Gap out;
  const Vec3 xa = x.row(c.a).transpose();
  const double ra = model.radius[static_cast<size_t>(c.a)];
  switch (c.kind) {
    case ContactKind::Plane: {
      const PlaneCollider& p = model.planes[static_cast<size_t>(c.b)];
      const double nn = p.normal.norm();
      out.d = (p.normal.dot(xa) + p.offset) / nn - ra;
      out.grad.head<3>() = p.normal / nn;
      break;
    }
    case ContactKind::Sphere: {
      const SphereCollider& s = model.spheres[static_cast<size_t>(c.b)];
      const Vec3 centre = sphere_center(model, s, t);
      double d;
      Vec3 g;
      Mat3 H;
      if (s.side == SphereSide::Outside)
        radial(xa - centre, s.radius + ra, 1.0, d, g, H);
      else
        radial(xa - centre, s.radius - ra, -1.0, d, g, H);
      out.d = d;
      out.grad.head<3>() = g;
      out.hess.topLeftCorner<3, 3>() = H;
      break;
    }
    case ContactKind::Mesh: {
      // The unsigned distance to the mesh (IPC's): every accepted state keeps it above the
      // radius, so the particle never changes sides and the signed distance is the same there.
      const MeshCollider& m = model.meshes[static_cast<size_t>(c.b)];
      const MeshDistance md = mesh_distance(m, xa - mesh_offset(model, m, t));
      out.d = md.unsigned_distance - ra;
      out.grad.head<3>() = md.direction;
      out.hess.topLeftCorner<3, 3>() = md.hessian;
      break;
    }
    case ContactKind::Particle: {
      const Vec3 xb = x.row(c.b).transpose();
      const double rb = model.radius[static_cast<size_t>(c.b)];
      double d;
      Vec3 g;
      Mat3 H;
      radial(xa - xb, ra + rb, 1.0, d, g, H);
      out.d = d;
      out.size = 6;
      out.grad.head<3>() = g;
      out.grad.tail<3>() = -g;
      out.hess.topLeftCorner<3, 3>() = H;
      out.hess.topRightCorner<3, 3>() = -H;
      out.hess.bottomLeftCorner<3, 3>() = -H;
      out.hess.bottomRightCorner<3, 3>() = H;
      break;
    }
    case ContactKind::Edge:  // (edge-edge: refused with it)
    case ContactKind::Triangle:  // refused by make_ref_be_contact
      throw std::logic_error("ref-be: a vertex-triangle contact reached the barrier");
  }
  return out;
}

std::vector<Gap> barrier_terms(const Model& model, const Contact& c, const Points& x, double t,
                               double d_hat) {
  if (c.kind != ContactKind::Mesh) return {gap(model, c, x, t)};
  std::vector<Gap> out;
  const MeshCollider& m = model.meshes[static_cast<size_t>(c.b)];
  const Vec3 p = x.row(c.a).transpose() - mesh_offset(model, m, t);
  const double r = model.radius[static_cast<size_t>(c.a)];
  TriangleBvh::Box box;
  box.grow(p);
  box.lo.array() -= r + d_hat;
  box.hi.array() += r + d_hat;
  std::vector<int> tris;
  m.bvh.overlapping(box, [&](int k) { tris.push_back(k); });
  std::sort(tris.begin(), tris.end());
  for (int k : tris) {
    const auto& tri = m.triangles[static_cast<size_t>(k)];
    Vec3 bary;
    const Vec3 a = m.vertices.row(tri[0]).transpose(), b = m.vertices.row(tri[1]).transpose(),
               cc = m.vertices.row(tri[2]).transpose();
    const Vec3 q = closest_point_on_triangle(p, a, b, cc, &bary);
    const Vec3 u = p - q;
    const double dist = u.norm();
    if (!(dist > 0.0)) {  // on the triangle: the barrier is infinite there
      Gap g;
      g.d = -r;
      out.push_back(g);
      continue;
    }
    if (!(dist - r < d_hat)) continue;
    Gap g;
    g.d = dist - r;
    const Vec3 dir = u / dist;
    g.grad.head<3>() = dir;
    int nonzero = 0, zero = 0;  // the closest feature: the regions give exact zeros
    for (int i = 0; i < 3; ++i) {
      if (bary[i] != 0.0) ++nonzero;
      else zero = i;
    }
    if (nonzero == 1) {
      g.hess.topLeftCorner<3, 3>() = (Mat3::Identity() - dir * dir.transpose()) / dist;
    } else if (nonzero == 2) {
      const int e0 = (zero + 1) % 3, e1 = (zero + 2) % 3;
      const Vec3 te = (m.vertices.row(tri[static_cast<size_t>(e1)]) - m.vertices.row(tri[static_cast<size_t>(e0)]))
                          .transpose()
                          .normalized();
      g.hess.topLeftCorner<3, 3>() =
          (Mat3::Identity() - te * te.transpose() - dir * dir.transpose()) / dist;
    }
    out.push_back(g);
  }
  return out;
}

Vec3 tangential_displacement(const FrictionContact& f, const Points& x, const Points& x0) {
  Vec3 dx = (x.row(f.contact.a) - x0.row(f.contact.a)).transpose() - f.collider_motion;
  if (f.contact.kind == ContactKind::Particle)
    dx -= (x.row(f.contact.b) - x0.row(f.contact.b)).transpose();
  return dx - f.normal * f.normal.dot(dx);
}

double friction_value(const FrictionContact& f, const Vec3& u, double e) {
  return f.mu * f.lambda * f0(u.norm(), e);
}

Vec3 friction_gradient(const FrictionContact& f, const Vec3& u, double e) {
  const double y = u.norm();
  if (y == 0.0) return Vec3::Zero();
  return f.mu * f.lambda * f1(y, e) * u / y;
}

Mat3 friction_hessian(const FrictionContact& f, const Vec3& u, double e) {
  const Mat3 P = Mat3::Identity() - f.normal * f.normal.transpose();
  const double y = u.norm();
  const double k = f.mu * f.lambda;
  if (y < 1e-12 * e) return k * (2.0 / e) * P;  // the limit y -> 0 of both terms below
  const Vec3 w = u / y;
  const Mat3 ww = w * w.transpose();
  return k * (f1_prime(y, e) * ww + (f1(y, e) / y) * (P - ww));
}

namespace {

// Smallest s in (0, 1] where |p + s q| crosses the radius `target` from the side it starts on
// (outside: decreasing to target; inside: increasing to target), or +inf when it does not.
double radial_crossing(const Vec3& p, const Vec3& q, double target, bool from_outside) {
  // |p + s q|^2 - target^2 = a s^2 + b s + c
  const double a = q.squaredNorm();
  const double b = 2.0 * p.dot(q);
  const double c = p.squaredNorm() - target * target;
  if (a == 0.0) return kInf;
  const double disc = b * b - 4.0 * a * c;
  if (from_outside) {
    if (disc < 0.0) return kInf;
    // The first root: where the distance first drops to target (c > 0 at s = 0).
    const double sq = std::sqrt(disc);
    const double s = (-b - sq) / (2.0 * a);
    return s >= 0.0 ? s : kInf;
  }
  // Inside (c < 0): the larger root is where it leaves the ball; disc > 0 always then.
  const double sq = std::sqrt(std::max(disc, 0.0));
  const double s = (-b + sq) / (2.0 * a);
  return s >= 0.0 ? s : kInf;
}

// The distance from the point y0 + s dy to triangle t of the mesh: convex in s.
double triangle_distance(const MeshCollider& m, int t, const Vec3& y0, const Vec3& dy, double s) {
  const auto& tri = m.triangles[static_cast<size_t>(t)];
  const Vec3 p = y0 + s * dy;
  const Vec3 q = closest_point_on_triangle(p, m.vertices.row(tri[0]).transpose(),
                                           m.vertices.row(tri[1]).transpose(),
                                           m.vertices.row(tri[2]).transpose());
  return (p - q).norm();
}

// The largest s in [0, limit] such that the distance from y0 + s' dy to triangle t stays above
// `target` for every s' in [0, s] (the distance at s = 0 is above it). The distance is convex in s
// (a point moving on a line, a convex set): its minimum on [0, limit] by golden-section search;
// when that minimum is below target, the crossing on the decreasing side by bisection, whose
// lower end (still above target) is returned. Both to 1e-12 of limit: the bound keeps the gap
// above target up to that fraction of the step, a small part of the 10 % it keeps.
double triangle_crossing(const MeshCollider& m, int t, const Vec3& y0, const Vec3& dy,
                         double target, double limit) {
  if (triangle_distance(m, t, y0, dy, limit) > target) {
    // The minimum may still lie inside; golden-section search for it.
    double lo = 0.0, hi = limit;
    const double phi = 0.5 * (std::sqrt(5.0) - 1.0);
    double a = hi - phi * (hi - lo), b = lo + phi * (hi - lo);
    double fa = triangle_distance(m, t, y0, dy, a), fb = triangle_distance(m, t, y0, dy, b);
    while (hi - lo > 1e-12 * limit) {
      if (fa <= target || fb <= target) break;
      if (fa < fb) {
        hi = b;
        b = a;
        fb = fa;
        a = hi - phi * (hi - lo);
        fa = triangle_distance(m, t, y0, dy, a);
      } else {
        lo = a;
        a = b;
        fa = fb;
        b = lo + phi * (hi - lo);
        fb = triangle_distance(m, t, y0, dy, b);
      }
    }
    if (fa > target && fb > target) return limit;
    limit = fa <= target ? a : b;
  }
  // f(0) > target >= f(limit): bisection keeps f(lo) > target >= f(hi).
  double lo = 0.0, hi = limit;
  while (hi - lo > 1e-12 * std::max(limit, 1e-300)) {
    const double mid = 0.5 * (lo + hi);
    if (triangle_distance(m, t, y0, dy, mid) > target) lo = mid;
    else hi = mid;
  }
  return lo;
}

// The step bound of particle path a0 -> a0 + da (radius r) against a mesh moving from offset o0
// to o1: in the mesh's frame the point moves on the straight path y0 + s dy.
double mesh_step_bound(const Model& model, const MeshCollider& m, const Vec3& a0, const Vec3& da,
                       double r, double t0, double t1, double keep, double alpha) {
  const Vec3 o0 = mesh_offset(model, m, t0), o1 = mesh_offset(model, m, t1);
  const Vec3 y0 = a0 - o0, dy = da - (o1 - o0);
  // The distance falls by at most |dy| over the path: from farther than r + |dy| / (1 - keep)
  // the gap keeps its fraction `keep` whatever the path does.
  const double reach = r + dy.norm() / (1.0 - keep);
  if (m.bvh.bounds().squared_distance(y0) > reach * reach) return alpha;
  const MeshDistance md = mesh_distance(m, y0, reach);
  if (md.triangle < 0) return alpha;
  const double d0 = md.unsigned_distance - r;
  if (d0 <= 0.0) return alpha;
  const double target = r + keep * d0;
  // Only triangles within target of some point of the path can be reached.
  TriangleBvh::Box path;
  path.grow(y0);
  path.grow(Vec3(y0 + dy));
  path.lo.array() -= target;
  path.hi.array() += target;
  m.bvh.overlapping(path, [&](int t) {
    alpha = std::min(alpha, triangle_crossing(m, t, y0, dy, target, alpha));
  });
  return alpha;
}

}  // namespace

double step_bound(const Model& model, const Points& x0, const Points& x1, double t0, double t1,
                  const std::vector<Contact>& pair_candidates, double slack) {
  double alpha = 1.0;
  const double keep = 1.0 - slack;  // the fraction of each starting gap that must remain
  const int n = model.particle_count();
  for (int i = 0; i < n; ++i) {
    if (model.inv_mass[static_cast<size_t>(i)] <= 0.0) continue;
    const Vec3 a0 = x0.row(i).transpose();
    const Vec3 a1 = x1.row(i).transpose();
    const Vec3 da = a1 - a0;
    const double r = model.radius[static_cast<size_t>(i)];
    for (const PlaneCollider& p : model.planes) {
      const double nn = p.normal.norm();
      const double d0 = (p.normal.dot(a0) + p.offset) / nn - r;
      const double dd = p.normal.dot(da) / nn;
      if (dd < 0.0 && d0 > 0.0) alpha = std::min(alpha, slack * d0 / -dd);  // d0 + alpha dd = keep d0
    }
    for (const SphereCollider& s : model.spheres) {
      const Vec3 c0 = sphere_center(model, s, t0), c1 = sphere_center(model, s, t1);
      const Vec3 p = a0 - c0, q = da - (c1 - c0);
      if (s.side == SphereSide::Outside) {
        const double d0 = p.norm() - (s.radius + r);
        if (d0 <= 0.0) continue;
        alpha = std::min(alpha, radial_crossing(p, q, s.radius + r + keep * d0, true));
      } else {
        if (s.side == SphereSide::Bowl && !below_centre(model, a0, c0) &&
            !below_centre(model, a1, c1))
          continue;
        const double d0 = (s.radius - r) - p.norm();
        if (d0 <= 0.0) continue;
        alpha = std::min(alpha, radial_crossing(p, q, s.radius - r - keep * d0, false));
      }
    }
  }
  for (const MeshCollider& m : model.meshes)
    for (int i = 0; i < n; ++i) {
      if (model.inv_mass[static_cast<size_t>(i)] <= 0.0) continue;
      const Vec3 a0 = x0.row(i).transpose();
      const Vec3 da = x1.row(i).transpose() - a0;
      alpha = mesh_step_bound(model, m, a0, da, model.radius[static_cast<size_t>(i)], t0, t1,
                              keep, alpha);
    }
  for (const Contact& c : pair_candidates) {
    if (c.kind != ContactKind::Particle) continue;
    const Vec3 p = (x0.row(c.a) - x0.row(c.b)).transpose();
    const Vec3 q = (x1.row(c.a) - x1.row(c.b)).transpose() - p;
    const double R = model.radius[static_cast<size_t>(c.a)] + model.radius[static_cast<size_t>(c.b)];
    const double d0 = p.norm() - R;
    if (d0 <= 0.0) continue;
    alpha = std::min(alpha, radial_crossing(p, q, R + keep * d0, true));
  }
  return alpha;
}

}  // namespace pbdbench::barrier
