// Factorisations of a sparse n x n matrix on a fixed symmetric pattern (SparsityPattern: both
// triangles stored, every diagonal entry present), for the reference solvers' Newton systems:
//
//   - Cholesky LL^T, supernodal (CHOLMOD), when the matrix is symmetric and positive definite;
//   - LU with partial pivoting (KLU) otherwise: a matrix that is not symmetric, or one whose
//     Cholesky meets a pivot <= 0 (an indefinite or singular matrix: compressed springs or
//     buckling make a stiffness indefinite).
//
// Each symbolic analysis (fill-reducing ordering, elimination tree, supernodes) is done once for
// the fixed pattern: CHOLMOD's at construction, KLU's at the first LU. factorize() does only the
// numeric factorisation. Cholesky is tried first every time (a failed one stops at the first
// pivot <= 0: CHOLMOD's quick return), so a matrix that becomes definite again goes back to it.
//
// Symmetry: a matrix is symmetric here when every pair of mirrored entries agrees to
// |a_ij - a_ji| <= 1e-10 max(|a_ij|, |a_ji|) + 1e-12 sqrt(|a_ii a_jj|): the round-off of a matrix
// assembled or scaled row by row (the reduced matrix M + gamma D + gamma^2 K is formed from rows
// scaled by the masses) passes, a genuinely unsymmetric one does not. CHOLMOD gets the average
// (a_ij + a_ji) / 2 of each pair; KLU gets the matrix as it is.
//
// Not thread-safe; move-only objects are not needed here, so it is neither copyable nor movable.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "reference/energy.hpp"

namespace pbdbench {

class SparseFactor {
 public:
  enum class Method : std::uint8_t {
    None,      // no valid factorisation (none yet, or the last factorize() failed)
    Cholesky,  // LL^T of the symmetrised matrix (CHOLMOD, supernodal)
    Lu,        // LU with partial pivoting (KLU)
  };

  // What the factorisations did, cumulative.
  struct Stats {
    long cholesky = 0;               // successful Cholesky factorisations
    long not_positive_definite = 0;  // Cholesky attempts that met a pivot <= 0
    long unsymmetric = 0;            // factorize() calls on a matrix that was not symmetric
    long lu = 0;                     // successful LU factorisations
    long singular = 0;               // LU attempts that found the matrix singular (a zero pivot,
                                     // or KLU's reciprocal condition estimate below 1e-15)
    long solves = 0;                 // solve() calls that succeeded
  };

  // Copies `pattern` (square, sorted rows, symmetric, every (i, i) present; throws
  // std::invalid_argument otherwise) and runs CHOLMOD's symbolic analysis on it.
  explicit SparseFactor(const SparsityPattern& pattern);
  ~SparseFactor();
  SparseFactor(const SparseFactor&) = delete;
  SparseFactor& operator=(const SparseFactor&) = delete;

  int size() const;
  const SparsityPattern& pattern() const;

  // Factorises the matrix with `values` in pattern() order (nnz of them): Cholesky when it is
  // symmetric and positive definite; else, when allow_lu, LU. Returns the method that succeeded,
  // or None (non-finite values; not positive definite or not symmetric and !allow_lu; singular).
  // After None, solve() refuses until the next successful factorize().
  Method factorize(const double* values, bool allow_lu = true);
  Method method() const;

  // x = A^-1 b with the last factorisation (n values each; x may be b). Returns false when there
  // is no valid factorisation or the solve failed.
  bool solve(const double* b, double* x);

  const Stats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// "none", "cholesky", "lu".
const char* to_string(SparseFactor::Method method);

}  // namespace pbdbench
