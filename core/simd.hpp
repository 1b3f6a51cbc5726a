// Packs: the values of T (double or float) in one vector register of Bytes bytes (16: SSE2, part
// of every x86-64; 32: AVX2; 64: AVX-512), a lane type of core/lanes.hpp, so that the constraint
// stencils (core/constraint_stencils.hpp) and the projection kernels
// (solvers/projection_kernels.hpp) run Bytes / sizeof(T) independent items at once. Every
// operation is the IEEE operation of each lane (add, subtract, multiply, divide and square root
// correctly rounded; comparisons and selections exact; nothing fused, the build has
// -ffp-contract=off): a lane gives the bits the scalar code gives, whatever the width. Built on
// GCC's vector extensions; the 32- and 64-byte square roots exist only in the translation units
// compiled for those instruction sets (solvers/projection_wide.cpp).
#pragma once

#include <cstdint>
#include <type_traits>

#include <immintrin.h>

#include "core/lanes.hpp"

namespace pbdbench {

template <class T, int Bytes>
struct PackMask {
  using I = std::conditional_t<sizeof(T) == 8, std::int64_t, std::int32_t>;
  typedef I V __attribute__((vector_size(Bytes)));
  V v;  // -1 (all bits) where set, 0 elsewhere
};

template <class T, int Bytes = 16>
struct Pack {
  static constexpr int kWidth = Bytes / static_cast<int>(sizeof(T));
  typedef T V __attribute__((vector_size(Bytes)));
  V v;
  Pack() = default;
  Pack(T s) : v(V{} + s) {}  // every lane s
  static Pack of(V x) {
    Pack p;
    p.v = x;
    return p;
  }
  T operator[](int i) const { return v[i]; }
  void set(int i, T s) { v[i] = s; }
  // kWidth consecutive values at a (any alignment of T). Typed accesses, not memcpy: the compiler
  // knows a store of T values leaves the index arrays and pointers of a kernel as they were
  // (a memcpy store may alias anything, and made it reload them after every store).
  typedef T U __attribute__((vector_size(Bytes), aligned(sizeof(T))));
  static Pack load(const T* a) { return of(*reinterpret_cast<const U*>(a)); }
  void store(T* a) const { *reinterpret_cast<U*>(a) = v; }
};

// The lanes of the registers every x86-64 has: 2 doubles or 4 floats.
template <class T>
inline constexpr int kPackWidth = Pack<T, 16>::kWidth;

template <class T, int B>
struct LaneTraits<Pack<T, B>> {
  using Scalar = T;
  using Mask = PackMask<T, B>;
};

template <class T, int B> PBDBENCH_INLINE Pack<T, B> operator+(Pack<T, B> a, Pack<T, B> b) { return Pack<T, B>::of(a.v + b.v); }
template <class T, int B> PBDBENCH_INLINE Pack<T, B> operator-(Pack<T, B> a, Pack<T, B> b) { return Pack<T, B>::of(a.v - b.v); }
template <class T, int B> PBDBENCH_INLINE Pack<T, B> operator*(Pack<T, B> a, Pack<T, B> b) { return Pack<T, B>::of(a.v * b.v); }
template <class T, int B> PBDBENCH_INLINE Pack<T, B> operator/(Pack<T, B> a, Pack<T, B> b) { return Pack<T, B>::of(a.v / b.v); }
template <class T, int B> PBDBENCH_INLINE Pack<T, B> operator-(Pack<T, B> a) { return Pack<T, B>::of(-a.v); }
template <class T, int B> PBDBENCH_INLINE PackMask<T, B> operator<(Pack<T, B> a, Pack<T, B> b) { return {a.v < b.v}; }
template <class T, int B> PBDBENCH_INLINE PackMask<T, B> operator>(Pack<T, B> a, Pack<T, B> b) { return {a.v > b.v}; }
template <class T, int B> PBDBENCH_INLINE PackMask<T, B> operator!=(Pack<T, B> a, Pack<T, B> b) { return {a.v != b.v}; }

template <class T, int B>
PBDBENCH_INLINE Pack<T, B> lane_select(PackMask<T, B> m, Pack<T, B> a, Pack<T, B> b) {
  return Pack<T, B>::of(m.v ? a.v : b.v);
}
template <class T, int B>
PBDBENCH_INLINE PackMask<T, B> lane_and(PackMask<T, B> m, PackMask<T, B> n) {
  return {m.v & n.v};
}
template <class T, int B>
PBDBENCH_INLINE PackMask<T, B> lane_not(PackMask<T, B> m) {
  return {~m.v};
}
template <class T, int B>
PBDBENCH_INLINE Pack<T, B> lane_abs(Pack<T, B> a) {
  using M = typename PackMask<T, B>::V;
  using I = typename PackMask<T, B>::I;
  M bits;
  __builtin_memcpy(&bits, &a.v, sizeof bits);
  bits = bits & static_cast<I>(~(I(1) << (8 * sizeof(T) - 1)));  // clear the sign
  Pack<T, B> out;
  __builtin_memcpy(&out.v, &bits, sizeof bits);
  return out;
}
// The lanes of a mask as bits (lane i at bit i). A mask lane is all bits or none, so its sign
// bit says which: one movemask (or, in AVX-512, one compare into a mask register) instead of a
// lane-by-lane extraction.
template <class T, int B>
PBDBENCH_INLINE int lane_bits(PackMask<T, B> m) {
  if constexpr (B == 16) {
    if constexpr (sizeof(T) == 8) return _mm_movemask_pd(reinterpret_cast<__m128d>(m.v));
    else return _mm_movemask_ps(reinterpret_cast<__m128>(m.v));
  }
#ifdef __AVX__
  if constexpr (B == 32) {
    if constexpr (sizeof(T) == 8) return _mm256_movemask_pd(reinterpret_cast<__m256d>(m.v));
    else return _mm256_movemask_ps(reinterpret_cast<__m256>(m.v));
  }
#endif
#ifdef __AVX512F__
  if constexpr (B == 64) {
    if constexpr (sizeof(T) == 8) return _mm512_cmpneq_epi64_mask(reinterpret_cast<__m512i>(m.v), _mm512_setzero_si512());
    else return _mm512_cmpneq_epi32_mask(reinterpret_cast<__m512i>(m.v), _mm512_setzero_si512());
  }
#endif
  int bits = 0;
  for (int i = 0; i < Pack<T, B>::kWidth; ++i) bits |= (m.v[i] != 0 ? 1 : 0) << i;
  return bits;
}

PBDBENCH_INLINE Pack<double, 16> lane_sqrt(Pack<double, 16> a) {
  return Pack<double, 16>::of(reinterpret_cast<Pack<double, 16>::V>(_mm_sqrt_pd(reinterpret_cast<__m128d>(a.v))));
}
PBDBENCH_INLINE Pack<float, 16> lane_sqrt(Pack<float, 16> a) {
  return Pack<float, 16>::of(reinterpret_cast<Pack<float, 16>::V>(_mm_sqrt_ps(reinterpret_cast<__m128>(a.v))));
}
#ifdef __AVX__
PBDBENCH_INLINE Pack<double, 32> lane_sqrt(Pack<double, 32> a) {
  return Pack<double, 32>::of(reinterpret_cast<Pack<double, 32>::V>(_mm256_sqrt_pd(reinterpret_cast<__m256d>(a.v))));
}
PBDBENCH_INLINE Pack<float, 32> lane_sqrt(Pack<float, 32> a) {
  return Pack<float, 32>::of(reinterpret_cast<Pack<float, 32>::V>(_mm256_sqrt_ps(reinterpret_cast<__m256>(a.v))));
}
#endif
#ifndef __AVX__
// The wider packs in a translation unit built without their instructions (the tests, to check
// every width's data movement on any processor; the compiler lowers the packs): lane by lane,
// correctly rounded as the instructions are.
PBDBENCH_INLINE Pack<double, 32> lane_sqrt(Pack<double, 32> a) {
  for (int i = 0; i < 4; ++i) a.v[i] = std::sqrt(a.v[i]);
  return a;
}
#endif
#ifndef __AVX512F__
PBDBENCH_INLINE Pack<double, 64> lane_sqrt(Pack<double, 64> a) {
  for (int i = 0; i < 8; ++i) a.v[i] = std::sqrt(a.v[i]);
  return a;
}
#endif
#ifdef __AVX512F__
PBDBENCH_INLINE Pack<double, 64> lane_sqrt(Pack<double, 64> a) {
  return Pack<double, 64>::of(reinterpret_cast<Pack<double, 64>::V>(_mm512_maskz_sqrt_pd(static_cast<__mmask8>(0xff), reinterpret_cast<__m512d>(a.v))));
}
PBDBENCH_INLINE Pack<float, 64> lane_sqrt(Pack<float, 64> a) {
  return Pack<float, 64>::of(reinterpret_cast<Pack<float, 64>::V>(_mm512_maskz_sqrt_ps(static_cast<__mmask16>(0xffff), reinterpret_cast<__m512>(a.v))));
}
#endif

}  // namespace pbdbench
