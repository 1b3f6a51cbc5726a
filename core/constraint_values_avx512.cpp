// constraint_values in 64-byte packs (core/constraint_values_packed.hpp). This file alone is
// compiled with -mavx512f -mfma (core/CMakeLists.txt); it instantiates only templates over 64-byte
// packs, so no function it emits is shared with the code that runs on other processors.
#include "core/constraint_values_packed.hpp"

namespace pbdbench::detail {

void constraint_values_avx512(const Model& model, const Points& x, const double* X, const RunsView& v,
                              double* C) {
  constraint_values_packed<Pack<double, 64>>(model, x, X, v, C);
}

}  // namespace pbdbench::detail
