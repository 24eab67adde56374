// printer_profiles/deflate.hpp against zlib, an independent implementation: what igzip compresses,
// zlib inflates (raw and zlib-wrapped, Adler-32 checked by zlib); what zlib compresses, InflateStream
// reads in any piece sizes; CRC-32 as zlib computes it; damaged and truncated data refused; staged
// deflate data copied into a zip by libzip without recompressing, read back by libzip (zlib).
#include "printer_profiles/deflate.hpp"
#include "printer_profiles/job_archive.hpp"

#include <catch2/catch.hpp>
#include <zip.h>
#include <zlib.h>

#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>
#include <vector>

using namespace rodfab::printer_profiles;
namespace fs = std::filesystem;
using Data = std::vector<std::uint8_t>;

namespace {

// A layer-like image: mostly zero, with runs and noisy patches (dithered material), `size` bytes.
Data layerLike(std::size_t size, unsigned seed) {
  std::mt19937 random(seed);
  Data data(size, 0);
  for (std::size_t at = 0; at + 300 < size; at += 1000 + random() % 4000)
    for (std::size_t n = 0; n < 300; ++n) data[at + n] = static_cast<std::uint8_t>(random() % 3 == 0 ? random() : 0xff);
  return data;
}

Data zlibInflate(const Data& compressed, std::size_t size, int windowBits) {
  z_stream z{};
  REQUIRE(inflateInit2(&z, windowBits) == Z_OK);
  Data out(size + 1);
  z.next_in = const_cast<Bytef*>(compressed.data());
  z.avail_in = static_cast<uInt>(compressed.size());
  z.next_out = out.data();
  z.avail_out = static_cast<uInt>(out.size());
  const int status = inflate(&z, Z_FINISH);
  inflateEnd(&z);
  REQUIRE(status == Z_STREAM_END);  // Z_DATA_ERROR for a bad Adler-32 in the zlib wrapper
  out.resize(z.total_out);
  return out;
}

Data zlibDeflateRaw(const Data& data) {
  z_stream z{};
  REQUIRE(deflateInit2(&z, 6, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY) == Z_OK);
  Data out(deflateBound(&z, data.size()));
  z.next_in = const_cast<Bytef*>(data.data());
  z.avail_in = static_cast<uInt>(data.size());
  z.next_out = out.data();
  z.avail_out = static_cast<uInt>(out.size());
  REQUIRE(deflate(&z, Z_FINISH) == Z_STREAM_END);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

Data inflateInPieces(const Data& compressed, std::size_t piece, InflateStream::Status& status, std::uint32_t& crc) {
  InflateStream stream;
  Data out;
  status = InflateStream::Status::More;
  for (std::size_t at = 0; at < compressed.size() && status == InflateStream::Status::More; at += piece)
    status = stream.add(std::span(compressed).subspan(at, std::min(piece, compressed.size() - at)),
                        [&](std::span<const std::uint8_t> p) { out.insert(out.end(), p.begin(), p.end()); });
  if (status == InflateStream::Status::End) crc = stream.crc();
  return out;
}

}  // namespace

TEST_CASE("igzip deflate is read back by zlib at every level, raw and zlib-wrapped", "[deflate]") {
  const Data image = layerLike(268'000, 1);
  const Data empty;
  Data noise(70'000);
  std::mt19937 random(2);
  for (auto& b : noise) b = static_cast<std::uint8_t>(random());  // incompressible: stored blocks
  for (const Data* input : std::initializer_list<const Data*>{&image, &empty, &noise})
    for (int level = 0; level <= 3; ++level) {
      CAPTURE(input->size(), level);
      const Data raw = deflateBytes(*input, level, DeflateWrapper::Raw);
      CHECK(zlibInflate(raw, input->size(), -15) == *input);
      const Data wrapped = deflateBytes(*input, level, DeflateWrapper::Zlib);
      CHECK(zlibInflate(wrapped, input->size(), 15) == *input);
      CHECK(deflateBytes(*input, level, DeflateWrapper::Raw) == raw);  // deterministic
    }
  CHECK(deflateBytes(image, 1, DeflateWrapper::Raw).size() * 8 < image.size());  // it does compress
  CHECK_THROWS_AS(deflateBytes(image, 4, DeflateWrapper::Raw), std::invalid_argument);
  CHECK_THROWS_AS(deflateBytes(image, -1, DeflateWrapper::Raw), std::invalid_argument);
}

TEST_CASE("deflateSmallest is read back by igzip's inflate, and a blank image comes out far smaller than at igzip's level", "[deflate]") {
  Data blank(6'461'762, 0);  // the size of a blank 11424 x 4525 layer BMP
  std::memcpy(blank.data(), "BM", 2);
  const Data image = layerLike(268'000, 3), empty;
  for (const Data* input : std::initializer_list<const Data*>{&blank, &image, &empty}) {
    CAPTURE(input->size());
    const Data smallest = deflateSmallest(*input);
    Data out(input->size());
    CHECK(inflateRaw(smallest, out) == zipCrc32(*input));
    CHECK(out == *input);
    CHECK(deflateSmallest(*input) == smallest);  // deterministic
    if (!input->empty()) CHECK(smallest.size() <= deflateBytes(*input, kLayerDeflateLevel, DeflateWrapper::Raw).size());
  }
  CHECK(deflateSmallest(blank).size() * 1000 < blank.size());  // deflate's bound is 1,032 to 1
}

// Bits set with probability p, as white noise dithers a modulus of Vero fraction p.
Data ditheredNoise(std::size_t size, double p, unsigned seed) {
  std::mt19937 random(seed);
  std::bernoulli_distribution bit(p);
  Data data(size);
  for (auto& b : data)
    for (int n = 0; n < 8; ++n) b = static_cast<std::uint8_t>(b << 1 | (bit(random) ? 1 : 0));
  return data;
}

TEST_CASE("deflateWouldNotShrink agrees with deflating the whole input, deflateStored is read back by zlib", "[deflate]") {
  Data halfNoise = ditheredNoise(268'000, 0.5, 9);
  std::fill(halfNoise.begin(), halfNoise.begin() + 134'000, 0);
  Data framedNoise = ditheredNoise(268'000, 0.5, 10);  // noise inside a 5 % blank frame (the part in its image)
  std::fill(framedNoise.begin(), framedNoise.begin() + 6'700, 0);
  std::fill(framedNoise.end() - 6'700, framedNoise.end(), 0);
  const std::vector<std::pair<Data, bool>> cases{
      {ditheredNoise(268'000, 0.5, 1), true}, {ditheredNoise(268'000, 0.3, 2), true}, {ditheredNoise(1'000'000, 0.5, 3), true},
      {framedNoise, true},                    {Data(268'000, 0), false},              {layerLike(268'000, 4), false},
      {halfNoise, false},                     {ditheredNoise(268'000, 0.02, 5), false},
      {ditheredNoise(60'000, 0.5, 6), false},  // under 64 KiB: never sampled
  };
  for (const auto& [input, notWorthIt] : cases) {
    CAPTURE(input.size(), notWorthIt);
    CHECK(deflateWouldNotShrink(input, kLayerDeflateLevel) == notWorthIt);
    CHECK(deflateWouldNotShrink(input, kLayerDeflateLevel) == notWorthIt);  // the same answer again
    // The truth: what deflating the whole input saves.
    const std::size_t whole = deflateBytes(input, kLayerDeflateLevel, DeflateWrapper::Raw).size();
    if (notWorthIt) CHECK(8 * whole > 7 * input.size());
    else if (input.size() >= (std::size_t{64} << 10)) CHECK(8 * whole < 7 * input.size());
    for (const DeflateWrapper wrapper : {DeflateWrapper::Raw, DeflateWrapper::Zlib}) {
      const Data stored = deflateStored(input, wrapper);
      CHECK(zlibInflate(stored, input.size(), wrapper == DeflateWrapper::Raw ? -15 : 15) == input);
      CHECK(stored.size() < input.size() + input.size() / 1000 + 64);  // stored blocks: 5 bytes in 64 KiB
    }
  }
  CHECK_THROWS_AS(deflateWouldNotShrink(Data(100'000), 4), std::invalid_argument);
}

TEST_CASE("deflateBytes gives an input the same bytes whatever the thread compressed before", "[deflate]") {
  // The thread keeps its igzip stream and clears only its fields before the history buffer: what an
  // earlier, different image left there must not reach the next one's bytes.
  std::vector<Data> inputs{layerLike(268'000, 3), Data(70'000, 0xff), layerLike(5'000, 4), Data{7}, layerLike(900'000, 5)};
  Data noise(70'000);
  std::mt19937 random(6);
  for (auto& b : noise) b = static_cast<std::uint8_t>(random());
  inputs.push_back(noise);
  for (int level = 0; level <= 3; ++level) {
    CAPTURE(level);
    std::vector<Data> fresh(inputs.size());  // each on a thread of its own, its stream new
    for (std::size_t i = 0; i < inputs.size(); ++i)
      std::thread([&, i] { fresh[i] = deflateBytes(inputs[i], level, DeflateWrapper::Zlib); }).join();
    for (int round = 0; round < 2; ++round)
      for (std::size_t k = 0; k < inputs.size(); ++k) {
        const std::size_t i = round == 0 ? k : inputs.size() - 1 - k;  // after larger and after smaller ones
        CAPTURE(i);
        CHECK(deflateBytes(inputs[i], level, DeflateWrapper::Zlib) == fresh[i]);
      }
  }
}

TEST_CASE("DeflateStream in pieces makes a stream zlib reads", "[deflate]") {
  const Data image = layerLike(3'000'000, 3);
  for (const std::size_t piece : {std::size_t{1} << 20, std::size_t{4099}}) {
    DeflateStream stream(1, DeflateWrapper::Zlib);
    for (std::size_t at = 0; at < image.size(); at += piece) {
      const std::size_t n = std::min(piece, image.size() - at);
      stream.add(std::span(image).subspan(at, n), at + n == image.size());
    }
    CHECK(zlibInflate(stream.take(), image.size(), 15) == image);
  }
  DeflateStream ended(1, DeflateWrapper::Raw);
  CHECK_THROWS_AS(ended.take(), std::logic_error);
  ended.add({}, true);
  CHECK(zlibInflate(ended.take(), 0, -15).empty());
  CHECK_THROWS_AS(ended.add({}, true), std::logic_error);
}

TEST_CASE("CRC-32 and inflate agree with zlib, damaged or short data is refused", "[deflate]") {
  const Data image = layerLike(1'500'000, 4);  // inflates to more than one 64 KiB output buffer
  const std::uint32_t zlibCrc = static_cast<std::uint32_t>(crc32(0, image.data(), static_cast<uInt>(image.size())));
  CHECK(zipCrc32(image) == zlibCrc);
  CHECK(zipCrc32(std::span(image).subspan(1000), zipCrc32(std::span(image).first(1000))) == zlibCrc);

  const Data compressed = zlibDeflateRaw(image);
  for (const std::size_t piece : {compressed.size(), std::size_t{1}, std::size_t{777}}) {
    InflateStream::Status status;
    std::uint32_t crc = 0;
    CHECK(inflateInPieces(compressed, piece, status, crc) == image);
    CHECK(status == InflateStream::Status::End);
    CHECK(crc == zlibCrc);
  }
  Data out(image.size());
  CHECK(inflateRaw(compressed, out) == zlibCrc);
  CHECK(out == image);
  Data shorter(image.size() - 1), longer(image.size() + 1);
  CHECK_FALSE(inflateRaw(compressed, shorter));
  CHECK_FALSE(inflateRaw(compressed, longer));

  InflateStream::Status status;
  std::uint32_t crc = 0;
  inflateInPieces(Data(compressed.begin(), compressed.begin() + static_cast<long>(compressed.size() / 2)), 4096, status, crc);
  CHECK(status == InflateStream::Status::More);  // truncated: the stream never ends
  CHECK_FALSE(inflateRaw(Data(compressed.begin(), compressed.begin() + static_cast<long>(compressed.size() / 2)), out));
  const Data invalid{0xff, 0xff, 0xff, 0xff, 0xff, 0xff};  // block type 3 is reserved
  inflateInPieces(invalid, 64, status, crc);
  CHECK(status == InflateStream::Status::Damaged);
}

TEST_CASE("writeZip copies staged deflate data as it is, libzip reads it back", "[deflate][zip]") {
  const fs::path dir = fs::temp_directory_path() / ("rodfab-test-staged-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Data a = layerLike(268'000, 5), b = layerLike(100'000, 6), stored{'P', 'N', 'G', '!'};
  const Data da = deflateBytes(a, 1, DeflateWrapper::Raw), db = deflateBytes(b, 1, DeflateWrapper::Raw);
  Data blob = da;
  blob.insert(blob.end(), db.begin(), db.end());
  blob.insert(blob.end(), stored.begin(), stored.end());
  const fs::path staged = dir / "band.bin";
  std::ofstream(staged, std::ios::binary).write(reinterpret_cast<const char*>(blob.data()), static_cast<std::streamsize>(blob.size()));
  const auto entry = [&](const char* name, std::uint64_t offset, const Data& packed, const Data& plain, ZipStorage storage) {
    StagedZipData data{offset, packed.size(), plain.size(), zipCrc32(plain)};
    data.storage = storage;  // the entry's and its data's method agree (writeZip checks)
    return ZipEntry{name, {}, storage, data};
  };
  const std::vector<ZipEntry> entries{entry("a.bmp", 0, da, a, ZipStorage::Deflate),
                                      entry("b.bmp", da.size(), db, b, ZipStorage::Deflate),
                                      entry("c.png", da.size() + db.size(), stored, stored, ZipStorage::Store)};
  writeZip(dir / "job.zip", entries, staged);

  int error = 0;
  zip_t* za = zip_open((dir / "job.zip").c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &error);
  REQUIRE(za);
  const std::vector<std::pair<const Data*, const Data*>> expected{{&a, &da}, {&b, &db}, {&stored, &stored}};
  for (zip_uint64_t n = 0; n < 3; ++n) {
    zip_stat_t st;
    REQUIRE(zip_stat_index(za, n, 0, &st) == 0);
    CHECK(st.comp_method == (n < 2 ? ZIP_CM_DEFLATE : ZIP_CM_STORE));
    CHECK(st.comp_size == expected[n].second->size());  // igzip's bytes, not recompressed by libzip
    zip_file_t* zf = zip_fopen_index(za, n, 0);
    REQUIRE(zf);
    Data back(st.size + 1);
    const zip_int64_t got = zip_fread(zf, back.data(), back.size());  // to the end: libzip checks the CRC
    zip_fclose(zf);
    REQUIRE(got == static_cast<zip_int64_t>(st.size));
    back.resize(st.size);
    CHECK(back == *expected[n].first);
  }
  zip_discard(za);

  // A staged file shorter than recorded: the archive is not written.
  fs::resize_file(staged, blob.size() - 10);
  CHECK_THROWS_AS(writeZip(dir / "short.zip", entries, staged), std::runtime_error);
  fs::remove_all(dir);
}
