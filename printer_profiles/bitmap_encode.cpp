// The file encodings of bitmap.hpp's images: 1-bit BMP (written and read here), 1-bit, RGB and RGBA PNG
// (libpng, the image data compressed by igzip), and the bitmap made inside its own BMP file.
#include "printer_profiles/bitmap.hpp"

#include "printer_profiles/deflate.hpp"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <functional>

namespace rodfab::printer_profiles {

std::uint32_t pixelsPerMetre(int dpi) { return static_cast<std::uint32_t>(std::lround(dpi / 0.0254)); }

// ---------------------------------------------------------------------------------------------- BMP

namespace {

constexpr std::size_t kFileHeaderSize = 14;
constexpr std::size_t kInfoHeaderSize = 40;
constexpr std::size_t kPaletteSize = 8;

void put16(Bytes& out, std::size_t at, std::uint16_t v) {
  out[at] = static_cast<std::uint8_t>(v);
  out[at + 1] = static_cast<std::uint8_t>(v >> 8);
}
void put32(Bytes& out, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}
std::uint16_t get16(std::span<const std::uint8_t> in, std::size_t at) {
  return static_cast<std::uint16_t>(in[at] | (in[at + 1] << 8));
}
std::uint32_t get32(std::span<const std::uint8_t> in, std::size_t at) {
  return static_cast<std::uint32_t>(in[at]) | (static_cast<std::uint32_t>(in[at + 1]) << 8) |
         (static_cast<std::uint32_t>(in[at + 2]) << 16) | (static_cast<std::uint32_t>(in[at + 3]) << 24);
}

// BMP rows are padded to whole 32-bit words.
std::size_t bmpStride(int width) { return (static_cast<std::size_t>(width) + 31) / 32 * 4; }

constexpr std::size_t kBmpHeaders = kFileHeaderSize + kInfoHeaderSize + kPaletteSize;  // where the rows begin

// A 1-bit BMP file's headers and palette for a `width` x `height` image into out[0, kBmpHeaders).
void writeBmpHeaders(Bytes& out, int width, int height, int xDpi, int yDpi) {
  const std::size_t imageSize = bmpStride(width) * static_cast<std::size_t>(height);
  std::fill(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(kBmpHeaders), std::uint8_t{0});
  out[0] = 'B';
  out[1] = 'M';
  put32(out, 2, static_cast<std::uint32_t>(kBmpHeaders + imageSize));
  put32(out, 10, static_cast<std::uint32_t>(kBmpHeaders));
  put32(out, 14, kInfoHeaderSize);
  put32(out, 18, static_cast<std::uint32_t>(width));
  put32(out, 22, static_cast<std::uint32_t>(height));  // positive: bottom-up, the form every reader takes
  put16(out, 26, 1);                                    // planes
  put16(out, 28, 1);                                    // bits per pixel
  put32(out, 30, 0);                                    // BI_RGB, uncompressed
  put32(out, 34, static_cast<std::uint32_t>(imageSize));
  put32(out, 38, pixelsPerMetre(xDpi));
  put32(out, 42, pixelsPerMetre(yDpi));
  put32(out, 46, 2);  // palette entries
  put32(out, 50, 2);
  // Palette (blue, green, red, reserved): index 0 black, index 1 white.
  out[58] = out[59] = out[60] = 0xff;
}

}  // namespace

Bitmap Bitmap::inBmpFile(int width, int height, int xDpi, int yDpi) {
  Bitmap b;  // its bytes allocated once, as the BMP file's
  b.width_ = width;
  b.height_ = height;
  b.stride_ = checkedStride(width, height);
  const std::size_t stride = bmpStride(width);
  b.bits_.assign(kBmpHeaders + stride * static_cast<std::size_t>(height), 0);
  writeBmpHeaders(b.bits_, width, height, xDpi, yDpi);
  b.pixelsAt_ = kBmpHeaders;
  b.pitch_ = -static_cast<std::ptrdiff_t>(stride);
  b.first_ = static_cast<std::ptrdiff_t>(kBmpHeaders + stride * static_cast<std::size_t>(height - 1));  // row 0 is stored last
  return b;
}

Bytes encodeBmp(const Bitmap& bitmap, int xDpi, int yDpi) {
  const std::size_t stride = bmpStride(bitmap.width());
  Bytes out(kBmpHeaders + stride * static_cast<std::size_t>(bitmap.height()), 0);  // the rows' padding stays 0
  writeBmpHeaders(out, bitmap.width(), bitmap.height(), xDpi, yDpi);
  for (int r = 0; r < bitmap.height(); ++r)
    std::memcpy(out.data() + kBmpHeaders + static_cast<std::size_t>(bitmap.height() - 1 - r) * stride, bitmap.row(r), bitmap.stride());
  return out;
}

DecodedBitmap decodeBmp(std::span<const std::uint8_t> in) {
  if (in.size() < kFileHeaderSize + kInfoHeaderSize || in[0] != 'B' || in[1] != 'M')
    throw ImageError("not a BMP file (expected the 'BM' signature and a 54-byte header)");
  const std::uint32_t headerSize = get32(in, 14);
  if (headerSize < kInfoHeaderSize) throw ImageError("BMP header of " + std::to_string(headerSize) + " bytes; expected >= 40");
  const auto width = static_cast<std::int32_t>(get32(in, 18));
  const auto rawHeight = static_cast<std::int32_t>(get32(in, 22));
  const std::uint16_t bpp = get16(in, 28);
  const std::uint32_t compression = get32(in, 30);
  DecodedBitmap result;
  result.bitDepth = bpp;
  result.xPixelsPerMetre = get32(in, 38);
  result.yPixelsPerMetre = get32(in, 42);
  if (bpp != 1) throw ImageError("BMP has " + std::to_string(bpp) + " bits per pixel; expected 1");
  if (compression != 0) throw ImageError("BMP is compressed (method " + std::to_string(compression) + "); expected none");
  if (width <= 0 || rawHeight == 0 || rawHeight == INT32_MIN)
    throw ImageError("BMP size " + std::to_string(width) + " x " + std::to_string(rawHeight) + " is not a valid image size");
  const bool bottomUp = rawHeight > 0;
  const int height = bottomUp ? rawHeight : -rawHeight;

  std::uint32_t colours = get32(in, 46);
  if (colours == 0) colours = 2;
  const std::size_t paletteAt = kFileHeaderSize + headerSize;
  if (colours != 2 || in.size() < paletteAt + 8) throw ImageError("BMP palette is not the expected two entries");
  const auto brightness = [&](std::size_t at) { return in[at] + in[at + 1] + in[at + 2]; };
  if (brightness(paletteAt) != 0 || brightness(paletteAt + 4) != 3 * 255)
    throw ImageError("BMP palette is not (0 = black, 1 = white); expected 1 = deposit in white");

  const std::uint32_t offset = get32(in, 10);
  const std::size_t stride = bmpStride(width);
  const std::size_t need = static_cast<std::size_t>(offset) + stride * static_cast<std::size_t>(height);
  if (offset < paletteAt + 8 || in.size() < need)
    throw ImageError("BMP is truncated: " + std::to_string(in.size()) + " bytes, expected " + std::to_string(need));
  // The file header's own size field: a reader that trusts it (to allocate, or to find the end) must
  // get the truth, so a file that lies about its size is refused.
  if (const std::uint32_t declared = get32(in, 2); declared != in.size())
    throw ImageError("BMP file header says the file is " + std::to_string(declared) + " bytes; it is " + std::to_string(in.size()));
  result.bitmap = Bitmap(width, height);
  for (int r = 0; r < height; ++r) {
    const int fileRow = bottomUp ? height - 1 - r : r;
    std::memcpy(result.bitmap.row(r), in.data() + offset + static_cast<std::size_t>(fileRow) * stride,
                result.bitmap.stride());
  }
  // Bits past the last column are padding; clear them so equal images compare equal.
  if (const int spare = width % 8) {
    const auto keep = static_cast<std::uint8_t>(0xffu << (8 - spare));
    for (int r = 0; r < height; ++r) result.bitmap.row(r)[result.bitmap.stride() - 1] &= keep;
  }
  return result;
}

// ---------------------------------------------------------------------------------------------- PNG

namespace {

// libpng reports errors by longjmp; nothing with a destructor may live in a frame it jumps over, so
// the calls into libpng sit in small functions of plain data and C++ objects stay in the callers.
struct PngIo {
  Bytes* out = nullptr;
  const std::uint8_t* in = nullptr;
  std::size_t inSize = 0, pos = 0;
  std::size_t readLimit = SIZE_MAX;  // reading past this offset is an error (set once the rows are read)
  bool outOfMemory = false;
  char error[256] = {};
};

// What a PNG may still hold once its rows are read: the end of its deflate stream, IEND and a few small
// chunks (and libpng's 8 KiB read ahead). libpng inflates whatever image data follows the rows (to
// discard it), so a GCVF whose layers' data went on to inflate to 1 GB of zeros each kept inspect busy
// for minutes; 32 KiB of deflate inflates to at most 33 MB.
constexpr std::size_t kBytesAfterRows = std::size_t{32} << 10;

void pngError(png_structp png, png_const_charp message) {
  auto* io = static_cast<PngIo*>(png_get_error_ptr(png));
  std::snprintf(io->error, sizeof io->error, "%s", message);
  png_longjmp(png, 1);
}
void pngWarning(png_structp, png_const_charp) {}

void pngWrite(png_structp png, png_bytep data, png_size_t length) {
  auto* io = static_cast<PngIo*>(png_get_io_ptr(png));
  try {
    io->out->insert(io->out->end(), data, data + length);
  } catch (const std::bad_alloc&) {
    io->outOfMemory = true;
    png_error(png, "out of memory");
  }
}
void pngFlush(png_structp) {}

void pngRead(png_structp png, png_bytep data, png_size_t length) {
  auto* io = static_cast<PngIo*>(png_get_io_ptr(png));
  if (io->inSize - io->pos < length) png_error(png, "file is truncated");
  if (io->pos + length > io->readLimit)
    png_error(png, "more than 32 KiB of data follow the image's rows (image data its rows do not need?)");
  std::memcpy(data, io->in + io->pos, length);
  io->pos += length;
}

struct PngWriteSpec {
  png_uint_32 width, height;
  int bitDepth, colourType;
  png_uint_32 xPpm, yPpm;  // 0: no pHYs chunk
  std::size_t stride;      // bytes a row
};

// Layer images and previews: libpng writes the signature, IHDR and pHYs and frames every chunk
// (length, CRC), but its row interface compresses with zlib, and it has no way to take image data
// compressed elsewhere. So the rows are compressed by igzip (zlib-wrapped, deflate.hpp) and handed to
// libpng's png_write_chunk as IDAT chunks, then IEND: a standard PNG any decoder reads, made by libpng.
constexpr std::size_t kIdatChunkBytes = std::size_t{1} << 18;

// The PNG of `spec` whose image data is `zlibData`, through libpng's write structs on `io`; false when
// libpng failed (io.error says why). libpng's longjmp lands here, so nothing in this frame has a
// destructor: the buffers live in the caller.
bool writePngWithIdat(PngIo& io, const PngWriteSpec& spec, std::span<const std::uint8_t> zlibData) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &io, pngError, pngWarning);
  if (!png) return false;
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, &io, pngWrite, pngFlush);
  png_set_IHDR(png, info, spec.width, spec.height, spec.bitDepth, spec.colourType, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (spec.xPpm) png_set_pHYs(png, info, spec.xPpm, spec.yPpm, PNG_RESOLUTION_METER);
  png_write_info(png, info);
  for (std::size_t at = 0; at < zlibData.size(); at += kIdatChunkBytes)
    png_write_chunk(png, reinterpret_cast<png_const_bytep>("IDAT"), zlibData.data() + at, std::min(kIdatChunkBytes, zlibData.size() - at));
  png_write_chunk(png, reinterpret_cast<png_const_bytep>("IEND"), nullptr, 0);
  png_destroy_write_struct(&png, &info);
  return true;
}

