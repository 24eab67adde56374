// Parsing JSON from untrusted files: bounded nesting, no duplicate keys, located errors.
//
// nlohmann's parser itself is iterative, but the documents it builds are walked recursively by our
// validators and by json::dump() (used in error messages), so nesting is limited before a document
// is built. Duplicate keys are refused because nlohmann silently keeps the last one, so a file could
// say two things and mean one.
#pragma once

#include <nlohmann/json.hpp>

#include <cstddef>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>

namespace rodfab::common {

inline constexpr int kMaxJsonDepth = 64;
// Files rodfab reads as JSON are small (designs, profiles, calibrations, manifests).
inline constexpr std::size_t kMaxJsonBytes = std::size_t{256} << 20;

// Where and what: `path` is a JSON path such as `rods[3].centerline` (empty when the problem is
// the text itself), `message` says what was expected and, for syntax problems, the line and column.
struct JsonInputError : std::runtime_error {
  JsonInputError(std::string path, std::string message);
  std::string path, message;
};
// The document holds more values than the caller's `maxValues`: too large for what it should be, which
// some callers tell apart from malformed text.
struct JsonTooManyValues : JsonInputError {
  using JsonInputError::JsonInputError;
};

// Parses `text` in one pass: the document nlohmann's own parser would build (the same values and
// types), checked as it is built. Throws JsonInputError for malformed JSON, nesting deeper than
// `maxDepth` arrays and objects, a duplicate key, more than `maxValues` values (scalars, arrays and
// objects: a bound on the memory of the document built, which may be ~100 bytes per value; thrown as
// JsonTooManyValues), or text
// longer than kMaxJsonBytes, or a number literal beyond the range of a double (1e400), reported at its
// path. Checks for an interrupt every 65,536 values (throws common::Interrupted). Thread-safe.
nlohmann::json parseJsonStrict(const std::string& text, int maxDepth = kMaxJsonDepth,
                               std::size_t maxValues = std::numeric_limits<std::size_t>::max());

// An nlohmann-json exception's message as a message may show it: the text it quotes from the file
// ("last read: '...'", which holds the file's bytes as they are, DEL, C1 controls and bytes that are
// not UTF-8 among them) written with printableFromFile (common/quoted_text.hpp); the rest is the
// library's own words. Every message that passes on a parse error from a file goes through this.
std::string printableJsonError(std::string_view what);

// The bytes of `file`, read in chunks and refused beyond `maxBytes` (so /dev/zero or a huge file
// cannot exhaust memory); pipes are read like files. Throws JsonInputError("", what went wrong).
std::string readBoundedFile(const std::string& file, std::size_t maxBytes = kMaxJsonBytes);

// 1-based line and column of byte `offset` in `text`.
std::pair<std::size_t, std::size_t> lineAndColumn(const std::string& text, std::size_t offset);

// JSON paths for located messages: memberPath("rods[3]", "modulus") is "rods[3].modulus",
// memberPath("", "rods") is "rods", indexPath("rods", 3) is "rods[3]".
std::string memberPath(const std::string& path, const std::string& key);
std::string indexPath(const std::string& path, std::size_t i);

// The message for a member whose key is not among `allowed`: "unknown key (expected one of: a, b)".
std::string unknownKeyMessage(const std::set<std::string>& allowed);

// A value as a message shows it: its compact JSON, cut to at most `maxChars` characters ("..." at
// the end when cut); bytes that are not UTF-8 are shown as U+FFFD. Arrays and objects holding more
// than 64 values in all are described by kind and size ("an array of 20000 values"), and long strings
// are cut before they are escaped, so describing a huge value costs no more than a small one.
std::string describeJson(const nlohmann::json& j, std::size_t maxChars = 40);

}  // namespace rodfab::common
