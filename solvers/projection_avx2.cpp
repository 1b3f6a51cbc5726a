// The projection kernels in AVX2 registers (solvers/projection_wide.hpp). This file alone is
// compiled with -mavx2 (solvers/CMakeLists.txt); it instantiates only templates over 32-byte packs,
// so no function it emits is shared with the code that runs on processors without AVX2.
#include "solvers/projection_wide.hpp"

namespace pbdbench {

long project_chunk_avx2(const ChunkSpec& c, const BlockView<double>& b, double* P, const double* X0,
                        const JacobiBuffers<double>& J) {
  return project_chunk<double, Pack<double, 32>>(c, b, P, X0, J);
}

long project_chunk_avx2(const ChunkSpec& c, const BlockView<float>& b, float* P, const float* X0,
                        const JacobiBuffers<float>& J) {
  return project_chunk<float, Pack<float, 32>>(c, b, P, X0, J);
}

void residual_chunk_avx2(ConstraintKind kind, const BlockView<double>& b, int begin, int end,
                         const ResidualArgs<double>& r) {
  residual_chunk<Pack<double, 32>>(kind, b, begin, end, r);
}

void residual_chunk_avx2(ConstraintKind kind, const BlockView<double>& b, int begin, int end,
                         const ResidualArgs<float>& r) {
  residual_chunk<Pack<double, 32>>(kind, b, begin, end, r);
}

}  // namespace pbdbench