// The image data of a PNG whose rows all use filter type 0 (None): each row prefixed by a zero byte,
// compressed at the layer level. Rows come from `rowAt` in batches of about a megabyte, so a large
// RGBA layer is never held whole; the batches depend only on the image size (deterministic bytes).
Bytes compressUnfilteredRows(png_uint_32 height, std::size_t stride, const std::function<void(int, std::uint8_t*)>& rowAt) {
  const std::size_t line = stride + 1;
  const std::size_t batchRows = std::max<std::size_t>(1, (std::size_t{1} << 20) / line);
  std::vector<std::uint8_t> batch(std::min<std::size_t>(batchRows, height) * line, 0);
  if (batchRows >= height) {  // the whole image in one piece: igzip's one-shot path
    for (png_uint_32 r = 0; r < height; ++r) rowAt(static_cast<int>(r), batch.data() + r * line + 1);
    if (deflateWouldNotShrink(batch, kLayerDeflateLevel)) return deflateStored(batch, DeflateWrapper::Zlib);  // dithered noise
    return deflateBytes(batch, kLayerDeflateLevel, DeflateWrapper::Zlib);
  }
  DeflateStream stream(kLayerDeflateLevel, DeflateWrapper::Zlib);
  for (png_uint_32 r0 = 0; r0 < height; r0 += static_cast<png_uint_32>(batchRows)) {
    const png_uint_32 r1 = static_cast<png_uint_32>(std::min<std::size_t>(height, r0 + batchRows));
    for (png_uint_32 r = r0; r < r1; ++r) rowAt(static_cast<int>(r), batch.data() + (r - r0) * line + 1);
    stream.add(std::span(batch.data(), (r1 - r0) * line), r1 == height);
  }
  return stream.take();
}

