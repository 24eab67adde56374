// Internal to printer_profiles/: a layer's model bitmaps as the band encoder fills them and the
// previews read them, with the record of where they were written.
#pragma once

#include "printer_profiles/bitmap.hpp"

#include <cassert>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace rodfab::printer_profiles {

// Bytes [begin, end) of a bitmap row (begin >= end: none).
struct RowSpan {
  std::uint32_t begin = 0, end = 0;
  bool empty() const { return begin >= end; }
};

// The model bitmaps of one layer as the band encoder fills them, with the 8-byte words of their rows
// written in (a bit a word): what clearing, counting and the views' scans read, exactly. Rods cross a
// row in a few places far apart; the span between them covered most of the spring's rows. The rigid
// and rubbery bitmaps are written only through a Writer, which marks every word it writes in, so no
// set bit lies outside a marked word. Support, when the job has it, is a bitmap of its own.
class LayerBitmaps {
public:
  LayerBitmaps() = default;
  // Empty bitmaps of width x height, each held in its BMP file (Bitmap::inBmpFile, at xDpi x yDpi).
  // std::invalid_argument unless both sizes are positive.
  LayerBitmaps(int width, int height, int xDpi, int yDpi);

  const Bitmap& rigid() const { return rigid_; }
  const Bitmap& rubbery() const { return rubbery_; }
  // The words written in row r: word w (bytes [8 w, 8 w + 8) of the row, the last may be short) is
  // bit w % 64 of the (w / 64)-th.
  std::span<const std::uint64_t> writtenWords(int r) const {
    return {marks_.data() + static_cast<std::size_t>(r) * perRow_, perRow_};
  }
  // Row r's bytes from its first written word to the end of its last: empty when none was written.
  RowSpan span(int r) const;
  // Clears the words written (and only those) and forgets them: the bitmaps are empty again.
  void clear();

  // Writes into the bitmaps, marking every word it writes in; valid while the LayerBitmaps lives and
  // is not assigned. It holds what it writes through itself: a byte stored through a uint8_t pointer
  // may alias any object, so pointers read through the LayerBitmaps would be read again after every
  // store (those reloads were the largest part of the rasterizer's samples on the lattice).
  class Writer {
  public:
    // ORs the 8 pixels of byte `byte` of row `row` into the rigid and the rubbery bitmap. Requires a
    // writer of bitmaps with rows (a default LayerBitmaps has none: its writer writes nowhere), row in
    // [0, height) and byte below the row's stride (checked in debug builds).
    void orByte(int row, std::size_t byte, std::uint8_t rigidBits, std::uint8_t rubberyBits) {
      assert(rigid_ != nullptr && row >= 0 && row < height_ && byte < stride_);
      rigid_[row * rigidPitch_ + static_cast<std::ptrdiff_t>(byte)] |= rigidBits;
      rubbery_[row * rubberyPitch_ + static_cast<std::ptrdiff_t>(byte)] |= rubberyBits;
      marks_[static_cast<std::size_t>(row) * perRow_ + byte / 512] |= std::uint64_t{1} << (byte / 8 % 64);
    }
    // orByte() of a leaf's 8 rows, rows firstRow - y for y = 0 .. 7 (image rows run against the leaf's
    // y), its pixels in byte y of rigidRows and rubberyRows; rows with no pixel in either are not touched.
    void orLeafRows(int firstRow, std::size_t byte, std::uint64_t rigidRows, std::uint64_t rubberyRows) {
      const std::uint64_t mark = std::uint64_t{1} << (byte / 8 % 64);
      // Row by row from firstRow down: the three places step back by a pitch each (no multiply a row).
      std::ptrdiff_t rigidAt = firstRow * rigidPitch_ + static_cast<std::ptrdiff_t>(byte);
      std::ptrdiff_t rubberyAt = firstRow * rubberyPitch_ + static_cast<std::ptrdiff_t>(byte);
      auto markAt = static_cast<std::ptrdiff_t>(static_cast<std::size_t>(firstRow) * perRow_ + byte / 512);
      const auto markPitch = static_cast<std::ptrdiff_t>(perRow_);
      for (int y = 0; y < 8; ++y, rigidAt -= rigidPitch_, rubberyAt -= rubberyPitch_, markAt -= markPitch) {
        const auto rigid = static_cast<std::uint8_t>(rigidRows >> (8 * y)), rubbery = static_cast<std::uint8_t>(rubberyRows >> (8 * y));
        if (!(rigid | rubbery)) continue;
        assert(rigid_ != nullptr && firstRow - y >= 0 && firstRow - y < height_ && byte < stride_);
        rigid_[rigidAt] |= rigid;
        rubbery_[rubberyAt] |= rubbery;
        marks_[markAt] |= mark;
      }
    }

  private:
    friend class LayerBitmaps;
    std::uint8_t* rigid_ = nullptr;    // row 0
    std::uint8_t* rubbery_ = nullptr;  // row 0
    std::ptrdiff_t rigidPitch_ = 0, rubberyPitch_ = 0;
    std::uint64_t* marks_ = nullptr;
    std::size_t perRow_ = 0;
    int height_ = 0;          // for the debug checks
    std::size_t stride_ = 0;  // bytes of a row holding pixels
  };
  Writer writer();

  Bitmap support;
  bool hasSupport = false;

private:
  Bitmap rigid_, rubbery_;
  std::size_t perRow_ = 0;             // masks a row: ceil(words / 64)
  std::vector<std::uint64_t> marks_;   // row r's at [r * perRow_, (r + 1) * perRow_)
};

}  // namespace rodfab::printer_profiles
