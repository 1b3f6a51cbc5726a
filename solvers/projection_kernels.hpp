// The straight-line projection kernels of the compiled path (solvers/compiled_projection.hpp):
// one inline function per (rule, kind) that projects the items [begin, end) of a block of one
// kind on positions P (kStride scalars a particle), W::kWidth items at a time in the lanes of a
// pack W (core/simd.hpp; the items of a batch share no moving particle), the last pack partial.
// No per-projection temporaries beyond registers, no calls, no branches on the kind. What each
// computes is what the per-item kernels of solvers/kernels.hpp compute (the reference
// implementation, compared with these in tests/solvers/test_compiled_projection.cpp), with the
// constant parts of the denominators precomputed at setup and each particle's inverse mass w read
// with its coordinates (the fourth scalar of its row of P: one gather brings both, and a distance
// item streams 16 bytes fewer than with arrays of w per item):
//
//   pbd, distance:  d = x1 - x0, f = (|d| - rest) / |d|, x0 += a0 f d, x1 -= a1 f d,
//                   a_i = k w_i / (w0 + w1)                      (Mueller et al. 2007, sec. 3.3)
//   pbd, other:     s = k C / sum_i w_i |grad_i C|^2, x_i -= s w_i grad_i C
//   xpbd, distance: n = d / |d|, dlambda = (-C - alpha~ lambda - gamma n . (dx1 - dx0)) / D,
//                   D = (1 + gamma)(w0 + w1) + alpha~ (its inverse precomputed per h),
//                   lambda += dlambda, x0 -= w0 dlambda n, x1 += w1 dlambda n
//   xpbd, other:    dlambda = (-C - alpha~ lambda - gamma sum_i grad_i C . dx_i)
//                             / ((1 + gamma) sum_i w_i |grad_i C|^2 + alpha~)
//                                                            (Macklin et al. 2016, eq. 26)
// with dx_i = x_i - x_n,i the motion since the start of the substep. An item whose gradient is
// undefined or whose denominator is not positive is skipped and counted. A particle with w = 0
// is never written (the items that have one are in "anchored" batches, whose kernels test). A lane
// computes the bits the one-by-one code computes: every operation is the same IEEE operation.
#pragma once

#include <array>
#include <cstdint>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/constraint_kind.hpp"
#include "core/constraint_stencils.hpp"
#include "core/simd.hpp"