// Every PNG rodfab writes (1-bit and RGBA layers, RGB previews): the rows from `rowAt`, unfiltered,
// compressed by igzip at the layer level, framed by libpng.
Bytes encodeUnfilteredPng(const PngWriteSpec& spec, const std::function<void(int, std::uint8_t*)>& rowAt) {
  const Bytes zlibData = compressUnfilteredRows(spec.height, spec.stride, rowAt);
  Bytes out;
  out.reserve(zlibData.size() + 128);
  PngIo io;
  io.out = &out;
  if (!writePngWithIdat(io, spec, zlibData)) {
    if (io.outOfMemory) throw std::bad_alloc();
    throw ImageError(std::string("PNG encoding failed: ") + io.error);
  }
  return out;
}

struct PngHeader {
  png_uint_32 width = 0, height = 0;
  int bitDepth = 0, colourType = 0, interlace = 0;
  png_uint_32 xPpm = 0, yPpm = 0;
};

class PngReader {
public:
  explicit PngReader(std::span<const std::uint8_t> file) {
    io_.in = file.data();
    io_.inSize = file.size();
    png_ = png_create_read_struct(PNG_LIBPNG_VER_STRING, &io_, pngError, pngWarning);
    if (png_) info_ = png_create_info_struct(png_);
    if (!png_ || !info_) throw std::bad_alloc();
  }
  ~PngReader() { png_destroy_read_struct(&png_, &info_, nullptr); }
  PngReader(const PngReader&) = delete;
  PngReader& operator=(const PngReader&) = delete;

