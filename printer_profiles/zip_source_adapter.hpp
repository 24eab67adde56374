// Internal to printer_profiles/: what every libzip source of ours shares, written once. libzip drives a
// source through one callback and a switch over ZIP_SOURCE_* commands; here that callback is a
// template over the source's class, which keeps only its own operations:
//   open() read(void*, zip_uint64_t) close() seek(void*, zip_uint64_t) tell() stat(zip_stat_t*)
//   attributes(zip_file_attributes_t*) beginWrite() write(const void*, zip_uint64_t)
//   seekWrite(void*, zip_uint64_t) tellWrite() commitWrite() rollbackWrite() remove()
// each returning what libzip expects of that command (-1 after failed()). The class lists the
// commands it answers in `static constexpr std::array kCommands` (libzip is told exactly these); a
// listed command it has no operation for fails with ZIP_ER_OPNOTSUPP, as does anything unlisted.
#pragma once

#include <zip.h>

#include <array>
#include <memory>
#include <new>

namespace rodfab::printer_profiles {

// The error a source reports through ZIP_SOURCE_ERROR; every source derives from it.
class ZipSourceState {
public:
  ZipSourceState() { zip_error_init(&error_); }
  ~ZipSourceState() { zip_error_fini(&error_); }
  ZipSourceState(const ZipSourceState&) = delete;
  ZipSourceState& operator=(const ZipSourceState&) = delete;

  zip_int64_t reportError(void* data, zip_uint64_t length) { return zip_error_to_data(&error_, data, length); }

  // Sets the error libzip will ask for and returns -1, the failure of every command.
  zip_int64_t failed(int code, int systemError) {
    zip_error_set(&error_, code, systemError);
    return -1;
  }

protected:
  // ZIP_SOURCE_SEEK and ZIP_SOURCE_SEEK_WRITE: moves `position` as libzip's `data` says, within [0, end].
  zip_int64_t seekWithin(zip_uint64_t& position, zip_uint64_t end, void* data, zip_uint64_t length) {
    const zip_int64_t to = zip_source_seek_compute_offset(position, end, data, length, &error_);
    if (to < 0) return -1;
    position = static_cast<zip_uint64_t>(to);
    return 0;
  }

private:
  zip_error_t error_;
};

namespace zip_source_detail {

template <class Source>
constexpr zip_int64_t commandBitmap() {
  zip_int64_t bits = 0;
  for (const zip_source_cmd_t command : Source::kCommands) bits |= ZIP_SOURCE_MAKE_COMMAND_BITMASK(command);
  return bits;
}

template <class Source>
constexpr bool lists(zip_source_cmd_t command) {
  return (commandBitmap<Source>() & ZIP_SOURCE_MAKE_COMMAND_BITMASK(command)) != 0;
}

// What readCommand and writeCommand return when the source has no operation for the command (libzip's
// answers are -1 or more).
constexpr zip_int64_t kNoOperation = -2;

template <class Source>
zip_int64_t readCommand(Source& s, void* data, zip_uint64_t length, zip_source_cmd_t command) {
  switch (command) {
    case ZIP_SOURCE_OPEN: if constexpr (requires { s.open(); }) return s.open(); break;
    case ZIP_SOURCE_READ: if constexpr (requires { s.read(data, length); }) return s.read(data, length); break;
    case ZIP_SOURCE_CLOSE: if constexpr (requires { s.close(); }) return s.close(); break;
    case ZIP_SOURCE_SEEK: if constexpr (requires { s.seek(data, length); }) return s.seek(data, length); break;
    case ZIP_SOURCE_TELL: if constexpr (requires { s.tell(); }) return s.tell(); break;
    case ZIP_SOURCE_STAT: if constexpr (requires { s.stat(static_cast<zip_stat_t*>(data)); }) return s.stat(static_cast<zip_stat_t*>(data)); break;
    case ZIP_SOURCE_GET_FILE_ATTRIBUTES:
      if constexpr (requires { s.attributes(static_cast<zip_file_attributes_t*>(data)); })
        return s.attributes(static_cast<zip_file_attributes_t*>(data));
      break;
    default: break;
  }
  return kNoOperation;
}

template <class Source>
zip_int64_t writeCommand(Source& s, void* data, zip_uint64_t length, zip_source_cmd_t command) {
  switch (command) {
    case ZIP_SOURCE_BEGIN_WRITE: if constexpr (requires { s.beginWrite(); }) return s.beginWrite(); break;
    case ZIP_SOURCE_WRITE: if constexpr (requires { s.write(data, length); }) return s.write(data, length); break;
    case ZIP_SOURCE_SEEK_WRITE: if constexpr (requires { s.seekWrite(data, length); }) return s.seekWrite(data, length); break;
    case ZIP_SOURCE_TELL_WRITE: if constexpr (requires { s.tellWrite(); }) return s.tellWrite(); break;
    case ZIP_SOURCE_COMMIT_WRITE: if constexpr (requires { s.commitWrite(); }) return s.commitWrite(); break;
    case ZIP_SOURCE_ROLLBACK_WRITE: if constexpr (requires { s.rollbackWrite(); }) return s.rollbackWrite(); break;
    case ZIP_SOURCE_REMOVE: if constexpr (requires { s.remove(); }) return s.remove(); break;
    default: break;
  }
  return kNoOperation;
}

// The zip_source_callback libzip calls with a Source*; ZIP_SOURCE_FREE deletes it. Nothing is thrown
// through libzip's C frames (it would skip libzip's own clean-up): an allocation that fails inside an
// operation (read-ahead and tail buffers grow under the memory budget) becomes ZIP_ER_MEMORY, anything
// else ZIP_ER_INTERNAL, and libzip reports the failure to its caller as any other.
template <class Source>
zip_int64_t callback(void* self, void* data, zip_uint64_t length, zip_source_cmd_t command) noexcept {
  auto* source = static_cast<Source*>(self);
  if (command == ZIP_SOURCE_FREE) {
    delete source;
    return 0;
  }
  if (command == ZIP_SOURCE_SUPPORTS) return commandBitmap<Source>();
  if (!lists<Source>(command)) return source->failed(ZIP_ER_OPNOTSUPP, 0);
  if (command == ZIP_SOURCE_ERROR) return source->reportError(data, length);
  try {
    zip_int64_t answer = readCommand(*source, data, length, command);
    if (answer == kNoOperation) answer = writeCommand(*source, data, length, command);
    return answer == kNoOperation ? source->failed(ZIP_ER_OPNOTSUPP, 0) : answer;
  } catch (const std::bad_alloc&) {
    return source->failed(ZIP_ER_MEMORY, 0);
  } catch (...) {
    return source->failed(ZIP_ER_INTERNAL, 0);
  }
}

}  // namespace zip_source_detail

// `source` as a libzip source, which owns it from then on; nullptr, with `error` set, when it cannot
// be made (`source` is deleted then).
template <class Source>
zip_source_t* makeZipSource(std::unique_ptr<Source> source, zip_error_t* error) {
  zip_source_t* made = zip_source_function_create(zip_source_detail::callback<Source>, source.get(), error);
  if (made) source.release();
  return made;
}

// The same for a source added to `za`, whose error says why when it cannot be made.
template <class Source>
zip_source_t* makeZipSource(zip_t* za, std::unique_ptr<Source> source) {
  zip_source_t* made = zip_source_function(za, zip_source_detail::callback<Source>, source.get());
  if (made) source.release();
  return made;
}

}  // namespace rodfab::printer_profiles