namespace pbdbench {

inline constexpr int kStride = 4;  // scalars per particle in a positions array: x, y, z and the
                                   // inverse mass w (1/kg), so that a particle is one 4-vector and
                                   // a kernel has its w with its coordinates

// Which projection the sweeps apply.
enum class ProjectionRule : std::uint8_t {
  Pbd,   // Mueller et al. 2007: stiffness k (k' with solver.pbd.stiffness_correction), no multipliers
  Xpbd,  // Macklin et al. 2016, eq. 26: compliance, damping, multipliers
};

// The items of one constraint kind, struct of arrays (one array per field, indexed by the slot),
// in the order the schedule visits them. Coefficients per item depend on the rule:
//   pbd  distance: coef[0] = a0, coef[1] = a1        pbd  other: coef[0] = k
//   xpbd distance: alpha~, gamma, 1/D                xpbd other: alpha~, gamma
template <class T>
struct KindBlock {
  static constexpr int kCoefficients = 3;
  ConstraintKind kind = ConstraintKind::Distance;
  int arity = 0;
  int count = 0;
  std::array<std::vector<std::int32_t>, 4> offset;    // [i] (count): kStride x the i-th particle's
                                                      // index, where it starts in a positions array
  std::vector<T> rest;                                // (count) rest value, units of C
  std::array<std::vector<T>, kCoefficients> coef;     // [c] (count), see above
  std::array<std::vector<T>, 9> rest_inverse;         // [3 r + c] (count) FEM kinds: Dm^-1, 1/m
  std::vector<T> lambda;                              // (count) xpbd: multiplier of the substep
  std::vector<std::int32_t> item;                     // (count) the model constraint
  std::vector<double> stiffness;                      // (count) pbd: k (or k'), as compiled
  std::vector<double> compliance;                     // (count) xpbd: alpha
  std::vector<double> damping;                        // (count) xpbd: beta
  std::vector<double> rest_double;                    // (count) the rest values in double, and
  std::array<std::vector<double>, 9> rest_inverse_double;  // Dm^-1: for the xpbd residuals
};

template <class T>
inline V3<T> load3(const T* P, std::int32_t p) {
  const T* q = P + static_cast<std::ptrdiff_t>(kStride) * p;
  return {q[0], q[1], q[2]};
}
template <class T>
inline void store3(T* P, std::int32_t p, const V3<T>& v) {
  T* q = P + static_cast<std::ptrdiff_t>(kStride) * p;
  q[0] = v.x;
  q[1] = v.y;
  q[2] = v.z;
}

// A block as the kernels read it: its arrays, no containers (the wide kernels of
// solvers/projection_wide.hpp take only this).
template <class T>
struct BlockView {
  const std::int32_t* offset[4] = {};  // kStride x particle index (KindBlock::offset)
  const T* rest = nullptr;
  const T* coef[KindBlock<T>::kCoefficients] = {};
  const T* rest_inverse[9] = {};
  T* lambda = nullptr;
};
template <class T>
inline BlockView<T> view(KindBlock<T>& b) {
  BlockView<T> v;
  for (int i = 0; i < 4; ++i) v.offset[i] = b.offset[static_cast<size_t>(i)].data();
  v.rest = b.rest.data();
  for (int c = 0; c < KindBlock<T>::kCoefficients; ++c) v.coef[c] = b.coef[static_cast<size_t>(c)].data();
  for (int k = 0; k < 9; ++k) v.rest_inverse[k] = b.rest_inverse[static_cast<size_t>(k)].data();
  v.lambda = b.lambda.data();
  return v;
}

// A run of items of one kind and one kernel variant: [begin, end) of the kind's block.
struct ChunkSpec {
  ProjectionRule rule = ProjectionRule::Pbd;
  ConstraintKind kind = ConstraintKind::Distance;
  bool anchored = false;  // some item has a particle with w = 0: tested before each write
  bool damped = false;    // xpbd: some item has damping != 0
  bool jacobi = false;    // corrections into JacobiBuffers instead of the positions
  int begin = 0, end = 0;
};

// Where a kernel's corrections go: straight into the positions (Gauss-Seidel orders), or, with
// Jacobi, into buffers applied after the sweep (solvers/compiled_projection.cpp): the correction
// of particle i of item s, component c, at dx[(3 i + c) count + s], the multiplier's change at
// dlambda[s]. A skipped item writes zeros there.
template <class T>
struct JacobiBuffers {
  T* dx = nullptr;       // (arity x 3 x count) m
  T* dlambda = nullptr;  // (count) xpbd
  int count = 0;         // items of the block
};

// ---------------------------------------------------------------------------------------------
// Lanes: the items s .. s + n - 1 in the lanes of a pack W. A full pack has n = W::kWidth; the
// last pack of a run may be partial (Partial): its lanes from n on repeat lane 0's item, so that
// they read only what lane 0 reads (nothing another thread may be writing), and nothing is
// written for them. Lane k of an array value is a[k]; of a position, the particle that starts at
// P + idx[k] (idx: a block's offsets, kStride x the particle's index).

template <class T, class W, bool Partial>
struct Lanes {
  static constexpr int kWidth = W::kWidth;
  using L = W;
  int n = kWidth;  // active lanes
  PBDBENCH_INLINE int lane(int k) const { return Partial && k >= n ? 0 : k; }
  PBDBENCH_INLINE int active() const { return Partial ? (1 << n) - 1 : (1 << kWidth) - 1; }
  PBDBENCH_INLINE L value(const T* a) const {
    L out;
    if constexpr (Partial) {
      for (int k = 0; k < kWidth; ++k) out.set(k, a[lane(k)]);
    } else {
      out = L::load(a);
    }
    return out;
  }
  PBDBENCH_INLINE void put(T* a, const L& v) const {
    if constexpr (Partial) {
      for (int k = 0; k < n; ++k) a[k] = v[k];
    } else {
      v.store(a);
    }
  }
  // A particle's coordinates move as whole vectors, transposed into x, y, z and w (and back for
  // the stores, w written as it was read; a pack whose lanes are all written stores without
  // testing each): in 4-lane double packs (AVX2) one 32-byte vector a particle;
  // in 2- and 8-lane double packs two 16-byte halves, (x, y) and (z, w), the even lanes' side by
  // side in one pack and the odd lanes' in another, then unpacked; in float packs one 16-byte
  // quarter (x, y, z, w), four lanes' quarters transposed in each 16-byte block of the pack.
  // Values one at a time would make every lane three loads and inserts. Only data moves: the same bits either way.
  static constexpr bool kWhole = std::is_same_v<T, double> && kWidth == 4;
  static constexpr bool kHalves = std::is_same_v<T, double> && (kWidth == 2 || kWidth == 8);
  static constexpr bool kQuarters = std::is_same_v<T, float> && (kWidth == 4 || kWidth == 8 || kWidth == 16);
  typedef T Half __attribute__((vector_size(16), aligned(sizeof(T))));
  PBDBENCH_INLINE V3<L> position(const T* P, const std::int32_t* idx) const {
    L w;
    return position(P, idx, w);
  }
  // The same, and the particles' fourth scalars (their inverse masses) into w.
  PBDBENCH_INLINE V3<L> position(const T* P, const std::int32_t* idx, L& w) const {
    V3<L> out;
    if constexpr (kWhole) {
      // Lane k's particle in one load, the four transposed.
      typedef T Whole __attribute__((vector_size(32), aligned(sizeof(T))));
      const auto at = [&](int l) PBDBENCH_INLINE_LAMBDA -> typename L::V { return *reinterpret_cast<const Whole*>(P + idx[lane(l)]); };
      const auto r0 = at(0), r1 = at(1), r2 = at(2), r3 = at(3);
      const auto t0 = __builtin_shufflevector(r0, r1, 0, 4, 2, 6), t1 = __builtin_shufflevector(r0, r1, 1, 5, 3, 7);
      const auto t2 = __builtin_shufflevector(r2, r3, 0, 4, 2, 6), t3 = __builtin_shufflevector(r2, r3, 1, 5, 3, 7);
      out.x = L::of(__builtin_shufflevector(t0, t2, 0, 1, 4, 5));
      out.y = L::of(__builtin_shufflevector(t1, t3, 0, 1, 4, 5));
      out.z = L::of(__builtin_shufflevector(t0, t2, 2, 3, 6, 7));
      w = L::of(__builtin_shufflevector(t1, t3, 2, 3, 6, 7));
    } else if constexpr (kHalves) {
      // Half h (0: x, y; 1: z, w) of the particles of lanes first, first + 2, ... in one pack.
      const auto halves = [&](int first, int h) PBDBENCH_INLINE_LAMBDA -> typename L::V {
        const auto at = [&](int k) PBDBENCH_INLINE_LAMBDA {
          return reinterpret_cast<const Half*>(P + idx[lane(k)])[h];
        };
        if constexpr (kWidth == 2) {
          return at(first);
        } else {
          const auto lo = __builtin_shufflevector(at(first), at(first + 2), 0, 1, 2, 3);
          const auto hi = __builtin_shufflevector(at(first + 4), at(first + 6), 0, 1, 2, 3);
          return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7);
        }
      };
      const auto xy_even = halves(0, 0), xy_odd = halves(1, 0);
      const auto zw_even = halves(0, 1), zw_odd = halves(1, 1);
      out.x = L::of(unpack_lo(xy_even, xy_odd));
      out.y = L::of(unpack_hi(xy_even, xy_odd));
      out.z = L::of(unpack_lo(zw_even, zw_odd));
      w = L::of(unpack_hi(zw_even, zw_odd));
    } else if constexpr (kQuarters) {
      // The particles of lanes k, k + 4, ... in the blocks of one pack: block b of quarters(k)
      // is lane 4 b + k's (x, y, z, w).
      const auto quarters = [&](int k) PBDBENCH_INLINE_LAMBDA -> typename L::V {
        const auto at = [&](int l) PBDBENCH_INLINE_LAMBDA { return *reinterpret_cast<const Half*>(P + idx[lane(l)]); };
        if constexpr (kWidth == 4) {
          return at(k);
        } else if constexpr (kWidth == 8) {
          return __builtin_shufflevector(at(k), at(k + 4), 0, 1, 2, 3, 4, 5, 6, 7);
        } else {
          const auto lo = __builtin_shufflevector(at(k), at(k + 4), 0, 1, 2, 3, 4, 5, 6, 7);
          const auto hi = __builtin_shufflevector(at(k + 8), at(k + 12), 0, 1, 2, 3, 4, 5, 6, 7);
          return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        }
      };
      const auto q0 = quarters(0), q1 = quarters(1), q2 = quarters(2), q3 = quarters(3);
      const auto xy01 = mix<Mix::LoPairs>(q0, q1), xy23 = mix<Mix::LoPairs>(q2, q3);
      out.x = L::of(mix<Mix::LoHalves>(xy01, xy23));
      out.y = L::of(mix<Mix::HiHalves>(xy01, xy23));
      const auto zw01 = mix<Mix::HiPairs>(q0, q1), zw23 = mix<Mix::HiPairs>(q2, q3);
      out.z = L::of(mix<Mix::LoHalves>(zw01, zw23));
      w = L::of(mix<Mix::HiHalves>(zw01, zw23));
    } else {
      for (int k = 0; k < kWidth; ++k) {
        const T* q = P + idx[lane(k)];
        out.x.set(k, q[0]);
        out.y.set(k, q[1]);
        out.z.set(k, q[2]);
        w.set(k, q[3]);
      }
    }
    return out;
  }
  // The positions v of the lanes set in `lanes` (and the active), with the fourth scalars w the
  // particles had when read (position(P, idx, w)).
  PBDBENCH_INLINE void store(T* P, const std::int32_t* idx, const V3<L>& v, const L& w, int lanes) const {
    lanes &= active();
    if constexpr (kWhole) {
      using V = typename L::V;
      typedef T Whole __attribute__((vector_size(32), aligned(sizeof(T))));
      const V t0 = __builtin_shufflevector(v.x.v, v.z.v, 0, 1, 4, 5), t2 = __builtin_shufflevector(v.x.v, v.z.v, 2, 3, 6, 7);
      const V t1 = __builtin_shufflevector(v.y.v, w.v, 0, 1, 4, 5), t3 = __builtin_shufflevector(v.y.v, w.v, 2, 3, 6, 7);
      const V r[4] = {__builtin_shufflevector(t0, t1, 0, 4, 2, 6), __builtin_shufflevector(t0, t1, 1, 5, 3, 7),
                      __builtin_shufflevector(t2, t3, 0, 4, 2, 6), __builtin_shufflevector(t2, t3, 1, 5, 3, 7)};
      if (lanes == 15) {
        for (int k = 0; k < 4; ++k) *reinterpret_cast<Whole*>(P + idx[k]) = r[k];
      } else {
        for (int k = 0; k < 4; ++k)
          if ((lanes >> k) & 1) *reinterpret_cast<Whole*>(P + idx[k]) = r[k];
      }
    } else if constexpr (kHalves) {
      using V = typename L::V;
      const V xy[2] = {unpack_lo(v.x.v, v.y.v), unpack_hi(v.x.v, v.y.v)};  // even lanes, odd lanes
      const V z[2] = {unpack_lo(v.z.v, w.v), unpack_hi(v.z.v, w.v)};
      // Lane K's particle; with Every (all lanes written, as nearly always) without testing it.
      const auto put = [&]<int K, bool Every>() PBDBENCH_INLINE_LAMBDA {
        if (!Every && !((lanes >> K) & 1)) return;
        Half* q = reinterpret_cast<Half*>(P + idx[K]);
        constexpr int j = K & ~1;
        q[0] = __builtin_shufflevector(xy[K & 1], xy[K & 1], j, j + 1);
        q[1] = __builtin_shufflevector(z[K & 1], z[K & 1], j, j + 1);
      };
      const auto put_lanes = [&]<bool Every, int... K>(std::integer_sequence<int, K...>) PBDBENCH_INLINE_LAMBDA {
        (put.template operator()<K, Every>(), ...);
      };
      if (lanes == (1 << kWidth) - 1) put_lanes.template operator()<true>(std::make_integer_sequence<int, kWidth>{});
      else put_lanes.template operator()<false>(std::make_integer_sequence<int, kWidth>{});
    } else if constexpr (kQuarters) {
      using V = typename L::V;
      const V xy01 = mix<Mix::LoPairs>(v.x.v, v.y.v), xy23 = mix<Mix::HiPairs>(v.x.v, v.y.v);
      const V z01 = mix<Mix::LoPairs>(v.z.v, w.v), z23 = mix<Mix::HiPairs>(v.z.v, w.v);
      // Block b of q[k]: lane 4 b + k's (x, y, z, w).
      const V q[4] = {mix<Mix::LoHalves>(xy01, z01), mix<Mix::HiHalves>(xy01, z01),
                      mix<Mix::LoHalves>(xy23, z23), mix<Mix::HiHalves>(xy23, z23)};
      const auto put = [&]<int K, bool Every>() PBDBENCH_INLINE_LAMBDA {
        if (!Every && !((lanes >> K) & 1)) return;
        constexpr int b = K / 4 * 4;
        *reinterpret_cast<Half*>(P + idx[K]) = __builtin_shufflevector(q[K % 4], q[K % 4], b, b + 1, b + 2, b + 3);
      };
      const auto put_lanes = [&]<bool Every, int... K>(std::integer_sequence<int, K...>) PBDBENCH_INLINE_LAMBDA {
        (put.template operator()<K, Every>(), ...);
      };
      if (lanes == (1 << kWidth) - 1) put_lanes.template operator()<true>(std::make_integer_sequence<int, kWidth>{});
      else put_lanes.template operator()<false>(std::make_integer_sequence<int, kWidth>{});
    } else {
      for (int k = 0; k < kWidth; ++k) {
        if (!((lanes >> k) & 1)) continue;
        T* q = P + idx[k];
        q[0] = v.x[k];
        q[1] = v.y[k];
        q[2] = v.z[k];
        q[3] = w[k];
      }
    }
  }
  // Lanes (a0, b0, a2, b2, ...) and (a1, b1, a3, b3, ...) of two packs of 2 or 8 lanes (unpcklpd,
  // unpckhpd).
  template <class V>
  static PBDBENCH_INLINE V unpack_lo(const V& a, const V& b) {
    if constexpr (kWidth == 2) return __builtin_shufflevector(a, b, 0, 2);
    else return __builtin_shufflevector(a, b, 0, 8, 2, 10, 4, 12, 6, 14);
  }
  template <class V>
  static PBDBENCH_INLINE V unpack_hi(const V& a, const V& b) {
    if constexpr (kWidth == 2) return __builtin_shufflevector(a, b, 1, 3);
    else return __builtin_shufflevector(a, b, 1, 9, 3, 11, 5, 13, 7, 15);
  }
  // Within each block of four lanes of two packs a, b: (a0, b0, a1, b1), (a2, b2, a3, b3),
  // (a0, a1, b0, b1), (a2, a3, b2, b3) (unpcklps, unpckhps, movlhps, movhlps).
  enum class Mix { LoPairs, HiPairs, LoHalves, HiHalves };
  template <Mix M>
  static constexpr int mix_index(int i) {
    const int block = i / 4 * 4, j = i % 4;
    if (M == Mix::LoPairs) return block + j / 2 + (j % 2 ? kWidth : 0);
    if (M == Mix::HiPairs) return block + 2 + j / 2 + (j % 2 ? kWidth : 0);
    if (M == Mix::LoHalves) return block + (j < 2 ? j : kWidth + j - 2);
    return block + 2 + (j < 2 ? j : kWidth + j - 2);
  }
  template <Mix M, class V>
  static PBDBENCH_INLINE V mix(const V& a, const V& b) {
    return [&]<int... I>(std::integer_sequence<int, I...>) PBDBENCH_INLINE_LAMBDA {
      return __builtin_shufflevector(a, b, mix_index<M>(I)...);
    }(std::make_integer_sequence<int, kWidth>{});
  }
  // The lanes of a mask as bits, the inactive ones clear.
  template <class M>
  PBDBENCH_INLINE int bits(const M& m) const {
    return lane_bits(m) & active();
  }
  // The active lanes whose bit is clear in `valid`.
  PBDBENCH_INLINE int skipped(int valid) const {
    return (Partial ? n : kWidth) - __builtin_popcount(static_cast<unsigned>(valid));
  }
};

