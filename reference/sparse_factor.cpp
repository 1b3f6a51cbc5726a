// CHOLMOD (supernodal Cholesky) with a KLU (LU) fallback on a fixed pattern. sparse_factor.hpp.
#include "reference/sparse_factor.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include <cholmod.h>
#include <klu.h>

namespace pbdbench {

// The pattern's int64 index arrays are handed to the long-index interfaces (cholmod_l_*,
// klu_l_*) without a copy.
static_assert(std::is_same_v<std::int64_t, SuiteSparse_long>,
              "SparsityPattern's indices must be SuiteSparse_long");

namespace {

constexpr double kSymmetryRelative = 1e-10;  // see sparse_factor.hpp
constexpr double kSymmetryDiagonal = 1e-12;
constexpr double kMinReciprocalCondition = 1e-15;  // KLU's rcond estimate below: singular

}  // namespace

struct SparseFactor::Impl {
  explicit Impl(const SparsityPattern& p) : pattern(p), n(p.n) {
    check_pattern();
    build_upper();

    cholmod_l_start(&cc);
    cc.supernodal = CHOLMOD_SUPERNODAL;
    cc.quick_return_if_not_posdef = 1;  // stop at the first pivot <= 0: LU follows anyway
    cc.print = 0;                       // failures are reported through Stats and Method
    cc.error_handler = nullptr;

    std::memset(&upper_view, 0, sizeof(upper_view));
    upper_view.nrow = upper_view.ncol = static_cast<size_t>(n);
    upper_view.nzmax = upper_row.size();
    upper_view.p = upper_start.data();
    upper_view.i = upper_row.data();
    upper_view.nz = nullptr;
    upper_view.x = upper_values.data();
    upper_view.z = nullptr;
    upper_view.stype = 1;  // symmetric, upper triangle stored
    upper_view.itype = CHOLMOD_LONG;
    upper_view.xtype = CHOLMOD_REAL;
    upper_view.dtype = CHOLMOD_DOUBLE;
    upper_view.sorted = 1;
    upper_view.packed = 1;
    if (n > 0) {
      L = cholmod_l_analyze(&upper_view, &cc);
      if (L == nullptr) {
        cholmod_l_finish(&cc);
        throw std::runtime_error("SparseFactor: cholmod_l_analyze failed (status " +
                                 std::to_string(cc.status) + ")");
      }
      B = cholmod_l_allocate_dense(static_cast<size_t>(n), 1, static_cast<size_t>(n),
                                   CHOLMOD_REAL, &cc);
      if (B == nullptr) {
        cholmod_l_free_factor(&L, &cc);
        cholmod_l_finish(&cc);
        throw std::runtime_error("SparseFactor: cholmod_l_allocate_dense failed");
      }
    }
    klu_l_defaults(&kc);
  }

  ~Impl() {
    if (num != nullptr) klu_l_free_numeric(&num, &kc);
    if (sym != nullptr) klu_l_free_symbolic(&sym, &kc);
    for (cholmod_dense** d : {&B, &X, &Y, &E})
      if (*d != nullptr) cholmod_l_free_dense(d, &cc);
    if (L != nullptr) cholmod_l_free_factor(&L, &cc);
    cholmod_l_finish(&cc);
  }

  void check_pattern() const {
    if (n < 0 || pattern.column_start.size() != static_cast<size_t>(n) + 1 ||
        pattern.column_start.front() != 0 ||
        pattern.column_start.back() != static_cast<std::int64_t>(pattern.row.size()))
      throw std::invalid_argument("SparseFactor: the pattern's column starts are inconsistent");
    for (int j = 0; j < n; ++j) {
      const auto b = pattern.column_start[static_cast<size_t>(j)];
      const auto e = pattern.column_start[static_cast<size_t>(j) + 1];
      for (auto k = b; k < e; ++k) {
        const auto i = pattern.row[static_cast<size_t>(k)];
        if (i < 0 || i >= n || (k > b && i <= pattern.row[static_cast<size_t>(k) - 1]))
          throw std::invalid_argument("SparseFactor: the pattern's rows are not sorted and in range");
      }
    }
  }

  // The upper triangle's pattern (rows i <= j of each column j), where each of its entries
  // comes from in the whole pattern, and the slot of its mirror (j, i); the diagonal slots.
  void build_upper() {
    diag.assign(static_cast<size_t>(n), -1);
    upper_start.assign(static_cast<size_t>(n) + 1, 0);
    for (int j = 0; j < n; ++j) {
      upper_start[static_cast<size_t>(j)] = static_cast<std::int64_t>(upper_row.size());
      for (auto k = pattern.column_start[static_cast<size_t>(j)];
           k < pattern.column_start[static_cast<size_t>(j) + 1]; ++k) {
        const auto i = pattern.row[static_cast<size_t>(k)];
        if (i > j) {
          if (pattern.find(j, static_cast<int>(i)) < 0)
            throw std::invalid_argument("SparseFactor: the pattern is not symmetric (entry (" +
                                        std::to_string(i) + ", " + std::to_string(j) +
                                        ") has no mirror)");
          continue;
        }
        const std::int64_t mirror = pattern.find(j, static_cast<int>(i));
        if (mirror < 0)
          throw std::invalid_argument("SparseFactor: the pattern is not symmetric (entry (" +
                                      std::to_string(i) + ", " + std::to_string(j) +
                                      ") has no mirror)");
        if (i == j) diag[static_cast<size_t>(j)] = k;
        upper_row.push_back(i);
        upper_source.push_back(k);
        upper_mirror.push_back(mirror);
      }
      if (diag[static_cast<size_t>(j)] < 0)
        throw std::invalid_argument("SparseFactor: the pattern lacks the diagonal entry (" +
                                    std::to_string(j) + ", " + std::to_string(j) + ")");
    }
    upper_start[static_cast<size_t>(n)] = static_cast<std::int64_t>(upper_row.size());
    upper_values.assign(upper_row.size(), 0.0);
  }