  PngHeader header() {
    if (io_.inSize < 8 || png_sig_cmp(io_.in, 0, 8) != 0) throw ImageError("not a PNG file (no PNG signature)");
    PngHeader h;
    if (!readHeader(h)) fail();
    return h;
  }
  void rows(std::uint8_t* data, std::size_t stride, png_uint_32 height) {
    if (!readRows(data, stride, height)) fail();
  }
  // Each row into `buffer` (one row), then `use(r, buffer)`; `use` must not throw.
  void eachRow(std::uint8_t* buffer, png_uint_32 height, const std::function<void(int, const std::uint8_t*)>& use) {
    if (!readEachRow(buffer, height, use)) fail();
  }

private:
  [[noreturn]] void fail() { throw ImageError(std::string("PNG is damaged: ") + io_.error); }

  bool readHeader(PngHeader& h) {
    if (setjmp(png_jmpbuf(png_))) return false;
    png_set_read_fn(png_, &io_, pngRead);
    png_read_info(png_, info_);
    png_get_IHDR(png_, info_, &h.width, &h.height, &h.bitDepth, &h.colourType, &h.interlace, nullptr, nullptr);
    int unit = 0;
    if (png_get_pHYs(png_, info_, &h.xPpm, &h.yPpm, &unit) && unit != PNG_RESOLUTION_METER) h.xPpm = h.yPpm = 0;
    return true;
  }
  bool readEachRow(std::uint8_t* buffer, png_uint_32 height, const std::function<void(int, const std::uint8_t*)>& use) {
    if (setjmp(png_jmpbuf(png_))) return false;
    for (png_uint_32 r = 0; r < height; ++r) {
      if (r + 1 == height) limitReadingAfterRows();
      png_read_row(png_, buffer, nullptr);
      use(static_cast<int>(r), buffer);
    }
    png_read_end(png_, nullptr);
    return true;
  }
  bool readRows(std::uint8_t* data, std::size_t stride, png_uint_32 height) {
    if (setjmp(png_jmpbuf(png_))) return false;
    for (png_uint_32 r = 0; r < height; ++r) {
      if (r + 1 == height) limitReadingAfterRows();
      png_read_row(png_, data + r * stride, nullptr);
    }
    png_read_end(png_, nullptr);
    return true;
  }
  // Before the last row is read: libpng discards the image data that follows it within that call.
  // Room for the row itself, stored (deflate's 5 bytes per 64 KiB), and kBytesAfterRows.
  void limitReadingAfterRows() {
    const std::size_t row = png_get_rowbytes(png_, info_) + 1;
    io_.readLimit = io_.pos + row + row / 8192 + 64 + kBytesAfterRows;
  }