// Runs body(s, lanes) over [begin, end): whole packs W of items, then one partial pack.
template <class T, class W, class Body>
inline long over_items(int begin, int end, Body&& body) {
  long skipped = 0;
  int s = begin;
  for (; s + W::kWidth <= end; s += W::kWidth) skipped += body(s, Lanes<T, W, false>{});
  if (s < end) {
    Lanes<T, W, true> partial;
    partial.n = end - s;
    skipped += body(s, partial);
  }
  return skipped;
}

// The Jacobi correction of particle i of the items s.. (zero where not ok).
template <class Ln, class M>
PBDBENCH_INLINE void put_correction(const Ln& ln, const JacobiBuffers<LaneScalar<typename Ln::L>>& J,
                                    int s, int i, const M& ok, const V3<typename Ln::L>& dx) {
  using L = typename Ln::L;
  using T = LaneScalar<L>;
  const L zero(T(0));
  T* base = J.dx + static_cast<std::ptrdiff_t>(3 * i) * J.count + s;
  ln.put(base, lane_select(ok, dx.x, zero));
  ln.put(base + J.count, lane_select(ok, dx.y, zero));
  ln.put(base + 2 * static_cast<std::ptrdiff_t>(J.count), lane_select(ok, dx.z, zero));
}

// ---------------------------------------------------------------------------------------------
// pbd

