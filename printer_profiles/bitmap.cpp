// 1-bit bitmaps in memory and counting their bits; their file encodings (BMP, PNG) are in
// bitmap_encode.cpp.
#include "printer_profiles/bitmap.hpp"
#include "printer_profiles/popcount_clones.hpp"

#include <algorithm>
#include <bit>
#include <cstring>

namespace rodfab::printer_profiles {

std::size_t Bitmap::checkedStride(int width, int height) {
  if (width <= 0 || height <= 0) throw std::invalid_argument("bitmap size must be positive");
  return (static_cast<std::size_t>(width) + 7) / 8;
}

Bitmap::Bitmap(int width, int height) : width_(width), height_(height) {
  stride_ = checkedStride(width, height);
  pitch_ = static_cast<std::ptrdiff_t>(stride_);
  bits_.assign(stride_ * static_cast<std::size_t>(height), 0);
}

namespace {

RODFAB_POPCNT_CLONES std::size_t countWords(const std::uint8_t* a, const std::uint8_t* b, std::size_t size) {
  std::size_t n = 0, at = 0;
  for (; at + 8 <= size; at += 8) {
    std::uint64_t x, y = ~std::uint64_t{0};
    std::memcpy(&x, a + at, 8);
    if (b) std::memcpy(&y, b + at, 8);
    if (const std::uint64_t both = x & y) n += static_cast<std::size_t>(std::popcount(both));
  }
  for (; at < size; ++at) n += static_cast<std::size_t>(std::popcount(static_cast<std::uint8_t>(a[at] & (b ? b[at] : 0xff))));
  return n;
}

}  // namespace

std::size_t countSetBits(std::span<const std::uint8_t> bytes) { return countWords(bytes.data(), nullptr, bytes.size()); }

std::size_t countCommonBits(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b) {
  if (a.size() != b.size()) throw std::invalid_argument("countCommonBits: bitmaps of different sizes");
  return countWords(a.data(), b.data(), a.size());
}

// The rows (and a BMP file's row padding, which is never written and stays 0) lie in bits_[pixelsAt_, end).
void Bitmap::clear() { std::fill(bits_.begin() + static_cast<std::ptrdiff_t>(pixelsAt_), bits_.end(), std::uint8_t{0}); }

std::size_t Bitmap::count() const { return countSetBits(pixelBytes()); }

bool Bitmap::operator==(const Bitmap& other) const {
  if (width_ != other.width_ || height_ != other.height_) return false;
  for (int r = 0; r < height_; ++r)
    if (std::memcmp(row(r), other.row(r), stride_) != 0) return false;
  return true;
}

RgbImage::RgbImage(int w, int h, std::uint8_t r, std::uint8_t g, std::uint8_t b) : width(w), height(h) {
  pixels.resize(static_cast<std::size_t>(w) * h * 3);
  for (std::size_t i = 0; i < pixels.size(); i += 3) {
    pixels[i] = r;
    pixels[i + 1] = g;
    pixels[i + 2] = b;
  }
}

}  // namespace rodfab::printer_profiles
