// Distances between surface primitives, their derivatives, conservative CCD. proximity.hpp.
#include "core/proximity.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>

#include "core/bvh.hpp"

namespace pbdbench::proximity {

namespace {

// Second-order forward-mode differentiation over the 12 coordinates: a value with its gradient
// and Hessian, carried exactly through +, -, *, and smooth functions of one argument.
struct D {
  double v = 0.0;
  Vec12 g = Vec12::Zero();
  Mat12 H = Mat12::Zero();
};

D variable(double v, int i) {
  D d;
  d.v = v;
  d.g[i] = 1.0;
  return d;
}

D operator+(const D& a, const D& b) {
  D r;
  r.v = a.v + b.v;
  r.g = a.g + b.g;
  r.H = a.H + b.H;
  return r;
}

D operator-(const D& a, const D& b) {
  D r;
  r.v = a.v - b.v;
  r.g = a.g - b.g;
  r.H = a.H - b.H;
  return r;
}

D operator*(const D& a, const D& b) {
  D r;
  r.v = a.v * b.v;
  r.g = b.v * a.g + a.v * b.g;
  const Mat12 outer = a.g * b.g.transpose();
  r.H = b.v * a.H + a.v * b.H + outer + outer.transpose();
  return r;
}

// f(a) with f, f', f'' at a.v.
D chain(const D& a, double f, double f1, double f2) {
  D r;
  r.v = f;
  r.g = f1 * a.g;
  r.H = f1 * a.H + f2 * a.g * a.g.transpose();
  return r;
}

D reciprocal(const D& a) {
  const double v = a.v;
  return chain(a, 1.0 / v, -1.0 / (v * v), 2.0 / (v * v * v));
}

D square_root(const D& a) {
  const double s = std::sqrt(a.v);
  return chain(a, s, 0.5 / s, -0.25 / (s * a.v));
}

struct D3 {
  D x, y, z;
};

D3 point(const std::array<Vec3, 4>& x, int k) {
  return {variable(x[static_cast<size_t>(k)][0], 3 * k), variable(x[static_cast<size_t>(k)][1], 3 * k + 1),
          variable(x[static_cast<size_t>(k)][2], 3 * k + 2)};
}

D3 operator-(const D3& a, const D3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
D dot(const D3& a, const D3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
D3 cross(const D3& a, const D3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

// Squared distances of the primitive pieces, over the variables of x.
D point_point2(const std::array<Vec3, 4>& x, int i, int j) {
  const D3 u = point(x, i) - point(x, j);
  return dot(u, u);
}

D point_line2(const std::array<Vec3, 4>& x, int p, int a, int b) {
  const D3 e = point(x, b) - point(x, a);
  const D3 c = cross(point(x, p) - point(x, a), e);
  return dot(c, c) * reciprocal(dot(e, e));
}

D point_plane2(const std::array<Vec3, 4>& x, int p, int a, int b, int c) {
  const D3 pa = point(x, a);
  const D3 n = cross(point(x, b) - pa, point(x, c) - pa);
  const D s = dot(point(x, p) - pa, n);
  return s * s * reciprocal(dot(n, n));
}

D line_line2(const std::array<Vec3, 4>& x) {
  const D3 a0 = point(x, 0), b0 = point(x, 2);
  const D3 n = cross(point(x, 1) - a0, point(x, 3) - b0);
  const D s = dot(a0 - b0, n);
  return s * s * reciprocal(dot(n, n));
}

Distance finish(const D& d2, int type) {
  Distance out;
  out.type = type;
  out.d = std::sqrt(std::max(d2.v, 0.0));
  if (!(d2.v > 0.0)) return out;  // derivatives undefined at 0
  const D d = square_root(d2);
  out.grad = d.g;
  out.hess = d.H;
  return out;
}

// Closest parameters s (on a) and t (on b) of two segments, with the type.
struct SegmentPair {
  double s = 0.0, t = 0.0;
  EdgeEdgeType type = EdgeEdgeType::EA_EB;
};

double clamp01(double v) { return std::min(1.0, std::max(0.0, v)); }

// Parameter of the point of segment (a, b) closest to p.
double segment_parameter(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 e = b - a;
  const double ee = e.squaredNorm();
  return ee > 0.0 ? clamp01((p - a).dot(e) / ee) : 0.0;
}

SegmentPair closest_segments(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  const Vec3 d1 = a1 - a0, d2 = b1 - b0, r = a0 - b0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm();
  const double b = d1.dot(d2), c = d1.dot(r), f = d2.dot(r);
  SegmentPair out;
  const double cross2 = d1.cross(d2).squaredNorm();
  if (cross2 <= 1e-20 * a * e) {
    // Parallel (or degenerate): the nearest endpoint against the other segment.
    struct Candidate {
      double dist, s, t;
    };
    const double tb0 = segment_parameter(a0, b0, b1), tb1 = segment_parameter(a1, b0, b1);
    const double sa0 = segment_parameter(b0, a0, a1), sa1 = segment_parameter(b1, a0, a1);
    const Candidate cands[4] = {
        {(a0 - (b0 + tb0 * d2)).squaredNorm(), 0.0, tb0},
        {(a1 - (b0 + tb1 * d2)).squaredNorm(), 1.0, tb1},
        {(b0 - (a0 + sa0 * d1)).squaredNorm(), sa0, 0.0},
        {(b1 - (a0 + sa1 * d1)).squaredNorm(), sa1, 1.0},
    };
    int best = 0;
    for (int k = 1; k < 4; ++k)
      if (cands[k].dist < cands[best].dist) best = k;
    out.s = cands[best].s;
    out.t = cands[best].t;
  } else {
    const double denom = a * e - b * b;
    double s = denom > 0.0 ? clamp01((b * f - c * e) / denom) : 0.0;
    double t = (b * s + f) / e;
    if (t < 0.0) {
      t = 0.0;
      s = clamp01(-c / a);
    } else if (t > 1.0) {
      t = 1.0;
      s = clamp01((b - c) / a);
    }
    out.s = s;
    out.t = t;
  }
  const bool s_end = out.s == 0.0 || out.s == 1.0, t_end = out.t == 0.0 || out.t == 1.0;
  if (!s_end && !t_end) {
    out.type = EdgeEdgeType::EA_EB;
  } else if (s_end && !t_end) {
    out.type = out.s == 0.0 ? EdgeEdgeType::EA0_EB : EdgeEdgeType::EA1_EB;
  } else if (!s_end && t_end) {
    out.type = out.t == 0.0 ? EdgeEdgeType::EA_EB0 : EdgeEdgeType::EA_EB1;
  } else if (out.s == 0.0) {
    out.type = out.t == 0.0 ? EdgeEdgeType::EA0_EB0 : EdgeEdgeType::EA0_EB1;
  } else {
    out.type = out.t == 0.0 ? EdgeEdgeType::EA1_EB0 : EdgeEdgeType::EA1_EB1;
  }
  return out;
}

}  // namespace

PointTriangleType point_triangle_type(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  Vec3 bary;
  closest_point_on_triangle(p, a, b, c, &bary);
  // Ericson's regions give exact zeros for the coordinates off the closest feature.
  const bool u = bary[0] != 0.0, v = bary[1] != 0.0, w = bary[2] != 0.0;
  if (u && v && w) return PointTriangleType::P_T;
  if (u && v) return PointTriangleType::P_E01;
  if (v && w) return PointTriangleType::P_E12;
  if (w && u) return PointTriangleType::P_E20;
  if (v) return PointTriangleType::P_T1;
  if (w) return PointTriangleType::P_T2;
  return PointTriangleType::P_T0;
}

EdgeEdgeType edge_edge_type(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  return closest_segments(a0, a1, b0, b1).type;
}

void edge_edge_closest(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, double& s,
                       double& t) {
  const SegmentPair sp = closest_segments(a0, a1, b0, b1);
  s = sp.s;
  t = sp.t;
}

double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  return (p - closest_point_on_triangle(p, a, b, c)).norm();
}

double edge_edge_distance(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  const SegmentPair sp = closest_segments(a0, a1, b0, b1);
  return ((a0 + sp.s * (a1 - a0)) - (b0 + sp.t * (b1 - b0))).norm();
}

Distance point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                        PointTriangleType type) {
  const std::array<Vec3, 4> x = {p, a, b, c};
  switch (type) {
    case PointTriangleType::P_T0: return finish(point_point2(x, 0, 1), static_cast<int>(type));
    case PointTriangleType::P_T1: return finish(point_point2(x, 0, 2), static_cast<int>(type));
    case PointTriangleType::P_T2: return finish(point_point2(x, 0, 3), static_cast<int>(type));
    case PointTriangleType::P_E01: return finish(point_line2(x, 0, 1, 2), static_cast<int>(type));
    case PointTriangleType::P_E12: return finish(point_line2(x, 0, 2, 3), static_cast<int>(type));
    case PointTriangleType::P_E20: return finish(point_line2(x, 0, 3, 1), static_cast<int>(type));
    case PointTriangleType::P_T: return finish(point_plane2(x, 0, 1, 2, 3), static_cast<int>(type));
  }
  throw std::logic_error("point_triangle: unknown distance type");
}

Distance point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  return point_triangle(p, a, b, c, point_triangle_type(p, a, b, c));
}

Distance edge_edge(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1,
                   EdgeEdgeType type) {
  const std::array<Vec3, 4> x = {a0, a1, b0, b1};
  const int t = static_cast<int>(type);
  switch (type) {
    case EdgeEdgeType::EA0_EB0: return finish(point_point2(x, 0, 2), t);
    case EdgeEdgeType::EA0_EB1: return finish(point_point2(x, 0, 3), t);
    case EdgeEdgeType::EA1_EB0: return finish(point_point2(x, 1, 2), t);
    case EdgeEdgeType::EA1_EB1: return finish(point_point2(x, 1, 3), t);
    case EdgeEdgeType::EA_EB0: return finish(point_line2(x, 2, 0, 1), t);
    case EdgeEdgeType::EA_EB1: return finish(point_line2(x, 3, 0, 1), t);
    case EdgeEdgeType::EA0_EB: return finish(point_line2(x, 0, 2, 3), t);
    case EdgeEdgeType::EA1_EB: return finish(point_line2(x, 1, 2, 3), t);
    case EdgeEdgeType::EA_EB: return finish(line_line2(x), t);
  }
  throw std::logic_error("edge_edge: unknown distance type");
}

Distance edge_edge(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  return edge_edge(a0, a1, b0, b1, edge_edge_type(a0, a1, b0, b1));
}

double mollifier_threshold(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  return 1e-3 * (a1 - a0).squaredNorm() * (b1 - b0).squaredNorm();
}

Mollifier edge_edge_mollifier(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1,
                              double eps_x) {
  Mollifier out;
  const double c_value = (a1 - a0).cross(b1 - b0).squaredNorm();
  if (c_value >= eps_x) return out;  // 1, derivatives 0
  const std::array<Vec3, 4> x = {a0, a1, b0, b1};
  const D3 n = cross(point(x, 1) - point(x, 0), point(x, 3) - point(x, 2));
  const D c = dot(n, n);
  const double e = eps_x;
  const D m = chain(c, -c.v * c.v / (e * e) + 2.0 * c.v / e, -2.0 * c.v / (e * e) + 2.0 / e,
                    -2.0 / (e * e));
  out.value = m.v;
  out.grad = m.g;
  out.hess = m.H;
  return out;
}

namespace {

double pair_distance(PairKind kind, const std::array<Vec3, 4>& x) {
  return kind == PairKind::PointTriangle ? point_triangle_distance(x[0], x[1], x[2], x[3])
                                         : edge_edge_distance(x[0], x[1], x[2], x[3]);
}

}  // namespace

CcdResult conservative_ccd(PairKind kind, const std::array<Vec3, 4>& x0,
                           const std::array<Vec3, 4>& dx, double thickness, double keep,
                           double limit, int max_iterations) {
  CcdResult out;
  const double g0 = pair_distance(kind, x0) - thickness;
  if (!(g0 > 0.0))
    throw std::invalid_argument("conservative_ccd: the pair starts with a gap <= 0");
  if (!(keep > 0.0 && keep < 1.0)) throw std::invalid_argument("conservative_ccd: keep not in (0, 1)");
  const Vec3 mean = 0.25 * (dx[0] + dx[1] + dx[2] + dx[3]);
  double n[4];
  for (int i = 0; i < 4; ++i) n[i] = (dx[static_cast<size_t>(i)] - mean).norm();
  const double L = kind == PairKind::PointTriangle
                       ? n[0] + std::max({n[1], n[2], n[3]})
                       : std::max(n[0], n[1]) + std::max(n[2], n[3]);
  if (!(L > 0.0)) {  // a common translation (or no motion): the gap does not change
    out.alpha = limit;
    return out;
  }
  const double floor = keep * g0;
  double s = 0.0, g = g0;
  std::array<Vec3, 4> x;
  for (;;) {
    const double advance = 0.9 * (g - floor) / L;
    if (s + advance >= limit) {
      out.alpha = limit;
      return out;
    }
    s += advance;
    ++out.iterations;
    for (size_t i = 0; i < 4; ++i) x[i] = x0[i] + s * dx[i];
    g = pair_distance(kind, x) - thickness;
    if (g <= 2.0 * floor || out.iterations >= max_iterations) {
      out.alpha = s;
      return out;
    }
  }
}

}  // namespace pbdbench::proximity
