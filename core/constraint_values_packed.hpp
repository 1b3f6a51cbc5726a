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

// C of every constraint of the runs at positions X (row-major n x 3, the data of x), into C (one
// per model constraint). Raw pointers in and out, and no standard-library template instantiated
// here: a wide translation unit must emit nothing that the linker could share with code for
// other processors.
template <class L>
void constraint_values_packed(const Model& model, const Points& x, const double* X, const RunsView& v,
                              double* C) {
  constexpr int W = L::kWidth;
  // A run is taken kBatch constraints at a time: their particles' coordinates are first copied
  // into arrays (plain scalar stores), then loaded a pack at a time. Setting a pack's lanes one
  // by one instead made every lane a store and the pack a load that waits for all of them.
  constexpr int kBatch = 64;
  static_assert(kBatch % W == 0, "a batch is whole packs");
  alignas(64) double xs[4][3][kBatch];
  alignas(64) double rest[kBatch];
  for (size_t r = 0; r < v.count; ++r) {
    const ConstraintRuns::Run run = v.runs[r];
    if (is_fem_kind(run.kind)) {
      for (size_t j = run.begin; j < run.end; ++j) C[j] = eval_constraint(model, v.constraints[j], x).C;
      continue;
    }
    const int arity_run = run.kind == ConstraintKind::Distance ? 2 : 4;
    for (size_t j = run.begin; j < run.end; j += kBatch) {
      const int n = run.end - j < static_cast<size_t>(kBatch) ? static_cast<int>(run.end - j) : kBatch;
      const int padded = (n + W - 1) / W * W;
      for (int l = 0; l < padded; ++l) {
        const size_t c = j + static_cast<size_t>(l < n ? l : n - 1);
        rest[l] = v.rest[c];
        for (int i = 0; i < arity_run; ++i) {
          const double* p = X + 3 * static_cast<size_t>(v.particle[i][c]);
          xs[i][0][l] = p[0];
          xs[i][1][l] = p[1];
          xs[i][2][l] = p[2];
        }
      }
      const auto at = [&](int i, int l) {
        return V3<L>{L::load(&xs[i][0][l]), L::load(&xs[i][1][l]), L::load(&xs[i][2][l])};
      };
      for (int l = 0; l < padded; l += W) {
        const L rv = L::load(&rest[l]);
        L value(0.0);
        switch (run.kind) {
          case ConstraintKind::Distance: value = distance_stencil(at(0, l), at(1, l), rv).C; break;
          case ConstraintKind::Volume:
            value = volume_stencil(at(0, l), at(1, l), at(2, l), at(3, l), rv).C;
            break;
          case ConstraintKind::Bending:
            value = bending_stencil(at(0, l), at(1, l), at(2, l), at(3, l), rv).C;
            break;
          case ConstraintKind::FemDeviatoric:
          case ConstraintKind::FemHydrostatic:
          case ConstraintKind::FemStrainTriangle:
          case ConstraintKind::FemStrainTet:
            break;  // not reached (is_fem_kind above)
        }
        const int last = n - l < W ? n - l : W;
        for (int k = 0; k < last; ++k) C[j + static_cast<size_t>(l + k)] = value[k];
      }
    }
  }
}

}  // namespace pbdbench::detail