template <class T, class W, bool Anchored, bool Jacobi>
inline long pbd_distance(const BlockView<T>& b, int begin, int end, T* P, const JacobiBuffers<T>& J) {
  return over_items<T, W>(begin, end, [&](int s, auto ln) PBDBENCH_INLINE_LAMBDA -> long {
    using Ln = decltype(ln);
    using L = typename Ln::L;
    L w0, w1;
    const V3<L> x0 = ln.position(P, b.offset[0] + s, w0), x1 = ln.position(P, b.offset[1] + s, w1);
    const V3<L> d = x1 - x0;
    const L len = lane_sqrt(dot(d, d));
    const auto ok = len > L(T(0));
    const L f = (len - ln.value(b.rest + s)) / lane_select(ok, len, L(T(1)));
    const L a0 = ln.value(b.coef[0] + s) * f;
    const L a1 = ln.value(b.coef[1] + s) * f;
    const int valid = ln.bits(ok);
    if constexpr (Jacobi) {
      put_correction(ln, J, s, 0, ok, a0 * d);
      put_correction(ln, J, s, 1, ok, -(a1 * d));
    } else {
      int write0 = valid, write1 = valid;
      if constexpr (Anchored) {
        write0 &= ln.bits(w0 != L(T(0)));
        write1 &= ln.bits(w1 != L(T(0)));
      }
      ln.store(P, b.offset[0] + s, x0 + a0 * d, w0, write0);
      ln.store(P, b.offset[1] + s, x1 - a1 * d, w1, write1);
    }
    return ln.skipped(valid);
  });
}

