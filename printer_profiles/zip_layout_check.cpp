#include "printer_profiles/zip_layout_check.hpp"

#include "printer_profiles/job_reader.hpp"

#include <zip.h>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <unordered_map>
#include <vector>

namespace rodfab::printer_profiles {

namespace {

constexpr std::uint32_t kLocalHeader = 0x04034b50, kDescriptor = 0x08074b50, kEnd = 0x06054b50, kEnd64Locator = 0x07064b50,
                        kEnd64 = 0x06064b50;

std::uint64_t little(const std::uint8_t* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = bytes; i-- > 0;) v = (v << 8) | p[i];
  return v;
}

class Walk {
public:
  Walk(int fd, std::uint64_t size, const std::string& where) : fd_(fd), size_(size), where_(where) {}

  [[noreturn]] void fail(const std::string& what) const { throw JobReadError(where_ + ": not a consistent zip archive: " + what); }

  // `length` bytes at `at` (at least `needed` of them, fewer only at the end of the file), or a failure
  // naming what was being read.
  std::vector<std::uint8_t> read(std::uint64_t at, std::size_t length, const char* what, std::size_t needed = SIZE_MAX) const {
    std::vector<std::uint8_t> out(length);
    std::size_t got = 0;
    while (got < length && at + got < size_) {
      const ssize_t n = ::pread(fd_, out.data() + got, length - got, static_cast<off_t>(at + got));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      got += static_cast<std::size_t>(n);
    }
    if (got < std::min(length, needed)) fail(std::string("cannot read ") + what + " at byte " + std::to_string(at));
    out.resize(got);
    return out;
  }

  // Where the central directory begins, from the end of central directory record (zip64's if it has one).
  std::uint64_t directoryStart() const {
    const std::size_t tailBytes = static_cast<std::size_t>(std::min<std::uint64_t>(size_, 22 + 65535));
    const std::vector<std::uint8_t> tail = read(size_ - tailBytes, tailBytes, "the end of the archive");
    for (std::size_t p = tailBytes >= 22 ? tailBytes - 22 + 1 : 0; p-- > 0;) {
      if (little(&tail[p], 4) != kEnd || little(&tail[p + 20], 2) != tailBytes - p - 22) continue;
      const std::uint64_t start = little(&tail[p + 16], 4);
      if (start != 0xffffffffu) return start;
      if (p < 20 || little(&tail[p - 20], 4) != kEnd64Locator) fail("a zip64 archive without its end record locator");
      const std::vector<std::uint8_t> end64 = read(little(&tail[p - 20 + 8], 8), 56, "the zip64 end record");
      if (little(end64.data(), 4) != kEnd64) fail("no zip64 end record where its locator points");
      return little(&end64[48], 8);
    }
    fail("no end of central directory record");
  }

private:
  int fd_;
  std::uint64_t size_;
  const std::string& where_;
};

}  // namespace

void checkLocalEntriesTile(int fd, std::uint64_t size, zip_t* za, const std::string& where) {
  const Walk walk(fd, size, where);
  const std::uint64_t directory = walk.directoryStart();
  const auto entries = static_cast<std::uint64_t>(std::max<zip_int64_t>(zip_get_num_entries(za, 0), 0));
  // The directory's names as they lie in it (zip_name_locate did not find one holding a control
  // character), with each entry's index and compressed size.
  struct Listed {
    zip_uint64_t index, compressedBytes;
  };
  std::unordered_map<std::string, Listed> listed;
  for (zip_uint64_t i = 0; i < entries; ++i) {
    zip_stat_t st;
    zip_stat_init(&st);
    constexpr zip_uint64_t kNeeded = ZIP_STAT_NAME | ZIP_STAT_COMP_SIZE;
    if (zip_stat_index(za, i, ZIP_FL_ENC_RAW, &st) == 0 && (st.valid & kNeeded) == kNeeded) listed.emplace(st.name, Listed{i, st.comp_size});
  }
  std::vector<bool> seen(entries, false);
  std::uint64_t at = 0, walked = 0;
  while (at < directory) {
    // The header and, in the same read, a name of up to 226 bytes (a job's are under 80).
    const std::vector<std::uint8_t> h = walk.read(at, 256, "a local entry header", 30);
    if (little(h.data(), 4) != kLocalHeader)
      walk.fail("byte " + std::to_string(at) + " is not a local entry header (bytes between entries that no directory record lists)");
    const auto nameBytes = static_cast<std::size_t>(little(&h[26], 2));
    const std::vector<std::uint8_t> raw = 30 + nameBytes <= h.size()
                                              ? std::vector<std::uint8_t>(h.begin() + 30, h.begin() + 30 + static_cast<long>(nameBytes))
                                              : walk.read(at + 30, nameBytes, "a local entry name");
    const std::string name(raw.begin(), raw.end());
    const auto found = listed.find(name);
    if (found == listed.end())
      walk.fail("a local entry " + printableName(name) + " at byte " + std::to_string(at) +
                " that the central directory does not list (a streaming unzipper would unpack it)");
    const auto [index, compressedBytes] = found->second;
    if (compressedBytes > size)
      walk.fail(printableName(name) + ": its directory record says " + std::to_string(compressedBytes) + " bytes, more than the archive holds");
    if (seen[index])
      walk.fail(printableName(name) + " has a second local entry at byte " + std::to_string(at) + " (a streaming unzipper would unpack both)");
    seen[index] = true;
    ++walked;
    at += 30 + nameBytes + little(&h[28], 2) + compressedBytes;
    if (little(&h[6], 2) & 8u)  // a data descriptor follows the data, with or without its signature
      at += little(walk.read(at, 4, "a data descriptor").data(), 4) == kDescriptor ? 16 : 12;
  }
  if (at != directory)
    walk.fail("the local entries end at byte " + std::to_string(at) + ", not where the central directory begins (byte " +
              std::to_string(directory) + ")");
  if (walked != entries)
    walk.fail(std::to_string(entries - walked) + " entries the central directory lists have no local entry before it");
}

}  // namespace rodfab::printer_profiles