  PngIo io_;
  png_structp png_ = nullptr;
  png_infop info_ = nullptr;
};

}  // namespace

Bytes encodePng1(const Bitmap& bitmap, int xDpi, int yDpi) {
  const PngWriteSpec spec{static_cast<png_uint_32>(bitmap.width()), static_cast<png_uint_32>(bitmap.height()), 1,
                          PNG_COLOR_TYPE_GRAY, pixelsPerMetre(xDpi), pixelsPerMetre(yDpi), bitmap.stride()};
  return encodeUnfilteredPng(spec, [&](int r, std::uint8_t* out) { std::memcpy(out, bitmap.row(r), bitmap.stride()); });
}

DecodedBitmap decodePng1(std::span<const std::uint8_t> file, std::uint64_t maxPixels) {
  PngReader reader(file);
  const PngHeader h = reader.header();
  // Both bounds before the bitmap is allocated: a 700-byte PNG declaring 10^6 x 24,000 pixels took
  // inspect to 3 GB before libpng found its data short (a hostile-input review). Deflate expands by
  // at most 1,032 to 1, so no file holds rows of more than that many times its own size.
  const std::uint64_t rowBytes = 1 + (std::uint64_t(h.width) + 7) / 8;
  if (std::uint64_t(h.width) * h.height > maxPixels)
    throw ImageError("PNG declares " + std::to_string(h.width) + " x " + std::to_string(h.height) + " pixels, more than expected");
  if (rowBytes * h.height > kMaxDeflateRatio * file.size())
    throw ImageError("PNG declares " + std::to_string(h.width) + " x " + std::to_string(h.height) + " pixels, more than its " +
                     std::to_string(file.size()) + " bytes can hold");
  DecodedBitmap result;
  result.bitDepth = h.bitDepth;
  result.xPixelsPerMetre = h.xPpm;
  result.yPixelsPerMetre = h.yPpm;
  if (h.colourType != PNG_COLOR_TYPE_GRAY)
    throw ImageError("PNG colour type " + std::to_string(h.colourType) + "; expected 0 (grayscale)");
  if (h.bitDepth != 1) throw ImageError("PNG has " + std::to_string(h.bitDepth) + " bits per pixel; expected 1");
  if (h.interlace != PNG_INTERLACE_NONE) throw ImageError("PNG is interlaced; expected no interlacing");
  result.bitmap = Bitmap(static_cast<int>(h.width), static_cast<int>(h.height));
  reader.rows(result.bitmap.row(0), result.bitmap.stride(), h.height);
  return result;
}

