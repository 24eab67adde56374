// Internal to printer_profiles/: what every libzip source of ours shares, written once. libzip drives a
// source through one callback and a switch over ZIP_SOURCE_* commands; here that callback is a
// template over the source's class, which keeps only its own operations:
//   open() read(void*, zip_uint64_t) close() seek(void*, zip_uint64_t) tell() stat(zip_stat_t*)
//   attributes(zip_file_attributes_t*) beginWrite() write(const void*, zip_uint64_t)
//   seekWrite(void*, zip_uint64_t) tellWrite() commitWrite() rollbackWrite() remove()
// each returning what libzip expects of that command (-1 after failed()). The class lists the
// commands it has operations for in `static constexpr std::array kCommands`, exactly those (checked
// when the callback is compiled: a misspelt or missing operation does not compile); libzip is told
// these and ZIP_SOURCE_ERROR and ZIP_SOURCE_FREE, which the adapter answers, as it answers
// ZIP_SOURCE_SUPPORTS.
#pragma once

#include <zip.h>

#include <algorithm>
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
using Operation = zip_int64_t (*)(Source&, void* data, zip_uint64_t length);

// The one list of which member answers which command, as X(COMMAND, CALL) with the source `s` and
// libzip's `data` and `length` in CALL: operationFor's cases and kOperationCommands are both made from
// it, so they cannot drift apart.
#define RODFAB_ZIP_OPERATIONS(X)                                                       \
  X(ZIP_SOURCE_OPEN, s.open())                                                         \
  X(ZIP_SOURCE_READ, s.read(data, length))                                             \
  X(ZIP_SOURCE_CLOSE, s.close())                                                       \
  X(ZIP_SOURCE_SEEK, s.seek(data, length))                                             \
  X(ZIP_SOURCE_TELL, s.tell())                                                         \
  X(ZIP_SOURCE_STAT, s.stat(static_cast<zip_stat_t*>(data)))                           \
  X(ZIP_SOURCE_GET_FILE_ATTRIBUTES, s.attributes(static_cast<zip_file_attributes_t*>(data))) \
  X(ZIP_SOURCE_BEGIN_WRITE, s.beginWrite())                                            \
  X(ZIP_SOURCE_WRITE, s.write(data, length))                                           \
  X(ZIP_SOURCE_SEEK_WRITE, s.seekWrite(data, length))                                  \
  X(ZIP_SOURCE_TELL_WRITE, s.tellWrite())                                              \
  X(ZIP_SOURCE_COMMIT_WRITE, s.commitWrite())                                          \
  X(ZIP_SOURCE_ROLLBACK_WRITE, s.rollbackWrite())                                      \
  X(ZIP_SOURCE_REMOVE, s.remove())

// The source's operation for `command`, or nullptr when it has none: read both by the compile-time
// checks below and by the callback.
template <class Source>
constexpr Operation<Source> operationFor(zip_source_cmd_t command) {
  using S = Source;
  switch (command) {
#define RODFAB_ZIP_OPERATION_CASE(COMMAND, CALL)                                                \
  case COMMAND:                                                                                 \
    if constexpr (requires(S & s, void* data, zip_uint64_t length) { CALL; })                   \
      return [](S& s, [[maybe_unused]] void* data, [[maybe_unused]] zip_uint64_t length) -> zip_int64_t { return CALL; }; \
    return nullptr;
    RODFAB_ZIP_OPERATIONS(RODFAB_ZIP_OPERATION_CASE)
#undef RODFAB_ZIP_OPERATION_CASE
    default: return nullptr;  // the adapter's own (ERROR, FREE, SUPPORTS) and commands we never answer
  }
}

// Every command a source may have an operation for (operationFor's cases).
#define RODFAB_ZIP_COMMAND(COMMAND, CALL) COMMAND,
inline constexpr std::array kOperationCommands{RODFAB_ZIP_OPERATIONS(RODFAB_ZIP_COMMAND)};
#undef RODFAB_ZIP_COMMAND
#undef RODFAB_ZIP_OPERATIONS

template <class Source>
constexpr bool lists(zip_source_cmd_t command) {
  return std::ranges::find(Source::kCommands, command) != std::ranges::end(Source::kCommands);
}

// Whether the source lists exactly the commands it has operations for: a listed command without one (a
// misspelt or missing member) and an operation libzip is never told of are both compile errors.
template <class Source>
constexpr bool listsExactlyItsOperations() {
  return std::ranges::all_of(kOperationCommands, [](zip_source_cmd_t c) { return lists<Source>(c) == (operationFor<Source>(c) != nullptr); }) &&
         std::ranges::all_of(Source::kCommands, [](zip_source_cmd_t c) { return operationFor<Source>(c) != nullptr; });
}

// What libzip is told the source supports: its operations, and ERROR and FREE, which the adapter answers.
template <class Source>
constexpr zip_int64_t commandBitmap() {
  zip_int64_t bits = ZIP_SOURCE_MAKE_COMMAND_BITMASK(ZIP_SOURCE_ERROR) | ZIP_SOURCE_MAKE_COMMAND_BITMASK(ZIP_SOURCE_FREE);
  for (const zip_source_cmd_t command : Source::kCommands) bits |= ZIP_SOURCE_MAKE_COMMAND_BITMASK(command);
  return bits;
}

// The zip_source_callback libzip calls with a Source*. The adapter answers ZIP_SOURCE_ERROR (the
// source's error), ZIP_SOURCE_FREE (deletes it) and ZIP_SOURCE_SUPPORTS (commandBitmap) itself; every
// other command goes to the source's operation, and a command it has none for (libzip was not told
// of it) fails with ZIP_ER_OPNOTSUPP. Nothing is thrown through libzip's C frames (it would skip
// libzip's own clean-up): an allocation that fails inside an operation (read-ahead and tail buffers grow
// under the memory budget) becomes ZIP_ER_MEMORY, anything else ZIP_ER_INTERNAL, and libzip reports
// the failure to its caller as any other.
template <class Source>
zip_int64_t callback(void* self, void* data, zip_uint64_t length, zip_source_cmd_t command) noexcept {
  static_assert(listsExactlyItsOperations<Source>(),
                "Source::kCommands must list exactly the ZIP_SOURCE_* commands the source has operations for");
  auto* source = static_cast<Source*>(self);
  switch (command) {
    case ZIP_SOURCE_FREE: delete source; return 0;
    case ZIP_SOURCE_SUPPORTS: return commandBitmap<Source>();
    case ZIP_SOURCE_ERROR: return source->reportError(data, length);
    default: break;
  }
  const Operation<Source> operation = operationFor<Source>(command);
  if (!operation) return source->failed(ZIP_ER_OPNOTSUPP, 0);
  try {
    return operation(*source, data, length);
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
