// Internal to printer_profiles/ (the job reader): that a zip's local entries tile the file from its first
// byte to its central directory, each one an entry the directory lists, once. libzip reads entries
// through the central directory, and a streaming unzipper (Java's ZipInputStream, `unzip -` tools)
// through the local headers one after another: an extra local entry between two listed ones (a second
// VeroWhitePlus_0004.bmp holding layer 30's image) made them unpack different jobs, and inspect said OK.
#pragma once

#include <cstdint>
#include <string>

struct zip;
typedef struct zip zip_t;

namespace rodfab::printer_profiles {

// Walks the local headers of the zip open as `za`, read from `fd` (`size` bytes), from offset 0: each
// must be one the central directory lists (by name), none twice, and the next must start right after
// its data (its sizes from the directory; a data descriptor after it when its flags say so); the last
// must end where the central directory begins. Throws JobReadError naming `where` and the first byte
// that breaks this. Reads a few dozen bytes per entry.
void checkLocalEntriesTile(int fd, std::uint64_t size, zip_t* za, const std::string& where);

}  // namespace rodfab::printer_profiles
