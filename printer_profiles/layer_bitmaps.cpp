#include "printer_profiles/layer_bitmaps.hpp"

#include <algorithm>
#include <bit>
#include <cstring>

namespace rodfab::printer_profiles {

LayerBitmaps::LayerBitmaps(int width, int height, int xDpi, int yDpi)
    : rigid_(Bitmap::inBmpFile(width, height, xDpi, yDpi)), rubbery_(Bitmap::inBmpFile(width, height, xDpi, yDpi)),
      perRow_((rigid_.stride() + 511) / 512), marks_(perRow_ * static_cast<std::size_t>(height), 0) {}

RowSpan LayerBitmaps::span(int r) const {
  const std::span<const std::uint64_t> words = writtenWords(r);
  const auto first = std::find_if(words.begin(), words.end(), [](std::uint64_t m) { return m != 0; });
  if (first == words.end()) return {};
  const auto last = std::find_if(words.rbegin(), words.rend(), [](std::uint64_t m) { return m != 0; });
  const std::size_t firstWord = static_cast<std::size_t>(first - words.begin()) * 64 + static_cast<std::size_t>(std::countr_zero(*first));
  const std::size_t lastWord = static_cast<std::size_t>(words.rend() - last - 1) * 64 + 63 - static_cast<std::size_t>(std::countl_zero(*last));
  return {static_cast<std::uint32_t>(firstWord * 8), static_cast<std::uint32_t>(std::min((lastWord + 1) * 8, rigid_.stride()))};
}

void LayerBitmaps::clear() {
  const std::size_t stride = rigid_.stride();
  for (int r = 0; r < rigid_.height(); ++r) {
    std::uint8_t* rigid = rigid_.row(r);
    std::uint8_t* rubbery = rubbery_.row(r);
    for (std::size_t m = 0; m < perRow_; ++m)
      for (std::uint64_t& bits = marks_[static_cast<std::size_t>(r) * perRow_ + m]; bits; bits &= bits - 1) {
        const std::size_t at = (m * 64 + static_cast<std::size_t>(std::countr_zero(bits))) * 8;
        if (at + 8 <= stride) {  // a store each, not a memset call
          constexpr std::uint64_t kZero = 0;
          std::memcpy(rigid + at, &kZero, 8);
          std::memcpy(rubbery + at, &kZero, 8);
        } else {  // a row's last word may be short
          std::memset(rigid + at, 0, stride - at);
          std::memset(rubbery + at, 0, stride - at);
        }
      }
  }
}

LayerBitmaps::Writer LayerBitmaps::writer() {
  Writer w;
  if (rigid_.height() == 0) return w;  // nothing to write into
  w.rigid_ = rigid_.row(0);
  w.rubbery_ = rubbery_.row(0);
  w.rigidPitch_ = rigid_.pitch();
  w.rubberyPitch_ = rubbery_.pitch();
  w.marks_ = marks_.data();
  w.perRow_ = perRow_;
  w.height_ = rigid_.height();
  w.stride_ = std::min(rigid_.stride(), rubbery_.stride());
  return w;
}

}  // namespace rodfab::printer_profiles
