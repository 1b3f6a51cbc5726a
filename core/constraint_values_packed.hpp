// constraint_values (core/constraint_functions.hpp) over packs of any width: a run of
// neighbouring constraints of one kind (ConstraintRuns), L::kWidth of them in the lanes of each
// pack, the lanes past the run's end filled with its last constraint (computed and dropped). A lane is the IEEE operations
// of the scalar code (core/simd.hpp), so every width gives eval_constraint's C bit for bit.
// Instantiated for 16-byte packs in core/constraint_functions.cpp and for the AVX2 and AVX-512
// widths in translation units of their own (core/constraint_values_avx2.cpp,
// core/constraint_values_avx512.cpp), chosen at run time by what the processor has.
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>

#include "core/constraint_functions.hpp"
#include "core/constraint_stencils.hpp"
#include "core/model.hpp"
#include "core/simd.hpp"

namespace pbdbench::detail {

// What the packs read (ConstraintRuns, core/constraint_functions.hpp), as raw pointers.
struct RunsView {
  const ConstraintRuns::Run* runs = nullptr;
  size_t count = 0;
  const std::int32_t* particle[4] = {nullptr, nullptr, nullptr, nullptr};
  const double* rest = nullptr;
  const Constraint* constraints = nullptr;  // the model's, for the FEM kinds
};

// The rows of X (row-major n x 3) of the particles idx[0], ..., idx[kWidth - 1], transposed
// into the lanes of x, y and z: each row's (x, y) in one 16-byte load and its z in a scalar
// one, the even lanes' pairs side by side in one pack and the odd lanes' in another, then
// interleaved (lane k's x is pair k's first value). Copying the coordinates one scalar at a time
// into arrays and loading those made the gathering about half of this file's time (a profile of
// metrics/measure/* of bench_solvers). Only data moves: the same values either way.
template <class L, size_t... K>
PBDBENCH_INLINE V3<L> gather_rows(const double* X, const std::int32_t* idx, std::index_sequence<K...>) {
  constexpr int W = L::kWidth;
  static_assert(W == 2 || W == 4 || W == 8, "double packs of 16, 32 or 64 bytes");
  typedef double Pair __attribute__((vector_size(16), aligned(sizeof(double))));
  const auto pair = [&](int k) PBDBENCH_INLINE_LAMBDA {
    return *reinterpret_cast<const Pair*>(X + 3 * static_cast<size_t>(idx[k]));
  };
  // The pairs of lanes first, first + 2, first + 4, ... side by side.
  const auto side_by_side = [&](int first) PBDBENCH_INLINE_LAMBDA -> typename L::V {
    if constexpr (W == 2) {
      return pair(first);
    } else if constexpr (W == 4) {
      return __builtin_shufflevector(pair(first), pair(first + 2), 0, 1, 2, 3);
    } else {
      const auto lo = __builtin_shufflevector(pair(first), pair(first + 2), 0, 1, 2, 3);
      const auto hi = __builtin_shufflevector(pair(first + 4), pair(first + 6), 0, 1, 2, 3);
      return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7);
    }
  };
  const typename L::V even = side_by_side(0), odd = side_by_side(1);
  V3<L> out;
  // Lane k: pair k's first (x) or second (y) value, from `even` (k even) or `odd` (k odd), at
  // the same place: the unpack of each 16-byte block.
  out.x = L::of(__builtin_shufflevector(even, odd, (K % 2 == 0 ? K : W + K - 1)...));
  out.y = L::of(__builtin_shufflevector(even, odd, (K % 2 == 0 ? K + 1 : W + K)...));
  out.z = L::of(typename L::V{X[3 * static_cast<size_t>(idx[K]) + 2]...});
  return out;
}

// C of every constraint of the runs at positions X (row-major n x 3, the data of x), into C (one
// per model constraint). Raw pointers in and out, and no standard-library template instantiated
// here: a wide translation unit must emit nothing that the linker could share with code for
// other processors.
template <class L>
void constraint_values_packed(const Model& model, const Points& x, const double* X, const RunsView& v,
                              double* C) {
  constexpr int W = L::kWidth;
  using Lanes = std::make_index_sequence<static_cast<size_t>(W)>;
  for (size_t r = 0; r < v.count; ++r) {
    const ConstraintRuns::Run run = v.runs[r];
    if (is_fem_kind(run.kind)) {
      for (size_t j = run.begin; j < run.end; ++j) C[j] = eval_constraint(model, v.constraints[j], x).C;
      continue;
    }
    const int arity_run = run.kind == ConstraintKind::Distance ? 2 : 4;
    for (size_t j = run.begin; j < run.end; j += W) {
      // The lanes past the run's end take its last constraint (computed and dropped).
      const int n = run.end - j < static_cast<size_t>(W) ? static_cast<int>(run.end - j) : W;
      std::int32_t idx[4][W];
      L rv;
      if (n == W) {
        for (int i = 0; i < arity_run; ++i)
          for (int l = 0; l < W; ++l) idx[i][l] = v.particle[i][j + static_cast<size_t>(l)];
        rv = L::load(v.rest + j);
      } else {
        for (int l = 0; l < W; ++l) {
          const size_t c = j + static_cast<size_t>(l < n ? l : n - 1);
          for (int i = 0; i < arity_run; ++i) idx[i][l] = v.particle[i][c];
          rv.set(l, v.rest[c]);
        }
      }
      const auto at = [&](int i) PBDBENCH_INLINE_LAMBDA { return gather_rows<L>(X, idx[i], Lanes{}); };
      L value(0.0);
      switch (run.kind) {
        case ConstraintKind::Distance: value = distance_stencil(at(0), at(1), rv).C; break;
        case ConstraintKind::Volume: value = volume_stencil(at(0), at(1), at(2), at(3), rv).C; break;
        case ConstraintKind::Bending: value = bending_stencil(at(0), at(1), at(2), at(3), rv).C; break;
        case ConstraintKind::FemDeviatoric:
        case ConstraintKind::FemHydrostatic:
        case ConstraintKind::FemStrainTriangle:
        case ConstraintKind::FemStrainTet:
          break;  // not reached (is_fem_kind above)
      }
      if (n == W) {
        value.store(C + j);
      } else {
        for (int k = 0; k < n; ++k) C[j + static_cast<size_t>(k)] = value[k];
      }
    }
  }
}

}  // namespace pbdbench::detail
