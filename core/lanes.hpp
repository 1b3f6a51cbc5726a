// Lanes: the arithmetic that the constraint stencils (core/constraint_stencils.hpp) are written
// in, so that one definition serves a double, a float, and a pack of either (core/simd.hpp,
// one constraint per lane). A lane type L has +, -, *, / and comparisons, and these functions:
//
//   lane_sqrt(a), lane_abs(a)          correctly rounded, as std::sqrt and std::fabs
//   lane_select(m, a, b)               a where the mask m is set, else b
//   lane_and(m, n), lane_not(m)        masks
//   LaneScalar<L>                      the scalar of a lane: double or float
//
// Every operation is an IEEE operation on each lane: a stencil gives the same bits whether it
// runs on a scalar or in any lane of a pack (the build has -ffp-contract=off, so nothing is fused).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>

// On the functions of the projection's inner loops: inlined whatever the compiler's size
// heuristics say, so that a kernel is one straight-line loop body (and so that the instruction-set
// files of solvers/projection_wide.hpp emit no out-of-line copy of a shared function).
#define PBDBENCH_INLINE inline __attribute__((always_inline))
// The same on a lambda (after its parameter list).
#define PBDBENCH_INLINE_LAMBDA __attribute__((always_inline))

namespace pbdbench {

template <class L>
struct LaneTraits {
  using Scalar = L;
  using Mask = bool;
};

template <class L>
using LaneScalar = typename LaneTraits<L>::Scalar;
template <class L>
using LaneMask = typename LaneTraits<L>::Mask;

inline double lane_sqrt(double a) { return std::sqrt(a); }
inline float lane_sqrt(float a) { return std::sqrt(a); }
inline double lane_abs(double a) { return std::fabs(a); }
inline float lane_abs(float a) { return std::fabs(a); }
// Without a branch: the stencils select on data (the octant of an angle), which a branch would
// mispredict at random.
inline double lane_select(bool m, double a, double b) {
  std::uint64_t x, y;
  std::memcpy(&x, &a, sizeof x);
  std::memcpy(&y, &b, sizeof y);
  const std::uint64_t mask = -static_cast<std::uint64_t>(m);
  const std::uint64_t r = (x & mask) | (y & ~mask);
  double out;
  std::memcpy(&out, &r, sizeof out);
  return out;
}
inline float lane_select(bool m, float a, float b) {
  std::uint32_t x, y;
  std::memcpy(&x, &a, sizeof x);
  std::memcpy(&y, &b, sizeof y);
  const std::uint32_t mask = -static_cast<std::uint32_t>(m);
  const std::uint32_t r = (x & mask) | (y & ~mask);
  float out;
  std::memcpy(&out, &r, sizeof out);
  return out;
}
inline bool lane_and(bool m, bool n) { return m & n; }
inline bool lane_not(bool m) { return !m; }
// The lanes of a mask as bits (lane i at bit i): a scalar has one.
inline int lane_bits(bool m) { return m ? 1 : 0; }

// A lane holding the scalar v in every lane.
template <class L>
inline L lane_splat(LaneScalar<L> v) {
  return L(v);
}

}  // namespace pbdbench
