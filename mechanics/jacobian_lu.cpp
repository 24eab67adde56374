// JacobianLU on SuiteSparse's KLU. KLU orders A + A^T (AMD) and, factorizing, prefers diagonal
// pivots; the collocation Jacobian's diagonal is often zero (the unit-norm row against a quaternion
// component that vanishes in the drawn frame), and pivoting off it then ruins the ordering (2.6
// times the fill on a grid shell). So rows are first paired with columns inside each diagonal block
// (one control point: 7 unknowns, 7 equations) by complete pivoting of that block, and KLU factors
// the row-permuted matrix P J. Later factorizations reuse KLU's pivot sequence while it stays
// sound. Why KLU and these choices: mechanics/README.md.
#include "mechanics/mechanics.hpp"

#include <Eigen/LU>

#include <klu.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>

namespace rodfab::mechanics {

namespace {

// Sign of a permutation given as an index array, by its cycles: a cycle of length k is k - 1 swaps.
int permutationSign(const int* p, int n) {
  std::vector<char> seen(static_cast<std::size_t>(n), 0);
  int sign = 1;
  for (int i = 0; i < n; ++i) {
    if (seen[i]) continue;
    int length = 0;
    for (int j = i; !seen[j]; j = p[j]) seen[j] = 1, ++length;
    if (length % 2 == 0) sign = -sign;
  }
  return sign;
}

// Row order pairing each column with a strong row of its diagonal block: new row k is old row
// rowFor[k]. Complete pivoting of the block (P B Q = L U) pairs row P^-1(k) with column Q(k).
std::vector<int> blockMatching(const Eigen::SparseMatrix<double>& m, int block) {
  const int n = static_cast<int>(m.rows());
  std::vector<int> rowFor(n);
  for (int i = 0; i < n; ++i) rowFor[i] = i;
  if (block <= 1 || n % block != 0) return rowFor;
  Eigen::MatrixXd dense(block, block);
  std::vector<int> rowAt(block);
  for (int b = 0; b < n; b += block) {
    dense.setZero();
    for (int c = 0; c < block; ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(m, b + c); it; ++it)
        if (it.row() >= b && it.row() < b + block) dense(it.row() - b, c) = it.value();
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(dense);
    const auto& p = lu.permutationP().indices();
    const auto& q = lu.permutationQ().indices();
    for (int r = 0; r < block; ++r) rowAt[p[r]] = r;
    for (int k = 0; k < block; ++k) rowFor[b + q[k]] = b + rowAt[k];
  }
  return rowFor;
}

// KLU's settings for Jacobians: AMD on A + A^T (the Jacobian's pattern is nearly symmetric), and
// BTF, whose maximum transversal still trims the fill a little (3 % measured).
void configure(klu_common& common) {
  klu_defaults(&common);
  common.ordering = 0;
  common.btf = 1;
}

// Rows with more entries than this are a joint's balance rows, coupled to more than some 8 rod ends
// (an interior collocation row has at most 7 (p + 1) = 56, a rod end adds 14).
constexpr int kDenseRow = 112;

// KLU scales each row by its largest entry by default. A joint of N rod ends has balance rows with
// entries in every end's columns; scaled so, they keep the weight of a rod's own rows, outbid its
// diagonal as pivots after a few eliminations, and each such pivot spreads their fill: a star of
// 800 rods had 24 off-diagonal pivots and 1.4 times the factor entries per rod of one of 200, 1,600
// rods 2.3 times. Scaled by the sum of their magnitudes they weigh about 1 / N as much and the fill
// per rod stays the same (mechanics/README.md, "Many rods at one joint"). Matrices without such rows
// keep the largest-entry scaling, so their pivots, and every result, stay what they were.
int rowScaling(const Eigen::SparseMatrix<double>& m) {
  std::vector<int> entries(static_cast<std::size_t>(m.rows()), 0);
  for (Eigen::Index k = 0; k < m.nonZeros(); ++k) ++entries[static_cast<std::size_t>(m.innerIndexPtr()[k])];
  const bool dense = std::any_of(entries.begin(), entries.end(), [](int n) { return n > kDenseRow; });
  return dense ? 1 : 2;
}

}  // namespace

struct JacobianLU::Factors {
  klu_common common{};
  klu_symbolic* symbolic = nullptr;
  klu_numeric* numeric = nullptr;
  std::vector<int> columnStarts, rowIndices;  // the analysed pattern of J
  Eigen::SparseMatrix<double> permuted;  // P J, its values refreshed by every factorize
  std::vector<int> rowFor;               // P: row k of P J is row rowFor[k] of J
  std::vector<int> valueAt;              // entry i of J's values is entry valueAt[i] of P J's
  int rowSign = 1;                       // sign of P
  double freshRcond = 0.0;  // pivot ratio of the last factorization with fresh pivots
  int sign = 0;
  bool reused = false;      // the last factorization kept the previous pivots
  std::mutex solving;       // klu_solve works in the numeric object's workspace

