// The projection kernels (solvers/projection_kernels.hpp) in the wider registers of AVX2 (4
// doubles, 8 floats) and AVX-512 (8 doubles, 16 floats), each in a translation unit of its own
// compiled for that instruction set (solvers/projection_avx2.cpp, solvers/projection_avx512.cpp),
// used only when the processor has it. A lane computes the same IEEE operations as the 16-byte
// packs and the scalar code: the results are the same bits whichever runs.
#pragma once

#include "solvers/projection_kernels.hpp"

namespace pbdbench {

// The register width the projections use, in bytes: 64 (AVX-512F), 32 (AVX2) or 16 (SSE2).
enum class VectorWidth : int { Sse2 = 16, Avx2 = 32, Avx512 = 64 };

// The widest this processor (and its operating system) supports.
VectorWidth widest_vector_width();

// The chunk [c.begin, c.end) in packs of that width; returns the skipped projections.
long project_chunk_avx2(const ChunkSpec& c, const BlockView<double>& b, double* P, const double* X0,
                        const JacobiBuffers<double>& J);
long project_chunk_avx2(const ChunkSpec& c, const BlockView<float>& b, float* P, const float* X0,
                        const JacobiBuffers<float>& J);
long project_chunk_avx512(const ChunkSpec& c, const BlockView<double>& b, double* P, const double* X0,
                          const JacobiBuffers<double>& J);
long project_chunk_avx512(const ChunkSpec& c, const BlockView<float>& b, float* P, const float* X0,
                          const JacobiBuffers<float>& J);

// xpbd's residuals of the items [begin, end) of a block (residual_chunk) in packs of that width,
// the multipliers in double or float.
void residual_chunk_avx2(ConstraintKind kind, const BlockView<double>& b, int begin, int end,
                         const ResidualArgs<double>& r);
void residual_chunk_avx2(ConstraintKind kind, const BlockView<double>& b, int begin, int end,
                         const ResidualArgs<float>& r);
void residual_chunk_avx512(ConstraintKind kind, const BlockView<double>& b, int begin, int end,
                           const ResidualArgs<double>& r);
void residual_chunk_avx512(ConstraintKind kind, const BlockView<double>& b, int begin, int end,
                           const ResidualArgs<float>& r);

}  // namespace pbdbench
