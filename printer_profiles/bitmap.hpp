// 1-bit layer bitmaps in memory and their encodings: 1-bit BMP (our own small writer and reader: no
// well-kept library for it is packaged), 1-bit PNG (libpng), and RGB PNG for previews (libpng).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

using Bytes = std::vector<std::uint8_t>;

// A 1-bit image, row 0 at the top, bits packed most significant first (pixel 0 in bit 7 of byte 0),
// as both BMP and PNG store them. 1 = deposit the material. Its rows lie one after another top-down,
// or, made by inBmpFile, bottom-up inside the memory of a BMP file of the image.
class Bitmap {
public:
  Bitmap() = default;
  Bitmap(int width, int height);  // every pixel 0; std::invalid_argument unless both are positive
  // A bitmap whose memory is a 1-bit BMP file of it, headers (for xDpi x yDpi) and all: rows bottom-up,
  // padded to whole 32-bit words, as encodeBmp writes them. bmpFile() is then the file, with no row
  // copied: the job writer's layer bitmaps are made so (printer_profiles/README.md, "Emit, round 7").
  static Bitmap inBmpFile(int width, int height, int xDpi, int yDpi);

  int width() const { return width_; }
  int height() const { return height_; }
  std::size_t stride() const { return stride_; }  // bytes per row, ceil(width / 8)
  // Bytes from row r to row r + 1 in memory: stride() or more (a BMP file's padding), negative when the
  // rows lie bottom-up (inBmpFile). row(r) == row(0) + r * pitch().
  std::ptrdiff_t pitch() const { return pitch_; }

  bool get(int column, int row) const { return (this->row(row)[column >> 3] >> (7 - (column & 7))) & 1u; }
  void set(int column, int row, bool value = true) {
    std::uint8_t& b = this->row(row)[column >> 3];
    const std::uint8_t mask = static_cast<std::uint8_t>(0x80u >> (column & 7));
    b = value ? static_cast<std::uint8_t>(b | mask) : static_cast<std::uint8_t>(b & ~mask);
  }
  // Row r's stride() bytes (only those: a BMP file's row padding is not the caller's to write).
  std::uint8_t* row(int r) { return bits_.data() + rowOffset(r); }
  const std::uint8_t* row(int r) const { return bits_.data() + rowOffset(r); }
  // Every row's bytes as held (top-down, or bottom-up with a BMP file's padding, which is 0), nothing
  // else: for scans of the whole image that need not know where a row lies. Two bitmaps' pixelBytes()
  // line up byte for byte when they were made the same way (both by the constructor, or both by inBmpFile).
  std::span<const std::uint8_t> pixelBytes() const { return std::span<const std::uint8_t>(bits_).subspan(pixelsAt_); }
  // The BMP file holding the image, for a bitmap made by inBmpFile; empty for any other.
  std::span<const std::uint8_t> bmpFile() const { return pixelsAt_ > 0 ? std::span<const std::uint8_t>(bits_) : std::span<const std::uint8_t>(); }

  void clear();                // every pixel 0, keeping the memory (and a BMP file's headers)
  std::size_t count() const;  // pixels set
  // The same size and the same pixels, however each holds its rows.
  bool operator==(const Bitmap& other) const;

private:
  // Bytes of a row of `width` pixels, one bit each; std::invalid_argument unless both sizes are positive.
  static std::size_t checkedStride(int width, int height);
  std::ptrdiff_t rowOffset(int r) const { return first_ + static_cast<std::ptrdiff_t>(r) * pitch_; }

  int width_ = 0, height_ = 0;
  std::size_t stride_ = 0;
  std::ptrdiff_t first_ = 0, pitch_ = 0;  // row r at bits_[first_ + r * pitch_]; pitch_ < 0: bottom-up
  std::size_t pixelsAt_ = 0;              // where the rows begin (a BMP file's header size, or 0)
  std::vector<std::uint8_t> bits_;
};

// Bits set in `bytes`, and bits set in both `a` and `b` (same length). Word-wise, skipping zero words
// (layer bitmaps are mostly empty), with the CPU's popcount instruction where it has one.
std::size_t countSetBits(std::span<const std::uint8_t> bytes);
std::size_t countCommonBits(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b);