Bytes encodePngRgb(const RgbImage& image) {
  const std::size_t stride = static_cast<std::size_t>(image.width) * 3;
  return encodePngRgb(image.width, image.height, [&](int r, std::uint8_t* out) {
    std::memcpy(out, image.pixels.data() + static_cast<std::size_t>(r) * stride, stride);
  });
}

Bytes encodePngRgb(int width, int height, const std::function<void(int, std::uint8_t*)>& row) {
  // No filter, igzip level 0: measured on the previews of the four benchmark classes and the bundled
  // examples (printer_profiles/README.md, "Emit, round 10"), 7 to 15 times faster than libpng's
  // adaptive filters with zlib level 6, for files 1.4 to 2 times larger (a few hundred kB a job).
  const PngWriteSpec spec{static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8, PNG_COLOR_TYPE_RGB, 0, 0,
                          static_cast<std::size_t>(width) * 3};
  return encodeUnfilteredPng(spec, row);
}

RgbImage decodePngRgb(std::span<const std::uint8_t> file) {
  PngReader reader(file);
  const PngHeader h = reader.header();
  if (h.colourType != PNG_COLOR_TYPE_RGB || h.bitDepth != 8 || h.interlace != PNG_INTERLACE_NONE)
    throw ImageError("PNG is not 8-bit RGB without interlacing");
  RgbImage image(static_cast<int>(h.width), static_cast<int>(h.height), 0, 0, 0);
  reader.rows(image.pixels.data(), static_cast<std::size_t>(image.width) * 3, h.height);
  return image;
}

Bytes encodePngRgba(int width, int height, int xDpi, int yDpi, const std::function<void(int, std::uint8_t*)>& row) {
  // No filter: layers are long runs of one colour, which deflate finds as 4-byte repeats. Measured
  // with zlib on arm-cast (1,167 layers of 1768 x 753): 16.5 s CPU and 50.2 MB for the job, against
  // 25.1 s and 47.9 MB with the Sub filter. igzip compresses now (printer_profiles/README.md).
  const PngWriteSpec spec{static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8, PNG_COLOR_TYPE_RGBA,
                          pixelsPerMetre(xDpi), pixelsPerMetre(yDpi), static_cast<std::size_t>(width) * 4};
  return encodeUnfilteredPng(spec, row);
}

RgbaHeader decodePngRgba(std::span<const std::uint8_t> file, std::uint64_t maxPixels,
                         const std::function<void(const RgbaHeader&)>& begin, const std::function<void(int, const std::uint8_t*)>& row) {
  PngReader reader(file);
  const PngHeader h = reader.header();
  if (h.colourType != PNG_COLOR_TYPE_RGBA || h.bitDepth != 8)
    throw ImageError("PNG colour type " + std::to_string(h.colourType) + " with " + std::to_string(h.bitDepth) +
                     "-bit samples; expected 6 (RGBA) with 8-bit samples");
  if (h.interlace != PNG_INTERLACE_NONE) throw ImageError("PNG is interlaced; expected no interlacing");
  if (static_cast<std::uint64_t>(h.width) * h.height > maxPixels)
    throw ImageError("PNG declares " + std::to_string(h.width) + " x " + std::to_string(h.height) + " pixels, more than expected");
  const RgbaHeader header{static_cast<int>(h.width), static_cast<int>(h.height), h.xPpm, h.yPpm};
  begin(header);
  std::vector<std::uint8_t> buffer(static_cast<std::size_t>(h.width) * 4);
  reader.eachRow(buffer.data(), h.height, row);
  return header;
}

}  // namespace rodfab::printer_profiles
