// The heap the tests weigh memory estimates against: glibc's bytes in use now, every arena plus the
// blocks it mapped directly (mallinfo2).
#pragma once

#include <malloc.h>

#include <cstdint>

namespace rodfab::tests {

inline std::uint64_t heapBytesInUse() {
  const struct mallinfo2 m = mallinfo2();
  return std::uint64_t(m.uordblks) + std::uint64_t(m.hblkhd);
}

}  // namespace rodfab::tests
