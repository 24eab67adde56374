// Memory of a solve, estimated from the problem's sizes before the Jacobian is assembled or
// factorized: what the problem holds (counted from its containers), and what a solve adds at its
// peak (the Jacobian and JacobianLU's copies of it, KLU's factors from its symbolic analysis).
// Measured against the peak resident memory of `rodfab simulate` in tests/cli/simulate.sh.
#include "common/memory_budget.hpp"
#include "mechanics/discrete_structure.hpp"

#include <tbb/info.h>

#include <algorithm>

namespace rodfab::mechanics {

using namespace detail;

namespace {

template <class T> double bytesOf(const std::vector<T>& v) { return static_cast<double>(v.capacity() * sizeof(T)); }

double rodBytes(const DiscreteRod& r) {
  return bytesOf(r.tau) + bytesOf(r.basis) + bytesOf(r.constants) + bytesOf(r.sites) + bytesOf(r.sitePoints) +
         bytesOf(r.siteBelow) + bytesOf(r.siteBelowConstants) + bytesOf(r.curve.knots()) + bytesOf(r.curve.points()) +
         bytesOf(r.curve.weights()) + sizeof(DiscreteRod);
}

double nodeBytes(const Node& n) {
  double bytes = sizeof(Node) + bytesOf(n.ends) + bytesOf(n.offsets0) + bytesOf(n.relative0) + bytesOf(n.columns);
  for (const std::vector<int>& c : n.columns) bytes += bytesOf(c);
  return bytes;
}

double layoutBytes(const ItemLayout& layout) {
  double bytes = sizeof(ItemLayout) + bytesOf(layout.tiles);
  for (const Tile& t : layout.tiles) bytes += bytesOf(t.cols) + bytesOf(t.nonzero);
  return bytes;
}

// A compressed sparse matrix of n columns and nnz entries: values, row indices, column starts.
double sparseBytes(double n, double nnz) { return nnz * (sizeof(double) + sizeof(int)) + (n + 1) * sizeof(int); }

}  // namespace

SolveMemory StaticProblem::memoryEstimate() const {
  const DiscreteStructure& m = *structure_;
  double problem = sizeof(DiscreteStructure) + bytesOf(m.items) + bytesOf(m.slots) + bytesOf(m.layouts) +
                   static_cast<double>(m.reference.size()) * sizeof(double);
  for (const DiscreteRod& r : m.rods) problem += rodBytes(r);
  for (const Node& n : m.nodes) problem += nodeBytes(n);
  for (const ItemLayout& l : m.layouts) problem += layoutBytes(l);
  const double n = static_cast<double>(m.unknowns), nnz = static_cast<double>(m.pattern.nonZeros());
  problem += sparseBytes(n, nnz);

  // KLU's factors: AMD's count of L and U, every entry a value and a row index; klu_factor
  // allocates 1.2 times that and grows the block by 1.2 when pivoting needs more, the old copy
  // alive while it does. Its symbolic and numeric objects add some 30 words per unknown.
  const double factors = JacobianLU::estimatedFactorEntries(m.pattern) * (sizeof(double) + sizeof(int)) * 1.2 * 2.2 + 240 * n;
  // The Jacobian, JacobianLU's row-permuted copy, the copy of the pattern it analysed and the map
  // of values; while analysing, a matrix of entry numbers and its permuted product too.
  const double matrices = 4 * sparseBytes(n, nnz) + nnz * (sizeof(int) + sizeof(int)) + n * 2 * sizeof(int);
  // State, residual, corrections and their copies in Newton and the critical-point checks; the
  // per-thread scratch blocks of the assembly.
  std::size_t widest = 0;
  for (const ItemLayout& l : m.layouts) widest = std::max(widest, l.width);
  const double vectors = 24 * n * sizeof(double) + 7.0 * widest * sizeof(double) * tbb::info::default_concurrency();
  SolveMemory out;
  out.problem = common::saturatedBytes(problem);
  out.solve = common::saturatedBytes(factors + matrices + vectors);
  out.kept = common::saturatedBytes(factors + 2 * sparseBytes(n, nnz) + 2 * n * sizeof(double));
  return out;
}

}  // namespace rodfab::mechanics