// Kinds of four particles: the stencil of core/constraint_stencils.hpp. `Kind` is a template
// argument so that each kind's loop is straight-line code.
template <ConstraintKind Kind, class T, class L, class Ln>
PBDBENCH_INLINE StencilEval<L> eval4(const BlockView<T>& b, int s, const V3<L>* x, const Ln& ln) {
  const L rest = ln.value(b.rest + s);
  if constexpr (Kind == ConstraintKind::Volume) {
    return volume_stencil(x[0], x[1], x[2], x[3], rest);
  } else if constexpr (Kind == ConstraintKind::Bending) {
    return bending_stencil(x[0], x[1], x[2], x[3], rest);
  } else {
    L dm[9];
    for (int k = 0; k < 9; ++k) dm[k] = ln.value(b.rest_inverse[k] + s);
    if constexpr (Kind == ConstraintKind::FemDeviatoric) return fem_deviatoric_stencil(x[0], x[1], x[2], x[3], dm, rest);
    else return fem_hydrostatic_stencil(x[0], x[1], x[2], x[3], dm, rest);
  }
}

template <class T, class W, ConstraintKind Kind, bool Jacobi>
inline long pbd_four(const BlockView<T>& b, int begin, int end, T* P, const JacobiBuffers<T>& J) {
  return over_items<T, W>(begin, end, [&](int s, auto ln) PBDBENCH_INLINE_LAMBDA -> long {
    using Ln = decltype(ln);
    using L = typename Ln::L;
    V3<L> x[4];
    L ws[4];
    for (int i = 0; i < 4; ++i) x[i] = ln.position(P, b.offset[i] + s, ws[i]);
    const StencilEval<L> e = eval4<Kind>(b, s, x, ln);
    const L wsum = ws[0] * dot(e.grad[0], e.grad[0]) + ws[1] * dot(e.grad[1], e.grad[1]) +
                   ws[2] * dot(e.grad[2], e.grad[2]) + ws[3] * dot(e.grad[3], e.grad[3]);
    const auto ok = lane_and(e.valid, wsum > L(T(0)));
    const L scale = ln.value(b.coef[0] + s) * e.C / lane_select(ok, wsum, L(T(1)));
    const int valid = ln.bits(ok);
    const L zero(T(0));
    for (int i = 0; i < 4; ++i) {
      const V3<L> dx = -((scale * ws[i]) * e.grad[static_cast<size_t>(i)]);
      if constexpr (Jacobi) put_correction(ln, J, s, i, ok, dx);
      else ln.store(P, b.offset[i] + s, x[i] + dx, ws[i], valid & ln.bits(ws[i] != zero));
    }
    return ln.skipped(valid);
  });
}

