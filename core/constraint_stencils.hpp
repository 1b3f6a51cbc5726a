// The constraint functions C(x) and their gradients, written once for every scalar: inline
// templates over a lane type L (core/lanes.hpp: double, float, or a pack of them with one
// constraint per lane). core/constraint_functions.cpp evaluates them in double for the metrics,
// the references and the per-item projection path; the compiled projection kernels of solvers/
// call the same templates in the precision of the run.
//
// A stencil is the constraint's particles x0..x3 (the first arity(kind) of them); every template
// returns C, the gradient dC/dx_i of each particle, and `valid`, false where the gradient is
// undefined (C is still reported). The definitions of C are those of core/model.hpp.
#pragma once

#include <array>
#include <numbers>
#include <type_traits>

#include "core/lanes.hpp"

namespace pbdbench {

// A 3-vector of lanes.
template <class L>
struct V3 {
  L x, y, z;
};

template <class L>
PBDBENCH_INLINE V3<L> operator+(const V3<L>& a, const V3<L>& b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
template <class L>
PBDBENCH_INLINE V3<L> operator-(const V3<L>& a, const V3<L>& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
template <class L>
PBDBENCH_INLINE V3<L> operator-(const V3<L>& a) {
  return {-a.x, -a.y, -a.z};
}
template <class L>
PBDBENCH_INLINE V3<L> operator*(const L& s, const V3<L>& a) {
  return {s * a.x, s * a.y, s * a.z};
}
template <class L>
PBDBENCH_INLINE L dot(const V3<L>& a, const V3<L>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
template <class L>
PBDBENCH_INLINE V3<L> cross(const V3<L>& a, const V3<L>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <class L>
PBDBENCH_INLINE V3<L> select3(const LaneMask<L>& m, const V3<L>& a, const V3<L>& b) {
  return {lane_select(m, a.x, b.x), lane_select(m, a.y, b.y), lane_select(m, a.z, b.z)};
}

template <class L>
struct StencilEval {
  L C;                      // constraint value, units of the kind
  std::array<V3<L>, 4> grad;  // dC/dx_i for the first arity entries
  LaneMask<L> valid;        // gradient defined
};

// The angle atan2(s, c) in [0, pi] of a direction with s >= 0, to a few ulps, from arithmetic
// alone (no libm call: the same bits everywhere, and in any lane). 0 when s = c = 0.
// The direction is folded into the octant 0 <= num <= den (num/den = s/|c| or its inverse), then
// turned by phi in {0, atan(t8), pi/4} (t8 = tan(pi/8) rounded, phi its exact arctangent) so that
// u = tan(theta - phi) = (num - t den) / (den + t num) has |u| <= tan(pi/16) = 0.199, where
// atan u = u - u^3/3 + u^5/5 - ... : its terms up to u^21 (double) or u^9 (float) leave a
// truncation error below 4e-18 (double) or 2e-9 (float).
template <class L>
PBDBENCH_INLINE L angle_from_sin_cos(const L& s, const L& c) {
  using S = LaneScalar<L>;
  constexpr bool single = std::is_same_v<S, float>;
  constexpr S kTan1 = S(0.19891236737965800691);  // tan(pi/16)
  constexpr S kTan3 = S(0.66817863791929891999);  // tan(3 pi/16)
  constexpr S kTan8 = S(0.41421356237309504880);  // tan(pi/8), rounded to S
  // atan(kTan8) of the rounded constant, to the precision of S.
  constexpr S kAtan8 = single ? S(0.39269909262657166) : S(0.39269908169872414);
  constexpr S kPi = std::numbers::pi_v<S>;
  const L zero = lane_splat<L>(S(0));
  const L one = lane_splat<L>(S(1));
  const L ac = lane_abs(c);
  const LaneMask<L> swap = s > ac;
  const L num = lane_select(swap, ac, s);
  L den = lane_select(swap, s, ac);
  den = lane_select(den > zero, den, one);  // s = c = 0: u = 0, the angle 0
  const LaneMask<L> high = num > lane_splat<L>(kTan3) * den;
  const LaneMask<L> mid = lane_and(num > lane_splat<L>(kTan1) * den, lane_not(high));
  const L t = lane_select(high, one, lane_select(mid, lane_splat<L>(kTan8), zero));
  const L base = lane_select(high, lane_splat<L>(kPi / S(4)), lane_select(mid, lane_splat<L>(kAtan8), zero));
  const L u = (num - t * den) / (den + t * num);
  const L z = u * u;
  // atan u = u + u z p(z), p(z) = sum_k (-1)^k z^(k-1) / (2k + 1), k = 1..n, by Estrin's scheme (pairs, then pairs
  // of pairs): a short dependency chain where Horner's would be n multiply-adds long.
  const auto term = [](int k) { return lane_splat<L>(S(k % 2 ? -1 : 1) / S(2 * k + 1)); };
  const L z2 = z * z;
  L p;
  if constexpr (single) {
    p = (term(1) + z * term(2)) + z2 * (term(3) + z * term(4));
  } else {
    const L z4 = z2 * z2;
    const L z8 = z4 * z4;
    const L p01 = term(1) + z * term(2), p23 = term(3) + z * term(4), p45 = term(5) + z * term(6),
            p67 = term(7) + z * term(8), p89 = term(9) + z * term(10);
    p = ((p01 + z2 * p23) + z4 * (p45 + z2 * p67)) + z8 * p89;
  }
  L a = base + (u + u * (z * p));                                   // in [0, pi/4]
  a = lane_select(swap, lane_splat<L>(kPi / S(2)) - a, a);           // in [0, pi/2]
  return lane_select(c < zero, lane_splat<L>(kPi) - a, a);           // in [0, pi]
}

// Distance: C = |x1 - x0| - rest; grad_1 = -grad_0 = (x1 - x0) / |x1 - x0|, undefined at 0.
template <class L>
PBDBENCH_INLINE StencilEval<L> distance_stencil(const V3<L>& x0, const V3<L>& x1, const L& rest) {
  const V3<L> d = x1 - x0;
  const L len = lane_sqrt(dot(d, d));
  const L zero = lane_splat<L>(LaneScalar<L>(0));
  StencilEval<L> e;
  e.C = len - rest;
  e.valid = len > zero;
  const L safe = lane_select(e.valid, len, lane_splat<L>(LaneScalar<L>(1)));
  e.grad[1] = select3<L>(e.valid, V3<L>{d.x / safe, d.y / safe, d.z / safe}, V3<L>{zero, zero, zero});
  e.grad[0] = -e.grad[1];
  e.grad[2] = e.grad[3] = V3<L>{zero, zero, zero};
  return e;
}

// Volume: C = (1/6) (x1-x0) . ((x2-x0) x (x3-x0)) - rest;
// grad_1 = (1/6) e2 x e3, grad_2 = (1/6) e3 x e1, grad_3 = (1/6) e1 x e2, grad_0 = -(their sum);
// undefined when every gradient vanishes.
template <class L>
PBDBENCH_INLINE StencilEval<L> volume_stencil(const V3<L>& x0, const V3<L>& x1, const V3<L>& x2,
                                     const V3<L>& x3, const L& rest) {
  using S = LaneScalar<L>;
  const V3<L> e1 = x1 - x0, e2 = x2 - x0, e3 = x3 - x0;
  const L six = lane_splat<L>(S(6));
  const auto over6 = [&](const V3<L>& v) { return V3<L>{v.x / six, v.y / six, v.z / six}; };
  StencilEval<L> e;
  const V3<L> c23 = cross(e2, e3);
  e.C = dot(e1, c23) / six - rest;
  e.grad[1] = over6(c23);
  e.grad[2] = over6(cross(e3, e1));
  e.grad[3] = over6(cross(e1, e2));
  e.grad[0] = -(e.grad[1] + e.grad[2] + e.grad[3]);
  const L sum = dot(e.grad[0], e.grad[0]) + dot(e.grad[1], e.grad[1]) +
                dot(e.grad[2], e.grad[2]) + dot(e.grad[3], e.grad[3]);
  e.valid = sum > lane_splat<L>(S(0));
  return e;
}

// Bending (Mueller et al. 2007, sec. 4.2): C = theta - rest, theta = acos(n1 . n2) in [0, pi] the
// angle between n1 = unit(e x a) and n2 = unit(e x b), e = x1 - x0 (the shared edge), a = x2 - x0,
// b = x3 - x0 (the wings). Without acos: with c1 = e x a, c2 = e x b and V = c1 . b (six times the
// signed volume of the tet x0..x3), c1 x c2 = V e, so theta = atan2(|e| |V|, c1 . c2).
// The gradient, with sigma = sign(V): grad_2 = -sigma |e| c1 / |c1|^2, grad_3 = sigma |e| c2 / |c2|^2
// (a wing turns about the edge by its displacement over its height |c_k| / |e|), and for the edge
// grad_1 = -(s2 grad_2 + s3 grad_3), grad_0 = -(grad_1 + grad_2 + grad_3), s2 = a.e / |e|^2 and
// s3 = b.e / |e|^2 the positions of the wings' feet along the edge. It is undefined (valid = false)
// at theta = 0 or pi, where the angle has a kink: sin^2 theta < 1e-12 (sin theta = |e||V| /
// (|c1||c2|)); and where a triangle is degenerate (|c1| or |c2| = 0), with C = -rest (the angle
// taken as 0).
template <class L>
PBDBENCH_INLINE StencilEval<L> bending_stencil(const V3<L>& x0, const V3<L>& x1, const V3<L>& x2,
                                      const V3<L>& x3, const L& rest) {
  using S = LaneScalar<L>;
  const L zero = lane_splat<L>(S(0));
  const L one = lane_splat<L>(S(1));
  const V3<L> e = x1 - x0, a = x2 - x0, b = x3 - x0;
  const V3<L> c1 = cross(e, a), c2 = cross(e, b);
  const L q1 = dot(c1, c1), q2 = dot(c2, c2), ee = dot(e, e);
  const L el = lane_sqrt(ee);
  const L V = dot(c1, b);
  const L sin_scaled = el * lane_abs(V);  // |c1| |c2| sin theta
  const L cos_scaled = dot(c1, c2);       // |c1| |c2| cos theta
  const LaneMask<L> triangles = lane_and(q1 > zero, q2 > zero);
  StencilEval<L> out;
  out.C = lane_select(triangles, angle_from_sin_cos(sin_scaled, cos_scaled), zero) - rest;
  // sin^2 theta >= 1e-12, i.e. (|e| |V|)^2 >= 1e-12 q1 q2.
  out.valid = lane_and(triangles, lane_not(sin_scaled * sin_scaled < lane_splat<L>(S(1e-12)) * (q1 * q2)));
  const L sigma = lane_select(V < zero, -one, one);
  const L q1s = lane_select(triangles, q1, one), q2s = lane_select(triangles, q2, one);
  const L ees = lane_select(ee > zero, ee, one);
  // |e| / |c1|^2 and |e| / |c2|^2 from one division (q1 q2 ~ |e|^4 |a|^2 |b|^2 stays a normal
  // number for edges above 1e-60 m in double, 1e-5 m in float).
  const L r = (sigma * el) / (q1s * q2s);
  const V3<L> g2 = (-(r * q2s)) * c1;
  const V3<L> g3 = (r * q1s) * c2;
  const L inv_ee = one / ees;
  const L s2 = dot(a, e) * inv_ee, s3 = dot(b, e) * inv_ee;
  const V3<L> g1 = -(s2 * g2 + s3 * g3);
  const V3<L> g0 = -(g1 + g2 + g3);
  const V3<L> z{zero, zero, zero};
  out.grad[0] = select3<L>(out.valid, g0, z);
  out.grad[1] = select3<L>(out.valid, g1, z);
  out.grad[2] = select3<L>(out.valid, g2, z);
  out.grad[3] = select3<L>(out.valid, g3, z);
  return out;
}

// F = Ds Dm^-1 of a tet, Ds = [x1-x0, x2-x0, x3-x0]: its columns f0, f1, f2. `dm` is Dm^-1 by
// rows: dm[3 r + c] = (Dm^-1)_rc.
template <class L>
PBDBENCH_INLINE std::array<V3<L>, 3> deformation_columns(const V3<L>& x0, const V3<L>& x1, const V3<L>& x2,
                                                const V3<L>& x3, const L* dm) {
  const V3<L> d0 = x1 - x0, d1 = x2 - x0, d2 = x3 - x0;
  std::array<V3<L>, 3> f;
  for (int c = 0; c < 3; ++c)
    f[static_cast<size_t>(c)] = dm[c] * d0 + dm[3 + c] * d1 + dm[6 + c] * d2;
  return f;
}

// The vertex gradients of C(F) from G = dC/dF (by columns g0, g1, g2): grad_{k+1} = column k of
// G Dm^-T, i.e. sum_c g_c (Dm^-1)_kc; grad_0 = -(the sum of the other three).
template <class L>
PBDBENCH_INLINE void vertex_gradients(const std::array<V3<L>, 3>& g, const L* dm, StencilEval<L>& out) {
  for (int k = 0; k < 3; ++k)
    out.grad[static_cast<size_t>(k) + 1] = dm[3 * k] * g[0] + dm[3 * k + 1] * g[1] + dm[3 * k + 2] * g[2];
  out.grad[0] = -(out.grad[1] + out.grad[2] + out.grad[3]);
}

// The deviatoric constraint of a stable neo-Hookean element (Macklin and Mueller 2021):
// C = sqrt(tr F^T F) - rest, dC/dF = F / |F|, undefined at F = 0.
template <class L>
PBDBENCH_INLINE StencilEval<L> fem_deviatoric_stencil(const V3<L>& x0, const V3<L>& x1, const V3<L>& x2,
                                             const V3<L>& x3, const L* dm, const L& rest) {
  using S = LaneScalar<L>;
  const std::array<V3<L>, 3> f = deformation_columns(x0, x1, x2, x3, dm);
  const L norm = lane_sqrt(dot(f[0], f[0]) + dot(f[1], f[1]) + dot(f[2], f[2]));
  StencilEval<L> out;
  out.C = norm - rest;
  out.valid = norm > lane_splat<L>(S(0));
  const L inv = lane_splat<L>(S(1)) / lane_select(out.valid, norm, lane_splat<L>(S(1)));
  vertex_gradients<L>({inv * f[0], inv * f[1], inv * f[2]}, dm, out);
  return out;
}

// The hydrostatic constraint: C = det F - rest, dC/dF = cof F = [f1 x f2, f2 x f0, f0 x f1];
// undefined when every gradient vanishes.
template <class L>
PBDBENCH_INLINE StencilEval<L> fem_hydrostatic_stencil(const V3<L>& x0, const V3<L>& x1, const V3<L>& x2,
                                              const V3<L>& x3, const L* dm, const L& rest) {
  using S = LaneScalar<L>;
  const std::array<V3<L>, 3> f = deformation_columns(x0, x1, x2, x3, dm);
  const V3<L> c0 = cross(f[1], f[2]);
  StencilEval<L> out;
  out.C = dot(f[0], c0) - rest;
  vertex_gradients<L>({c0, cross(f[2], f[0]), cross(f[0], f[1])}, dm, out);
  const L sum = dot(out.grad[0], out.grad[0]) + dot(out.grad[1], out.grad[1]) +
                dot(out.grad[2], out.grad[2]) + dot(out.grad[3], out.grad[3]);
  out.valid = sum > lane_splat<L>(S(0));
  return out;
}

}  // namespace pbdbench
