// constraint_values in 32-byte packs (core/constraint_values_packed.hpp). This file alone is
// compiled with -mavx2 (core/CMakeLists.txt); it instantiates only templates over 32-byte
// packs, so no function it emits is shared with the code that runs on other processors.
#include "core/constraint_values_packed.hpp"

namespace pbdbench::detail {

void constraint_values_avx2(const Model& model, const Points& x, const double* X, const RunsView& v,
                            double* C) {
  constraint_values_packed<Pack<double, 32>>(model, x, X, v, C);
}

}  // namespace pbdbench::detail