// A decoded 1-bit image with the resolution its file declared.
struct DecodedBitmap {
  Bitmap bitmap;
  int bitDepth = 0;
  // Pixels per metre as stored (BMP header fields; PNG pHYs chunk), 0 when the file has none.
  std::uint32_t xPixelsPerMetre = 0, yPixelsPerMetre = 0;
};

// Raised for files that are not the images they should be; the message says what was expected.
class ImageError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

// Nearest whole pixels per metre for a dpi, as BMP and PNG store resolution.
std::uint32_t pixelsPerMetre(int dpi);

// BMP: BITMAPINFOHEADER, two-entry palette (0 black, 1 white), rows bottom-up as the format's default.
Bytes encodeBmp(const Bitmap& bitmap, int xDpi, int yDpi);
// Accepts 1-bit BMPs with either row order whose file header gives the file's true size; the pixel
// value is the palette index (1 = deposit).
DecodedBitmap decodeBmp(std::span<const std::uint8_t> file);

// PNG: grayscale, bit depth 1 (1 = white = deposit), pHYs in pixels per metre, no row filter; the image
// data compressed by igzip at kLayerDeflateLevel (deflate.hpp), the chunks written by libpng.
Bytes encodePng1(const Bitmap& bitmap, int xDpi, int yDpi);
// 1-bit grayscale PNGs only (anything else is reported as the wrong bit depth or colour type). Throws
// ImageError before allocating when the header declares more than `maxPixels` pixels, or rows more
// than the file's bytes can hold at deflate's largest ratio (kMaxDeflateRatio).
inline constexpr std::uint64_t kMaxDeflateRatio = 1032;
DecodedBitmap decodePng1(std::span<const std::uint8_t> file, std::uint64_t maxPixels = UINT64_MAX);

// 8-bit RGB image, row-major, 3 bytes per pixel.
struct RgbImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> pixels;
  RgbImage() = default;
  RgbImage(int w, int h, std::uint8_t r, std::uint8_t g, std::uint8_t b);
  std::uint8_t* at(int x, int y) { return pixels.data() + (static_cast<std::size_t>(y) * width + x) * 3; }
  const std::uint8_t* at(int x, int y) const { return pixels.data() + (static_cast<std::size_t>(y) * width + x) * 3; }
};
// 8-bit RGB PNG without pHYs, compressed like encodePng1 (the previews; no row filter). The second form
// takes row r (3 * width bytes) from `row(r, out)` when the encoder needs it, in batches of about 1 MB.
// Throws ImageError when libpng fails, std::bad_alloc when memory runs out.
Bytes encodePngRgb(const RgbImage& image);
Bytes encodePngRgb(int width, int height, const std::function<void(int, std::uint8_t*)>& row);
RgbImage decodePngRgb(std::span<const std::uint8_t> file);  // 8-bit RGB PNGs only

// 8-bit RGBA PNG (colour type 6) with pHYs, for GrabCAD Voxel Print layers: `row(r, out)` fills row r
// (4 * width bytes) when the encoder needs it, in batches of about 1 MB, so no whole image is held.
// Compressed like encodePng1.
Bytes encodePngRgba(int width, int height, int xDpi, int yDpi, const std::function<void(int, std::uint8_t*)>& row);

struct RgbaHeader {
  int width = 0, height = 0;
  std::uint32_t xPixelsPerMetre = 0, yPixelsPerMetre = 0;  // 0 when the file has no pHYs in metres
};
// Reads an 8-bit RGBA PNG without interlacing (ImageError otherwise, or when it declares more than
// `maxPixels`, or is damaged): `begin(header)` once, then `row(r, pixels)` for every row top-down (4 bytes
// a pixel). Neither callback may throw. Memory: one row.
RgbaHeader decodePngRgba(std::span<const std::uint8_t> file, std::uint64_t maxPixels, const std::function<void(const RgbaHeader&)>& begin,
                         const std::function<void(int, const std::uint8_t*)>& row);

}  // namespace rodfab::printer_profiles