// ---------------------------------------------------------------------------------------------
// xpbd

template <class T, class W, bool Anchored, bool Damped, bool Jacobi>
inline long xpbd_distance(const BlockView<T>& b, int begin, int end, T* P, const T* X0,
                          const JacobiBuffers<T>& J) {
  return over_items<T, W>(begin, end, [&](int s, auto ln) PBDBENCH_INLINE_LAMBDA -> long {
    using Ln = decltype(ln);
    using L = typename Ln::L;
    L w0, w1;
    const V3<L> x0 = ln.position(P, b.offset[0] + s, w0), x1 = ln.position(P, b.offset[1] + s, w1);
    const V3<L> d = x1 - x0;
    const L len = lane_sqrt(dot(d, d));
    const L inv_d = ln.value(b.coef[2] + s);  // 1/D, 0 when D <= 0
    const L zero(T(0));
    const auto ok = lane_and(len > zero, inv_d != zero);
    const L inv_len = L(T(1)) / lane_select(ok, len, L(T(1)));
    const L lam = ln.value(b.lambda + s);
    L num = -(len - ln.value(b.rest + s)) - ln.value(b.coef[0] + s) * lam;
    if constexpr (Damped) {
      const V3<L> motion = (x1 - ln.position(X0, b.offset[1] + s)) - (x0 - ln.position(X0, b.offset[0] + s));
      num = num - ln.value(b.coef[1] + s) * (dot(d, motion) * inv_len);
    }
    const L dlambda = lane_select(ok, num * inv_d, zero);
    const L q = dlambda * inv_len;
    const L q0 = w0 * q, q1 = w1 * q;
    const int valid = ln.bits(ok);
    if constexpr (Jacobi) {
      ln.put(J.dlambda + s, dlambda);
      put_correction(ln, J, s, 0, ok, -(q0 * d));
      put_correction(ln, J, s, 1, ok, q1 * d);
    } else {
      ln.put(b.lambda + s, lam + dlambda);
      int write0 = valid, write1 = valid;
      if constexpr (Anchored) {
        write0 &= ln.bits(w0 != zero);
        write1 &= ln.bits(w1 != zero);
      }
      ln.store(P, b.offset[0] + s, x0 - q0 * d, w0, write0);
      ln.store(P, b.offset[1] + s, x1 + q1 * d, w1, write1);
    }
    return ln.skipped(valid);
  });
}

