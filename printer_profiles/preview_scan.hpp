// Internal to printer_profiles/previews*.cpp: what the views' scans share. A view decides each of its
// pixels once, from the first voxel seen along its direction (forEachFresh), and colours it by the
// modulus there (modulusAt).
#pragma once

#include "printer_profiles/previews.hpp"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <limits>

namespace rodfab::printer_profiles::preview_scan {

inline constexpr float kNoModulus = std::numeric_limits<float>::quiet_NaN();

// The modulus at `ijk` (MPa), kNoModulus where the grid has no active voxel or there is no grid.
inline float modulusAt(const openvdb::FloatGrid* grid, openvdb::FloatGrid::ConstAccessor* acc, const openvdb::Coord& ijk) {
  if (!grid || !acc) return kNoModulus;
  float v = 0.0f;
  return acc->probeValue(ijk, v) ? v : kNoModulus;
}

// Calls visit(column, isRigid) for the pixels of a row's `span` (rigid or rubbery) not yet in `claimed`, left
// to right, and adds them to `claimed`: a view decides each of its pixels once. Skips a word at a
// time where there is nothing new (layers are mostly empty, columns soon claimed).
template <class Visit>
void forEachFresh(const std::uint8_t* rigid, const std::uint8_t* rubbery, std::uint8_t* claimed, RowSpan span, Visit&& visit) {
  for (std::size_t at = span.begin; at < span.end; at += 8) {
    const std::size_t n = std::min<std::size_t>(8, span.end - at);
    std::uint64_t a = 0, b = 0, c = 0;
    std::memcpy(&a, rigid + at, n);
    std::memcpy(&b, rubbery + at, n);
    std::memcpy(&c, claimed + at, n);
    if (!((a | b) & ~c)) continue;
    for (std::size_t byte = at; byte < at + n; ++byte) {
      const auto fresh = static_cast<unsigned>((rigid[byte] | rubbery[byte]) & ~claimed[byte] & 0xffu);
      if (!fresh) continue;
      claimed[byte] = static_cast<std::uint8_t>(claimed[byte] | fresh);
      for (unsigned bits = fresh; bits; bits &= bits - 1) {
        const int bit = 7 - std::countr_zero(bits);
        visit(static_cast<int>(byte) * 8 + bit, ((rigid[byte] >> (7 - bit)) & 1) != 0);
      }
    }
  }
}

// forEachFresh over the words `b` wrote in row r (LayerBitmaps::writtenWords), the only ones that can
// hold anything. Rods cross a row in a few places; the span between them covered most of the spring's rows.
template <class Visit>
void forEachFreshInRow(const LayerBitmaps& b, int r, std::uint8_t* claimed, Visit&& visit) {
  const std::uint8_t* rigid = b.rigid().row(r);
  const std::uint8_t* rubbery = b.rubbery().row(r);
  const auto stride = static_cast<std::uint32_t>(b.rigid().stride());
  const std::span<const std::uint64_t> words = b.writtenWords(r);
  for (std::size_t m = 0; m < words.size(); ++m)
    for (std::uint64_t bits = words[m]; bits; bits &= bits - 1) {
      const auto at = static_cast<std::uint32_t>((m * 64 + static_cast<std::size_t>(std::countr_zero(bits))) * 8);
      forEachFresh(rigid, rubbery, claimed, RowSpan{at, std::min(at + 8, stride)}, visit);
    }
}

}  // namespace rodfab::printer_profiles::preview_scan
