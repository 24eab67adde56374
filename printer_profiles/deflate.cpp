#include "printer_profiles/deflate.hpp"

#include <isa-l/crc.h>
#include <isa-l/igzip_lib.h>
#include <zlib.h>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>

namespace rodfab::printer_profiles {

namespace {

#if defined(__x86_64__)
__attribute__((target("avx"))) void zeroUpperVectorHalves() { _mm256_zeroupper(); }
#endif

// igzip's and the CRC's vector code return with the upper halves of the vector registers dirty, and
// until something clears them every legacy SSE instruction on the thread runs slowly: XXH3 (libxxhash,
// SSE2) hashed a layer image at 3.7 GB/s after an igzip call and 16 GB/s after this (bench/README.md,
// "Emit, round 4"). Not only the AVX-512 paths: ISA-L 2.30's AVX2 ones need it too, and Debian's build
// of libisal2 (2.30.0) has no vzeroupper anywhere (objdump: 0 of them, 1,322 ymm and 1,380 zmm
// instructions). Called after every call into ISA-L.
void afterIsal() {
#if defined(__x86_64__)
  static const bool avx = __builtin_cpu_supports("avx");
  if (avx) zeroUpperVectorHalves();
#endif
}

std::size_t levelBufferSize(int level) {
  switch (level) {
    case 0: return ISAL_DEF_LVL0_DEFAULT;
    case 1: return ISAL_DEF_LVL1_DEFAULT;
    case 2: return ISAL_DEF_LVL2_DEFAULT;
    default: return ISAL_DEF_LVL3_DEFAULT;
  }
}

// Room for stored blocks (5 bytes per 64 KiB), a dynamic header, a wrapper and slack: igzip falls back
// to stored blocks when compressing would not fit, so this always suffices; the retry is a safeguard.
std::size_t outputBound(std::size_t in) { return in + in / 8192 + ISAL_DEF_MAX_HDR_SIZE + 64; }

void checkLevel(int level) {
  if (level < 0 || level > ISAL_DEF_MAX_LEVEL)
    throw std::invalid_argument("deflate level " + std::to_string(level) + " is not one of igzip's 0 to " +
                                std::to_string(ISAL_DEF_MAX_LEVEL));
}

// The thread's igzip stream, its fields before the history buffer cleared. The stream is 82 kB, nearly
// all of it the history buffer and hash heads of igzip's stateful mode, and clearing it all was 3 % of
// a lattice job's writer instructions. The stateless pass never reads the history buffer, and the
// heads it reads it has set first (reset_match_history): under valgrind's memcheck a stream left
// uninitialised there gave no error of its own at levels 0 to 3, and on this CPU's AVX-512 paths one
// filled with random bytes gave the bytes of a cleared one (printer_profiles/README.md, "Emit, round 13").
// stateless_init leaves fields igzip reads (hist_bits among them) unset, hence the clearing first.
isal_zstream& clearedStatelessStream() {
  thread_local const std::unique_ptr<isal_zstream> stream = std::make_unique<isal_zstream>();
  std::memset(stream.get(), 0, offsetof(isal_zstream, internal_state) + offsetof(isal_zstate, buffer));
  return *stream;
}

// One stateless compression into `out`: the bytes written, or nullopt when `out` was too small.
std::optional<std::size_t> compressOnce(std::span<const std::uint8_t> input, int level, DeflateWrapper wrapper, std::span<std::uint8_t> out) {
  thread_local std::vector<std::uint8_t> levelBuffer;
  levelBuffer.resize(std::max(levelBuffer.size(), levelBufferSize(level)));
  isal_zstream& stream = clearedStatelessStream();
  isal_deflate_stateless_init(&stream);
  stream.hist_bits = ISAL_DEF_MAX_HIST_BITS;
  stream.level = static_cast<std::uint32_t>(level);
  stream.level_buf = levelBuffer.data();
  stream.level_buf_size = static_cast<std::uint32_t>(levelBufferSize(level));
  stream.gzip_flag = wrapper == DeflateWrapper::Zlib ? IGZIP_ZLIB : IGZIP_DEFLATE;
  stream.end_of_stream = 1;
  stream.flush = NO_FLUSH;
  // igzip's stream counts in 32 bits: a larger input would need the streaming interface.
  if (input.size() > 0xffffffffu || out.size() > 0xffffffffu) throw std::invalid_argument("deflateBytes: input over 4 GiB");
  stream.next_in = const_cast<std::uint8_t*>(input.data());  // igzip does not write through next_in
  stream.avail_in = static_cast<std::uint32_t>(input.size());
  stream.next_out = out.data();
  stream.avail_out = static_cast<std::uint32_t>(out.size());
  const int status = isal_deflate_stateless(&stream);
  afterIsal();
  if (status == STATELESS_OVERFLOW) return std::nullopt;
  if (status != COMP_OK) throw std::runtime_error("igzip deflate failed (status " + std::to_string(status) + ")");
  return out.size() - stream.avail_out;
}

}  // namespace

std::vector<std::uint8_t> deflateBytes(std::span<const std::uint8_t> input, int level, DeflateWrapper wrapper) {
  checkLevel(level);
  // Compressed into a buffer kept by the thread (its pages stay mapped from layer to layer), then
  // copied out at its size: layers compress 40 times or more, so the copy is small.
  thread_local std::unique_ptr<std::uint8_t[]> scratch;  // uninitialised: igzip writes before anything reads
  thread_local std::size_t scratchSize = 0;
  std::size_t room = outputBound(input.size());
  for (;; room *= 2) {
    if (scratchSize < room) {
      scratchSize = 0;  // a bad_alloc below leaves no buffer, and no size claiming one
      scratch.reset();
      scratch.reset(new std::uint8_t[room]);
      scratchSize = room;
    }
    if (const auto produced = compressOnce(input, level, wrapper, {scratch.get(), room})) {
      std::vector<std::uint8_t> out(scratch.get(), scratch.get() + *produced);
      if (scratchSize > (std::size_t{64} << 20)) scratch.reset(), scratchSize = 0;  // a huge input does not pin its buffer
      return out;
    }
  }
}

bool deflateWouldNotShrink(std::span<const std::uint8_t> input, int level) {
  checkLevel(level);
  constexpr std::size_t kSamples = 16, kMinSample = std::size_t{2} << 10;
  if (input.size() < (std::size_t{64} << 10)) return false;
  const std::size_t sample = std::max(kMinSample, input.size() / 128), sampled = kSamples * sample;
  thread_local std::vector<std::uint8_t> out;
  out.resize(std::max(out.size(), outputBound(sample)));
  std::size_t saved = 0;
  for (std::size_t n = 0; n < kSamples; ++n) {
    // Centred in the n-th sixteenth: the image's first and last bytes (a margin, often) are not
    // sampled twice as often as the rest.
    const std::size_t centre = input.size() * (2 * n + 1) / (2 * kSamples);
    const std::size_t at = std::min(centre - std::min(centre, sample / 2), input.size() - sample);
    const auto produced = compressOnce(input.subspan(at, sample), level, DeflateWrapper::Raw, out);
    if (produced && *produced < sample) saved += sample - *produced;
    if (saved * 8 > sampled) return false;  // saves an eighth already
  }
  return true;
}

DeflateStream::DeflateStream(int level, DeflateWrapper wrapper)
    : stream_(std::make_unique<isal_zstream>()), levelBuffer_(levelBufferSize((checkLevel(level), level))) {
  isal_deflate_init(stream_.get());
  stream_->level = static_cast<std::uint32_t>(level);
  stream_->level_buf = levelBuffer_.data();
  stream_->level_buf_size = static_cast<std::uint32_t>(levelBuffer_.size());
  stream_->gzip_flag = wrapper == DeflateWrapper::Zlib ? IGZIP_ZLIB : IGZIP_DEFLATE;
  stream_->flush = NO_FLUSH;
}

DeflateStream::~DeflateStream() = default;

void DeflateStream::add(std::span<const std::uint8_t> piece, bool last) {
  if (ended_) throw std::logic_error("DeflateStream::add after the last piece");
  if (piece.size() > 0xffffffffu) throw std::invalid_argument("DeflateStream::add: piece over 4 GiB");
  stream_->next_in = const_cast<std::uint8_t*>(piece.data());  // igzip does not write through next_in
  stream_->avail_in = static_cast<std::uint32_t>(piece.size());
  stream_->end_of_stream = last ? 1 : 0;
  do {
    if (out_.size() - produced_ < (std::size_t{1} << 16)) out_.resize(std::max<std::size_t>(out_.size() * 2, std::size_t{1} << 18));
    stream_->next_out = out_.data() + produced_;
    stream_->avail_out = static_cast<std::uint32_t>(std::min<std::size_t>(out_.size() - produced_, 0xffffffffu));
    const std::uint32_t room = stream_->avail_out;
    const int status = isal_deflate(stream_.get());
    afterIsal();
    if (status != COMP_OK) throw std::runtime_error("igzip deflate failed (status " + std::to_string(status) + ")");
    produced_ += room - stream_->avail_out;
  } while (stream_->avail_in > 0 || (last && stream_->internal_state.state != ZSTATE_END));
  ended_ = last;
}

std::vector<std::uint8_t> DeflateStream::take() {
  if (!ended_) throw std::logic_error("DeflateStream::take before the last piece");
  out_.resize(produced_);
  out_.shrink_to_fit();
  return std::move(out_);
}

std::optional<std::uint32_t> inflateRaw(std::span<const std::uint8_t> input, std::span<std::uint8_t> output) {
  if (input.size() > 0xffffffffu || output.size() > 0xffffffffu) return std::nullopt;  // beyond igzip's counters
  thread_local std::unique_ptr<inflate_state> state = std::make_unique<inflate_state>();
  isal_inflate_init(state.get());
  state->crc_flag = ISAL_GZIP_NO_HDR;  // raw deflate, with the gzip (= zip) CRC of the output
  state->next_in = const_cast<std::uint8_t*>(input.data());  // igzip does not write through next_in
  state->avail_in = static_cast<std::uint32_t>(input.size());
  state->next_out = output.data();
  state->avail_out = static_cast<std::uint32_t>(output.size());
  const int status = isal_inflate_stateless(state.get());
  afterIsal();
  const bool whole = (status == ISAL_DECOMP_OK || status == ISAL_END_INPUT) && state->block_state == ISAL_BLOCK_FINISH;
  if (!whole || state->avail_out != 0) return std::nullopt;
  return state->crc;
}

struct InflateStream::State {
  inflate_state igzip;
};

InflateStream::InflateStream() : state_(std::make_unique<State>()), buffer_(std::size_t{1} << 16) {
  isal_inflate_init(&state_->igzip);
  state_->igzip.crc_flag = ISAL_GZIP_NO_HDR;  // raw deflate, with the gzip (= zip) CRC of the output
}

InflateStream::~InflateStream() = default;

void InflateStream::feed(std::span<const std::uint8_t> input) {
  if (input.size() > 0xffffffffu) throw std::invalid_argument("InflateStream::add: piece over 4 GiB");
  state_->igzip.next_in = const_cast<std::uint8_t*>(input.data());  // igzip does not write through next_in
  state_->igzip.avail_in = static_cast<std::uint32_t>(input.size());
}

std::size_t InflateStream::inputLeft() const { return ended_ ? 0 : state_->igzip.avail_in; }

InflateStream::Status InflateStream::step() {
  pendingBytes_ = 0;
  if (ended_) return Status::End;
  inflate_state& z = state_->igzip;
  z.next_out = buffer_.data();
  z.avail_out = static_cast<std::uint32_t>(buffer_.size());
  const int result = isal_inflate(&z);
  afterIsal();
  pendingBytes_ = buffer_.size() - z.avail_out;
  if (result < 0) return Status::Damaged;
  ended_ = z.block_state == ISAL_BLOCK_FINISH;
  return ended_ ? Status::End : Status::More;
}

std::uint32_t InflateStream::crc() const { return state_->igzip.crc; }

namespace {

// `input` through zlib in one call at `level`, raw or zlib-wrapped.
std::vector<std::uint8_t> zlibDeflate(std::span<const std::uint8_t> input, int level, DeflateWrapper wrapper, const char* who) {
  if (input.size() > 0xffffffffu) throw std::invalid_argument(std::string(who) + ": input over 4 GiB");
  z_stream z{};
  const int windowBits = wrapper == DeflateWrapper::Raw ? -MAX_WBITS : MAX_WBITS;
  if (deflateInit2(&z, level, Z_DEFLATED, windowBits, 9, Z_DEFAULT_STRATEGY) != Z_OK) throw std::bad_alloc();
  std::vector<std::uint8_t> out(deflateBound(&z, static_cast<uLong>(input.size())));
  z.next_in = const_cast<Bytef*>(input.data());  // zlib's API is not const-correct; it does not write there
  z.avail_in = static_cast<uInt>(input.size());
  z.next_out = out.data();
  z.avail_out = static_cast<uInt>(out.size());
  const int result = deflate(&z, Z_FINISH);  // deflateBound's room: one call finishes
  out.resize(z.total_out);
  deflateEnd(&z);
  if (result != Z_STREAM_END) throw std::logic_error(std::string(who) + ": zlib did not finish within deflateBound");
  return out;
}

}  // namespace

std::vector<std::uint8_t> deflateSmallest(std::span<const std::uint8_t> input) {
  return zlibDeflate(input, Z_BEST_COMPRESSION, DeflateWrapper::Raw, "deflateSmallest");
}

std::vector<std::uint8_t> deflateStored(std::span<const std::uint8_t> input, DeflateWrapper wrapper) {
  return zlibDeflate(input, Z_NO_COMPRESSION, wrapper, "deflateStored");
}

std::uint32_t zipCrc32(std::span<const std::uint8_t> data, std::uint32_t crc) {
  const std::uint32_t result = crc32_gzip_refl(crc, data.data(), data.size());
  afterIsal();
  return result;
}

}  // namespace rodfab::printer_profiles