template <class T, class W, ConstraintKind Kind, bool Damped, bool Jacobi>
inline long xpbd_four(const BlockView<T>& b, int begin, int end, T* P, const T* X0,
                      const JacobiBuffers<T>& J) {
  return over_items<T, W>(begin, end, [&](int s, auto ln) PBDBENCH_INLINE_LAMBDA -> long {
    using Ln = decltype(ln);
    using L = typename Ln::L;
    V3<L> x[4];
    L ws[4];
    for (int i = 0; i < 4; ++i) x[i] = ln.position(P, b.offset[i] + s, ws[i]);
    const StencilEval<L> e = eval4<Kind>(b, s, x, ln);
    const L alpha = ln.value(b.coef[0] + s), gamma = ln.value(b.coef[1] + s);
    const L wsum = ws[0] * dot(e.grad[0], e.grad[0]) + ws[1] * dot(e.grad[1], e.grad[1]) +
                   ws[2] * dot(e.grad[2], e.grad[2]) + ws[3] * dot(e.grad[3], e.grad[3]);
    const L zero(T(0));
    const L denom = (L(T(1)) + gamma) * wsum + alpha;
    const auto ok = lane_and(e.valid, denom > zero);
    const L lam = ln.value(b.lambda + s);
    L num = -e.C - alpha * lam;
    if constexpr (Damped) {
      L rate = zero;
      for (int i = 0; i < 4; ++i)
        rate = rate + dot(e.grad[static_cast<size_t>(i)], x[i] - ln.position(X0, b.offset[i] + s));
      num = num - gamma * rate;
    }
    const L dlambda = lane_select(ok, num / lane_select(ok, denom, L(T(1))), zero);
    const int valid = ln.bits(ok);
    if constexpr (Jacobi) ln.put(J.dlambda + s, dlambda);
    else ln.put(b.lambda + s, lam + dlambda);
    for (int i = 0; i < 4; ++i) {
      const V3<L> dx = (ws[i] * dlambda) * e.grad[static_cast<size_t>(i)];
      if constexpr (Jacobi) put_correction(ln, J, s, i, ok, dx);
      else ln.store(P, b.offset[i] + s, x[i] + dx, ws[i], valid & ln.bits(ws[i] != zero));
    }
    return ln.skipped(valid);
  });
}

