// Deflate for the job's layer images, with ISA-L's igzip (Debian libisal-dev): raw deflate for zip
// entries and zlib-wrapped deflate for PNG IDAT data, plus the zip CRC-32. Chosen by measurement on
// real layer images (printer_profiles/README.md, "Compressing layer images"): igzip is 15 to 50 times
// faster than zlib level 1 here.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

struct isal_zstream;

namespace rodfab::printer_profiles {

// The igzip level the job writer uses for layer images (0 to 3; see the README's table). Level 0, not
// 1 or 2: on our 2-core test machine levels 1 and 2 (igzip's ICF path) gave a different, equally valid
// stream for about one image in 2,000 in one process of five under load; level 0 never did (README,
// "Same bytes every run"). Its streams are about 1.5 times larger and it compresses twice as fast.
inline constexpr int kLayerDeflateLevel = 0;

enum class DeflateWrapper {
  Raw,   // RFC 1951 deflate, as a zip entry of method 8 holds it
  Zlib,  // RFC 1950: 2-byte header, deflate, Adler-32 of the input, as a PNG's IDAT data holds it
};

// Compresses `input` in one piece at igzip `level` (0 to 3; std::invalid_argument otherwise). The
// bytes depend only on the input, the level and the wrapper on a given build and CPU (igzip picks its
// SIMD code at load time); any inflater reads them. Throws std::bad_alloc when memory runs out.
// Thread-safe: each thread keeps its own working buffers.
std::vector<std::uint8_t> deflateBytes(std::span<const std::uint8_t> input, int level, DeflateWrapper wrapper);

// Whether deflating `input` at igzip `level` would save less than an eighth of it, judged on sixteen
// samples (each 1/128 of it, at least 2 KiB, one centred in each sixteenth) deflated alone: true for a
// layer image filled with dithered noise, on which igzip's level 0 spends 2 ns a byte to end in stored
// blocks or save a few per cent. Stops once the samples saved an eighth, so an image that is mostly
// blank costs two or three samples. Always false for inputs under 64 KiB. The answer depends only on
// the input (on a given build and CPU). Thread-safe; std::invalid_argument for a level outside 0..3.
bool deflateWouldNotShrink(std::span<const std::uint8_t> input, int level);

// Raw deflate by zlib at level 9 (Debian zlib1g): up to ten times smaller than igzip's level 0 on
// blank images (a 6.5 MB all-zero layer: 6.5 KB against 60 KB) and twenty times slower (80 MB/s), so
// only for bytes compressed once and stored many times, as a job's blank layer image is. zlib's output
// depends only on the input on a given build. Throws std::bad_alloc when memory runs out.
std::vector<std::uint8_t> deflateSmallest(std::span<const std::uint8_t> input);

// `input` in deflate's stored blocks (zlib at level 0), raw or zlib-wrapped: for data that
// deflateWouldNotShrink says is not worth compressing but must be a deflate stream (a PNG's IDAT).
// Copies at memory speed (plus zlib's Adler-32 for the zlib wrapper). Throws std::bad_alloc when
// memory runs out.
std::vector<std::uint8_t> deflateStored(std::span<const std::uint8_t> input, DeflateWrapper wrapper);

// The same, fed in pieces, for data too large to hold at once (a layer's RGBA rows): memory is the
// compressed output and ~0.5 MB of igzip state. The bytes depend on the pieces' boundaries as well as
// on the input, so callers cut their input the same way every time (whole rows in fixed batches).
class DeflateStream {
public:
  DeflateStream(int level, DeflateWrapper wrapper);  // std::invalid_argument for a level outside 0..3
  ~DeflateStream();
  DeflateStream(const DeflateStream&) = delete;
  DeflateStream& operator=(const DeflateStream&) = delete;

  // Compresses the next piece; `last` ends the stream (nothing may be added after it).
  void add(std::span<const std::uint8_t> piece, bool last);
  // The compressed bytes, once the last piece has been added (std::logic_error before).
  std::vector<std::uint8_t> take();

private:
  std::unique_ptr<isal_zstream> stream_;
  std::vector<std::uint8_t> levelBuffer_, out_;
  std::size_t produced_ = 0;
  bool ended_ = false;
};

// Inflates raw deflate `input` into `output`, whose size is the size the data must have (a zip entry's
// recorded size). Returns the CRC-32 (zipCrc32) of the output, or nullopt when the data is damaged or
// inflates to another size. Thread-safe.
std::optional<std::uint32_t> inflateRaw(std::span<const std::uint8_t> input, std::span<std::uint8_t> output);

// Raw deflate decoded piece by piece (a zip entry read in chunks), with the CRC-32 of the output:
// memory is igzip's state and one output buffer of 64 KiB, whatever the data inflates to.
class InflateStream {
public:
  enum class Status {
    More,     // all input consumed; the stream has not ended
    End,      // the final block has ended (input after it is ignored)
    Damaged,  // invalid deflate data
  };
  InflateStream();
  ~InflateStream();
  InflateStream(const InflateStream&) = delete;
  InflateStream& operator=(const InflateStream&) = delete;

  // Decodes `input`, passing each piece of output (at most 64 KiB) to `sink` as it comes; whatever
  // `sink` throws passes through (the stream is then unusable).
  template <class Sink>
  Status add(std::span<const std::uint8_t> input, Sink&& sink) {
    feed(input);
    for (;;) {
      const Status status = step();
      if (!pending().empty()) sink(pending());
      // A full buffer may leave output inside igzip even when the input is used up: call again.
      if (status != Status::More || (inputLeft() == 0 && pending().size() < buffer_.size())) return status;
    }
  }
  // The CRC-32 (zipCrc32) of all output, once add() has returned End.
  std::uint32_t crc() const;

private:
  void feed(std::span<const std::uint8_t> input);
  Status step();  // one call into igzip, filling the output buffer
  std::span<const std::uint8_t> pending() const { return {buffer_.data(), pendingBytes_}; }
  std::size_t inputLeft() const;

  struct State;
  std::unique_ptr<State> state_;
  std::vector<std::uint8_t> buffer_;
  std::size_t pendingBytes_ = 0;
  bool ended_ = false;
};

// The CRC-32 of zip and gzip (IEEE 802.3, reflected) of `data`, continuing from `crc` (0 to start).
std::uint32_t zipCrc32(std::span<const std::uint8_t> data, std::uint32_t crc = 0);

}  // namespace rodfab::printer_profiles