  Factors() { configure(common); }
  ~Factors() { release(); }
  void release() {
    if (numeric) klu_free_numeric(&numeric, &common);
    if (symbolic) klu_free_symbolic(&symbolic, &common);
  }
  int determinantSign() const {
    const int n = symbolic->n;
    int s = rowSign * permutationSign(numeric->Pnum, n) * permutationSign(symbolic->Q, n);
    const double* u = static_cast<const double*>(numeric->Udiag);
    for (int i = 0; i < n; ++i) s = u[i] < 0 ? -s : s;
    return s;  // the row scaling KLU applies is positive and does not change it
  }
  // KLU factors R \ (P A Q) = L U with L unit lower triangular, so |det A| = prod Rs * prod |U_ii|.
  double logAbsDeterminant() const {
    const int n = symbolic->n;
    const double* u = static_cast<const double*>(numeric->Udiag);
    const double* rs = numeric->Rs;
    double sum = 0.0;
    for (int i = 0; i < n; ++i) sum += std::log(std::abs(u[i])) + (rs ? std::log(rs[i]) : 0.0);
    return sum;
  }
  void analyse(const Eigen::SparseMatrix<double>& m, int block);
};

// Pattern, row matching and ordering of a new Jacobian pattern, from its first matrix's values.
void JacobianLU::Factors::analyse(const Eigen::SparseMatrix<double>& m, int block) {
  release();
  columnStarts.assign(m.outerIndexPtr(), m.outerIndexPtr() + m.cols() + 1);
  rowIndices.assign(m.innerIndexPtr(), m.innerIndexPtr() + m.nonZeros());
  common.scale = rowScaling(m);
  rowFor = blockMatching(m, block);
  Eigen::VectorXi newRow(m.rows());
  for (int k = 0; k < static_cast<int>(rowFor.size()); ++k) newRow[rowFor[k]] = k;
  rowSign = permutationSign(newRow.data(), static_cast<int>(m.rows()));
  // Permute a matrix whose values are the entry indices, to learn where each entry goes.
  Eigen::SparseMatrix<double> index = m;
  for (Eigen::Index i = 0; i < index.nonZeros(); ++i) index.valuePtr()[i] = static_cast<double>(i);
  permuted = Eigen::PermutationMatrix<Eigen::Dynamic>(newRow) * index;
  permuted.makeCompressed();
  valueAt.assign(static_cast<std::size_t>(m.nonZeros()), 0);
  for (Eigen::Index k = 0; k < permuted.nonZeros(); ++k)
    valueAt[static_cast<std::size_t>(permuted.valuePtr()[k])] = static_cast<int>(k);
  symbolic = klu_analyze(static_cast<int>(m.rows()), permuted.outerIndexPtr(), permuted.innerIndexPtr(), &common);
  if (!symbolic) throw std::runtime_error("KLU could not analyse the Jacobian (status " + std::to_string(common.status) + ")");
}

JacobianLU::JacobianLU(int pivotBlock) : factors_(std::make_unique<Factors>()), pivotBlock_(std::max(1, pivotBlock)) {}
JacobianLU::~JacobianLU() = default;
JacobianLU::JacobianLU(JacobianLU&&) noexcept = default;
JacobianLU& JacobianLU::operator=(JacobianLU&&) noexcept = default;

bool JacobianLU::samePattern(const Eigen::SparseMatrix<double>& m) const {
  const Factors& f = *factors_;
  return f.symbolic && m.isCompressed() && m.rows() == m.cols() &&
         static_cast<std::size_t>(m.cols()) + 1 == f.columnStarts.size() &&
         static_cast<std::size_t>(m.nonZeros()) == f.rowIndices.size() &&
         std::equal(f.columnStarts.begin(), f.columnStarts.end(), m.outerIndexPtr()) &&
         std::equal(f.rowIndices.begin(), f.rowIndices.end(), m.innerIndexPtr());
}

bool JacobianLU::factorize(const Eigen::SparseMatrix<double>& jacobian, Pivoting pivoting) {
  Factors& f = *factors_;
  if (jacobian.rows() != jacobian.cols() || jacobian.rows() == 0 || !jacobian.isCompressed() ||
      jacobian.nonZeros() >= std::numeric_limits<int>::max())
    throw std::invalid_argument("JacobianLU::factorize: expected a square, non-empty, compressed matrix (< 2^31 entries)");
  if (!std::isfinite(jacobian.cwiseAbs().sum())) return false;
  if (!samePattern(jacobian)) {
    f.analyse(jacobian, pivotBlock_);
    ++analyses_;
  }
  for (Eigen::Index i = 0; i < jacobian.nonZeros(); ++i) f.permuted.valuePtr()[f.valueAt[i]] = jacobian.valuePtr()[i];
  int* colStart = f.permuted.outerIndexPtr();
  int* rowIndex = f.permuted.innerIndexPtr();
  double* values = f.permuted.valuePtr();
  f.sign = 0;
  // Refactor along the previous pivots unless the pivot ratio (min |U_ii| / max |U_ii|) has fallen
  // 1e4 below the fresh factorization's: then the old pivots no longer suit the values. (KLU's
  // pivot growth would be the finer test but costs half a refactorization.)
  if (pivoting == Pivoting::Reuse && f.numeric &&
      klu_refactor(colStart, rowIndex, values, f.symbolic, f.numeric, &f.common) && f.common.status == KLU_OK &&
      klu_rcond(f.symbolic, f.numeric, &f.common) && f.common.rcond > 1e-4 * f.freshRcond) {
    ++refactorizations_;
    f.reused = true;
    f.sign = f.determinantSign();
    return true;
  }
  if (f.numeric) klu_free_numeric(&f.numeric, &f.common);
  f.numeric = klu_factor(colStart, rowIndex, values, f.symbolic, &f.common);
  if (!f.numeric || f.common.status != KLU_OK) return false;  // KLU_SINGULAR: a zero pivot
  if (!klu_rcond(f.symbolic, f.numeric, &f.common) || !(f.common.rcond > 0)) return false;
  f.freshRcond = f.common.rcond;
  f.reused = false;
  ++factorizations_;
  f.sign = f.determinantSign();
  return true;
}

// J x = b is (P J) x = P b; J^T y = c is (P J)^T z = c with y = P^T z.
Eigen::VectorXd JacobianLU::solve(const Eigen::VectorXd& b, bool transposed) const {
  Factors& f = *factors_;
  if (!f.numeric || f.sign == 0) throw std::logic_error("JacobianLU: solve before a successful factorize");
  if (b.size() + 1 != static_cast<Eigen::Index>(f.columnStarts.size())) throw std::invalid_argument("JacobianLU: right-hand side of the wrong size");
  const int n = static_cast<int>(b.size());
  Eigen::VectorXd x(n);
  if (transposed) x = b;
  else
    for (int k = 0; k < n; ++k) x[k] = b[f.rowFor[k]];
  const std::lock_guard<std::mutex> lock(f.solving);
  klu_common common = f.common;
  const int ok = transposed ? klu_tsolve(f.symbolic, f.numeric, n, 1, x.data(), &common)
                            : klu_solve(f.symbolic, f.numeric, n, 1, x.data(), &common);
  if (!ok) throw std::runtime_error("KLU solve failed (status " + std::to_string(common.status) + ")");
  if (!transposed) return x;
  Eigen::VectorXd y(n);
  for (int k = 0; k < n; ++k) y[f.rowFor[k]] = x[k];
  return y;
}

Eigen::VectorXd JacobianLU::solve(const Eigen::VectorXd& b) const { return solve(b, false); }
Eigen::VectorXd JacobianLU::solveTransposed(const Eigen::VectorXd& b) const { return solve(b, true); }
int JacobianLU::determinantSign() const { return factors_->sign; }
double JacobianLU::logAbsDeterminant() const {
  return factors_->sign ? factors_->logAbsDeterminant() : std::numeric_limits<double>::quiet_NaN();
}
bool JacobianLU::pivotsReused() const { return factors_->sign != 0 && factors_->reused; }
double JacobianLU::pivotRatio() const { return factors_->sign ? factors_->common.rcond : 0.0; }

std::size_t JacobianLU::factorEntries() const {
  const Factors& f = *factors_;
  return f.sign && f.numeric ? static_cast<std::size_t>(f.numeric->lnz) + static_cast<std::size_t>(f.numeric->unz) : 0;
}

double JacobianLU::estimatedFactorEntries(const Eigen::SparseMatrix<double>& pattern) {
  if (pattern.rows() != pattern.cols() || pattern.rows() == 0 || !pattern.isCompressed())
    throw std::invalid_argument("JacobianLU::estimatedFactorEntries: expected a square, non-empty, compressed matrix");
  klu_common common{};
  configure(common);
  // klu_analyze takes non-const arrays.
  std::vector<int> starts(pattern.outerIndexPtr(), pattern.outerIndexPtr() + pattern.cols() + 1);
  std::vector<int> rows(pattern.innerIndexPtr(), pattern.innerIndexPtr() + pattern.nonZeros());
  klu_symbolic* symbolic = klu_analyze(static_cast<int>(pattern.rows()), starts.data(), rows.data(), &common);
  if (!symbolic) return std::numeric_limits<double>::infinity();
  const double entries = symbolic->lnz + symbolic->unz;
  klu_free_symbolic(&symbolic, &common);
  return entries;
}

}  // namespace rodfab::mechanics