// ---------------------------------------------------------------------------------------------
// One chunk through the kernel of its rule, kind and variant, in packs W. Returns the number of
// skipped projections.
template <class T, class W>
inline long project_chunk(const ChunkSpec& c, const BlockView<T>& b, T* P, const T* X0,
                          const JacobiBuffers<T>& J) {
  const int lo = c.begin, hi = c.end;
  if (c.rule == ProjectionRule::Pbd) {
    switch (c.kind) {
      case ConstraintKind::Distance:
        if (c.jacobi) return pbd_distance<T, W, true, true>(b, lo, hi, P, J);
        return c.anchored ? pbd_distance<T, W, true, false>(b, lo, hi, P, J)
                          : pbd_distance<T, W, false, false>(b, lo, hi, P, J);
      case ConstraintKind::Volume:
        return c.jacobi ? pbd_four<T, W, ConstraintKind::Volume, true>(b, lo, hi, P, J)
                        : pbd_four<T, W, ConstraintKind::Volume, false>(b, lo, hi, P, J);
      case ConstraintKind::Bending:
        return c.jacobi ? pbd_four<T, W, ConstraintKind::Bending, true>(b, lo, hi, P, J)
                        : pbd_four<T, W, ConstraintKind::Bending, false>(b, lo, hi, P, J);
      case ConstraintKind::FemDeviatoric:
      case ConstraintKind::FemHydrostatic:
      case ConstraintKind::FemStrainTriangle:
      case ConstraintKind::FemStrainTet:
        return 0;  // pbd refuses FEM (solvers/pbd.cpp)
    }
    return 0;
  }
  const auto four = [&](auto kind) -> long {
    constexpr ConstraintKind K = decltype(kind)::value;
    if (c.jacobi)
      return c.damped ? xpbd_four<T, W, K, true, true>(b, lo, hi, P, X0, J)
                      : xpbd_four<T, W, K, false, true>(b, lo, hi, P, X0, J);
    return c.damped ? xpbd_four<T, W, K, true, false>(b, lo, hi, P, X0, J)
                    : xpbd_four<T, W, K, false, false>(b, lo, hi, P, X0, J);
  };
  switch (c.kind) {
    case ConstraintKind::Distance:
      if (c.jacobi)
        return c.damped ? xpbd_distance<T, W, true, true, true>(b, lo, hi, P, X0, J)
                        : xpbd_distance<T, W, true, false, true>(b, lo, hi, P, X0, J);
      if (c.damped)
        return c.anchored ? xpbd_distance<T, W, true, true, false>(b, lo, hi, P, X0, J)
                          : xpbd_distance<T, W, false, true, false>(b, lo, hi, P, X0, J);
      return c.anchored ? xpbd_distance<T, W, true, false, false>(b, lo, hi, P, X0, J)
                        : xpbd_distance<T, W, false, false, false>(b, lo, hi, P, X0, J);
    case ConstraintKind::Volume: return four(std::integral_constant<ConstraintKind, ConstraintKind::Volume>{});
    case ConstraintKind::Bending: return four(std::integral_constant<ConstraintKind, ConstraintKind::Bending>{});
    case ConstraintKind::FemDeviatoric:
      return four(std::integral_constant<ConstraintKind, ConstraintKind::FemDeviatoric>{});
    case ConstraintKind::FemHydrostatic:
      return four(std::integral_constant<ConstraintKind, ConstraintKind::FemHydrostatic>{});
    case ConstraintKind::FemStrainTriangle:
    case ConstraintKind::FemStrainTet:
      return 0;  // vector constraints: never compiled (compile_projection refuses them)
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------
// xpbd's residuals (Macklin et al. 2016, eqs. 8 and 9; solvers/xpbd.cpp) of the items
// [begin, end) of one kind, at positions P (double, kStride scalars a particle), in packs W:
// h_j = C_j + (alpha_j / h^2) lambda_j into terms[s], and g_q -= lambda_j grad_i C_j for each
// moving particle q of an item whose lambda_j is not 0 (g: 3 doubles a particle). The products
// are formed in the packs; the subtractions one lane after another in slot order, as a loop over
// the items makes them: the same bits in any width. The block view's rest values (and Dm^-1) are
// the double ones; LT is the multipliers' type (the block's precision).
template <class LT>
struct ResidualArgs {
  const double* P = nullptr;           // (n x kStride) m
  const double* compliance = nullptr;  // (count) alpha
  const LT* lambda = nullptr;          // (count)
  const char* moving = nullptr;        // (n) inv_mass != 0
  double h2 = 0.0;                     // h^2, s^2
  double* terms = nullptr;             // (count) h_j
  double* g = nullptr;                 // (n x 3)
};

template <class W, ConstraintKind Kind, class LT>
inline void residual_items(const BlockView<double>& b, int begin, int end, const ResidualArgs<LT>& r) {
  constexpr int kArity = Kind == ConstraintKind::Distance ? 2 : 4;
  over_items<double, W>(begin, end, [&](int s, auto ln) PBDBENCH_INLINE_LAMBDA -> long {
    using L = typename decltype(ln)::L;
    V3<L> x[4];
    for (int i = 0; i < kArity; ++i) x[i] = ln.position(r.P, b.offset[i] + s);
    StencilEval<L> e;
    if constexpr (Kind == ConstraintKind::Distance) e = distance_stencil(x[0], x[1], ln.value(b.rest + s));
    else e = eval4<Kind>(b, s, x, ln);
    L lam;
    for (int k = 0; k < W::kWidth; ++k) lam.set(k, static_cast<double>(r.lambda[s + ln.lane(k)]));
    ln.put(r.terms + s, e.C + ln.value(r.compliance + s) / L(r.h2) * lam);
    V3<L> term[kArity];
    for (int i = 0; i < kArity; ++i) term[i] = lam * e.grad[static_cast<size_t>(i)];
    const int lanes = ln.bits(lam != L(0.0));
    for (int k = 0; k < W::kWidth; ++k) {
      if (!((lanes >> k) & 1)) continue;
      for (int i = 0; i < kArity; ++i) {
        const std::int32_t q = b.offset[i][s + k] / kStride;
        if (!r.moving[q]) continue;
        double* gq = r.g + 3 * static_cast<std::ptrdiff_t>(q);
        gq[0] -= term[i].x[k];
        gq[1] -= term[i].y[k];
        gq[2] -= term[i].z[k];
      }
    }
    return 0;
  });
}

// The residuals of the items [begin, end) of a block of kind `kind` (strain kinds: never
// compiled, nothing done).
template <class W, class LT>
inline void residual_chunk(ConstraintKind kind, const BlockView<double>& b, int begin, int end,
                           const ResidualArgs<LT>& r) {
  switch (kind) {
    case ConstraintKind::Distance: return residual_items<W, ConstraintKind::Distance>(b, begin, end, r);
    case ConstraintKind::Volume: return residual_items<W, ConstraintKind::Volume>(b, begin, end, r);
    case ConstraintKind::Bending: return residual_items<W, ConstraintKind::Bending>(b, begin, end, r);
    case ConstraintKind::FemDeviatoric: return residual_items<W, ConstraintKind::FemDeviatoric>(b, begin, end, r);
    case ConstraintKind::FemHydrostatic: return residual_items<W, ConstraintKind::FemHydrostatic>(b, begin, end, r);
    case ConstraintKind::FemStrainTriangle:
    case ConstraintKind::FemStrainTet: return;
  }
}

}  // namespace pbdbench
