// Internal to printer_profiles/: an open zip archive file as a libzip source, read through a
// read-ahead buffer. libzip's own file source seeks and reads through stdio for every entry's local
// header and data: opening a job of 6,000 layer images with ZIP_CHECKCONS and reading every image back
// cost the writer's verification some 40,000 system calls. Positions are only remembered here, and the
// file is read 1 MiB at a time where libzip asks, with pread (no mapping: a file truncated meanwhile
// is a read error, not a crash).
#pragma once

#include <zip.h>

namespace rodfab::printer_profiles {

// A read-only source over `fd`, a regular file, which it closes when freed (also when this fails).
// For zip_open_from_source(src, ZIP_RDONLY | ...); nullptr, with `error` set, when it cannot be made.
zip_source_t* newFileReadSource(int fd, zip_error_t* error);

}  // namespace rodfab::printer_profiles