  // Fills upper_values with the averaged pairs; returns whether the matrix is symmetric.
  bool symmetrise(const double* v) {
    bool symmetric = true;
    for (size_t k = 0; k < upper_row.size(); ++k) {
      const double a = v[upper_source[k]], b = v[upper_mirror[k]];
      upper_values[k] = 0.5 * (a + b);
      if (symmetric && a != b) {
        const int i = static_cast<int>(upper_row[k]);
        // Entry k is (i, j); its mirror (j, i) lies in column i, at row j.
        const int j = static_cast<int>(pattern.row[static_cast<size_t>(upper_mirror[k])]);
        const double dii = std::abs(v[diag[static_cast<size_t>(i)]]);
        const double djj = std::abs(v[diag[static_cast<size_t>(j)]]);
        const double tol = kSymmetryRelative * std::max(std::abs(a), std::abs(b)) +
                           kSymmetryDiagonal * std::sqrt(dii * djj);
        if (!(std::abs(a - b) <= tol)) symmetric = false;
      }
    }
    return symmetric;
  }

  bool cholesky() {
    if (n == 0) return true;
    const int ok = cholmod_l_factorize(&upper_view, L, &cc);
    return ok != 0 && cc.status == CHOLMOD_OK && L->minor == static_cast<size_t>(n);
  }

  bool lu(const double* values) {
    if (n == 0) return true;
    if (sym == nullptr) {
      sym = klu_l_analyze(n, const_cast<SuiteSparse_long*>(pattern.column_start.data()),
                          const_cast<SuiteSparse_long*>(pattern.row.data()), &kc);
      if (sym == nullptr) return false;
    }
    if (num != nullptr) klu_l_free_numeric(&num, &kc);
    num = klu_l_factor(const_cast<SuiteSparse_long*>(pattern.column_start.data()),
                       const_cast<SuiteSparse_long*>(pattern.row.data()),
                       const_cast<double*>(values), sym, &kc);
    if (num == nullptr || kc.status != KLU_OK) return false;
    if (klu_l_rcond(sym, num, &kc) == 0 || !(kc.rcond >= kMinReciprocalCondition)) return false;
    return true;
  }

  SparsityPattern pattern;
  int n;
  std::vector<std::int64_t> diag;  // (n) slot of (j, j) in pattern
  // Upper triangle, CSC.
  std::vector<std::int64_t> upper_start, upper_row, upper_source, upper_mirror;
  std::vector<double> upper_values;

  cholmod_common cc{};
  cholmod_sparse upper_view{};
  cholmod_factor* L = nullptr;
  cholmod_dense *B = nullptr, *X = nullptr, *Y = nullptr, *E = nullptr;  // solve2's buffers

  klu_l_common kc{};
  klu_l_symbolic* sym = nullptr;
  klu_l_numeric* num = nullptr;

  Method method = Method::None;
  Stats stats;
};

SparseFactor::SparseFactor(const SparsityPattern& pattern)
    : impl_(std::make_unique<Impl>(pattern)) {}

SparseFactor::~SparseFactor() = default;

int SparseFactor::size() const { return impl_->n; }

const SparsityPattern& SparseFactor::pattern() const { return impl_->pattern; }

SparseFactor::Method SparseFactor::factorize(const double* values, bool allow_lu) {
  Impl& m = *impl_;
  m.method = Method::None;
  const size_t nnz = m.pattern.row.size();
  for (size_t k = 0; k < nnz; ++k)
    if (!std::isfinite(values[k])) return Method::None;
  const bool symmetric = m.symmetrise(values);
  if (symmetric) {
    if (m.cholesky()) {
      ++m.stats.cholesky;
      return m.method = Method::Cholesky;
    }
    ++m.stats.not_positive_definite;
  } else {
    ++m.stats.unsymmetric;
  }
  if (!allow_lu) return Method::None;
  if (m.lu(values)) {
    ++m.stats.lu;
    return m.method = Method::Lu;
  }
  ++m.stats.singular;
  return Method::None;
}

SparseFactor::Method SparseFactor::method() const { return impl_->method; }

bool SparseFactor::solve(const double* b, double* x) {
  Impl& m = *impl_;
  if (m.method == Method::None) return false;
  const int n = m.n;
  if (n == 0) {
    ++m.stats.solves;
    return true;
  }
  if (m.method == Method::Cholesky) {
    std::copy(b, b + n, static_cast<double*>(m.B->x));
    if (!cholmod_l_solve2(CHOLMOD_A, m.L, m.B, nullptr, &m.X, nullptr, &m.Y, &m.E, &m.cc))
      return false;
    const double* r = static_cast<const double*>(m.X->x);
    std::copy(r, r + n, x);
  } else {
    if (x != b) std::copy(b, b + n, x);
    if (!klu_l_solve(m.sym, m.num, n, 1, x, &m.kc)) return false;
  }
  ++m.stats.solves;
  return true;
}

const SparseFactor::Stats& SparseFactor::stats() const { return impl_->stats; }

const char* to_string(SparseFactor::Method method) {
  switch (method) {
    case SparseFactor::Method::None: return "none";
    case SparseFactor::Method::Cholesky: return "cholesky";
    case SparseFactor::Method::Lu: return "lu";
  }
  return "none";
}

}  // namespace pbdbench
