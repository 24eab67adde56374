// Internal to printer_profiles/: the file a new zip archive is written to, as a libzip source.
// libzip's own file source writes through stdio's 4 KiB buffer and seeks back to every entry's local
// header once its data is written, which flushes that buffer: a job of 6,000 layer images cost
// zip_close some 30,000 system calls. This one keeps the archive's tail in one large buffer, patches
// the headers there, and writes it out in a few large pieces.
#pragma once

#include <zip.h>

#include <filesystem>

namespace rodfab::printer_profiles {

// A source for zip_open_from_source(src, ZIP_CREATE | ZIP_EXCL, ...): says whether `path` exists
// (without following a link), and when libzip writes the archive creates it as `path`.part (never
// replacing anything), renamed to `path` when libzip commits and removed when it rolls back or the
// source is freed first. nullptr, with `error` set, when it cannot be made.
zip_source_t* newArchiveSource(const std::filesystem::path& path, zip_error_t* error);

}  // namespace rodfab::printer_profiles
