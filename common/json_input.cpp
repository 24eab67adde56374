#include "common/json_input.hpp"

#include "common/interrupt.hpp"
#include "common/quoted_text.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <boost/algorithm/string/join.hpp>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <set>
#include <vector>

namespace rodfab::common {

using nlohmann::json;

namespace {

std::string lineColumnText(const std::string& text, std::size_t offset) {
  const auto [line, column] = lineAndColumn(text, offset);
  return "line " + std::to_string(line) + ", column " + std::to_string(column);
}

// A light scan that follows brackets, commas and keys outside strings (the text may be malformed;
// the parser reports that afterwards), keeping the JSON path of each open container. `visit(at, path)`
// is called at every '[' or '{' (before it is entered, with the depth so far) and at the first
// character of every number; it returns true to stop the scan there.
struct Found {
  std::size_t offset = std::string::npos;
  std::string path;
};

template <typename Visit>
Found scanJsonPaths(const std::string& text, Visit visit) {
  struct Level {
    bool array;
    std::size_t index = 0;
    std::string key;
  };
  std::vector<Level> levels;
  std::string lastString;
  const auto path = [&levels] {
    std::string p;
    for (const Level& l : levels) {
      if (l.array) p.append("[").append(std::to_string(l.index)).append("]");
      else if (!l.key.empty()) p.append(p.empty() ? "" : ".").append(printableFromFile(l.key, 64));  // a file's key: shown escaped
    }
    return p;
  };
  for (std::size_t at = 0; at < text.size(); ++at) {
    const char c = text[at];
    if (c == '"') {
      lastString.clear();
      for (++at; at < text.size() && text[at] != '"'; ++at) {
        if (text[at] == '\\') ++at;
        else if (lastString.size() < 64) lastString += text[at];
      }
    } else if (c == ':' && !levels.empty() && !levels.back().array) {
      levels.back().key = lastString;
    } else if (c == ',' && !levels.empty() && levels.back().array) {
      ++levels.back().index;
    } else if (c == '[' || c == '{') {
      if (visit(at, levels.size())) return {at, path()};
      levels.push_back({c == '[', 0, {}});
    } else if ((c == ']' || c == '}') && !levels.empty()) {
      levels.pop_back();
    } else if (c == '-' || (c >= '0' && c <= '9')) {
      if (visit(at, levels.size())) return {at, path()};
      while (at + 1 < text.size() && std::strchr("+-.0123456789eE", text[at + 1])) ++at;
    }
  }
  return {};
}

// Where nesting first goes deeper than allowed (the container one level too deep), before anything is built.
Found findTooDeep(const std::string& text, int maxDepth) {
  return scanJsonPaths(text, [&](std::size_t at, std::size_t depth) {
    return (text[at] == '[' || text[at] == '{') && static_cast<int>(depth) >= maxDepth;
  });
}

// The first number literal beyond the range of a double (nlohmann refuses it without saying where).
Found findOverflowingNumber(const std::string& text) {
  return scanJsonPaths(text, [&](std::size_t at, std::size_t) {
    if (text[at] == '[' || text[at] == '{') return false;
    const double v = std::strtod(text.c_str() + at, nullptr);
    return !std::isfinite(v);
  });
}

// Builds the document from nlohmann's SAX events in one pass over the text, refusing as it goes a key
// seen twice in one object (nlohmann's own parser keeps the last), nesting deeper than `maxDepth` and
// more than `maxValues` values, and checking for an interrupt every 65,536 values. A handler of our own,
// not a parser callback: nlohmann 3.11's callback DOM parser rescans the parent array at every object's
// end, quadratic in an array of objects (200,000 calibration points took 11 s). Until 2026-12-06 the
// checks were a SAX pass of their own before nlohmann's DOM parse, which polled nothing: one pass takes
// half the time (bench/README.md, "One pass for JSON").
class StrictDomBuilder : public nlohmann::json_sax<json> {
public:
  struct TooDeep {};  // located afterwards by findTooDeep, which has the text

  StrictDomBuilder(json& root, int maxDepth, std::size_t maxValues) : root_(root), maxDepth_(maxDepth), maxValues_(maxValues) {}

  bool null() override { return add(nullptr); }
  bool boolean(bool v) override { return add(v); }
  bool number_integer(number_integer_t v) override { return add(v); }
  bool number_unsigned(number_unsigned_t v) override { return add(v); }
  bool number_float(number_float_t v, const string_t&) override { return add(v); }
  bool string(string_t& v) override { return add(std::move(v)); }
  bool binary(binary_t& v) override { return add(json::binary(std::move(v))); }
  bool start_object(std::size_t) override { return open(json::object()); }
  bool start_array(std::size_t) override { return open(json::array()); }
  bool end_object() override { return close(); }
  bool end_array() override { return close(); }
  bool key(string_t& key) override {
    Level& l = levels_.back();
    const auto [member, fresh] = l.node->get_ref<json::object_t&>().try_emplace(key);
    l.key = &member->first;  // the first one's: the same text as a repeated key
    if (!fresh) throw JsonInputError(path(), "duplicate key (each key may appear once per object)");
    l.slot = &member->second;
    return true;
  }
  // Rethrown as the concrete exception nlohmann's DOM parser throws, for parseJsonStrict's messages.
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) override {
    if (const auto* syntax = dynamic_cast<const json::parse_error*>(&e)) throw *syntax;
    if (const auto* range = dynamic_cast<const json::out_of_range*>(&e)) throw *range;
    throw JsonInputError("", printableJsonError(e.what()));
  }

private:
  struct Level {
    json* node;
    json* slot = nullptr;              // an object's member whose key came last,
    const std::string* key = nullptr;  // and that key (both stay put: std::map's nodes do not move)
  };

  std::string path() const {
    std::string p;
    for (const Level& l : levels_) {
      if (l.node->is_array()) p.append("[").append(std::to_string(l.node->size() - (&l == &levels_.back() ? 0 : 1))).append("]");
      else if (l.key && !l.key->empty()) p.append(p.empty() ? "" : ".").append(printableFromFile(*l.key, 64));  // a file's key: shown escaped
    }
    return p;
  }
  void count() {
    if (++values_ > maxValues_)
      throw JsonTooManyValues(path(), "the document holds more than " + std::to_string(maxValues_) + " values; expected fewer");
    if (values_ % 65536 == 0) throwIfInterrupted();  // ~1 ms of values: a 256 MiB document reads for seconds
  }
  // Where the next value goes: the root, the end of the open array, or the member its key made.
  json* place(json&& value) {
    if (levels_.empty()) {
      root_ = std::move(value);
      return &root_;
    }
    Level& l = levels_.back();
    if (l.node->is_array()) {
      auto& items = l.node->get_ref<json::array_t&>();
      items.push_back(std::move(value));
      return &items.back();  // stays put: the array grows again only once this value is closed
    }
    *l.slot = std::move(value);
    return l.slot;
  }
  bool add(json&& value) {
    count();
    place(std::move(value));
    return true;
  }
  bool open(json&& container) {
    count();
    if (static_cast<int>(levels_.size()) >= maxDepth_) throw TooDeep{};
    levels_.push_back({place(std::move(container)), nullptr, nullptr});
    return true;
  }
  bool close() {
    levels_.pop_back();
    return true;
  }

  json& root_;
  int maxDepth_;
  std::size_t maxValues_;
  std::size_t values_ = 0;
  std::vector<Level> levels_;
};

}  // namespace

JsonInputError::JsonInputError(std::string p, std::string m)
    : std::runtime_error(p.empty() ? m : p + ": " + m), path(std::move(p)), message(std::move(m)) {}

std::pair<std::size_t, std::size_t> lineAndColumn(const std::string& text, std::size_t offset) {
  std::size_t line = 1, column = 1;
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') ++line, column = 1;
    else ++column;
  }
  return {line, column};
}

std::string readBoundedFile(const std::string& file, std::size_t maxBytes) {
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) throw JsonInputError("", "is a folder; expected a file");
  // Opened without blocking (a FIFO with no writer would wait forever), then read blocking: a pipe
  // with a writer is read like a file, one without reads as empty.
  const int fd = ::open(file.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw JsonInputError("", std::string("cannot open the file (") + std::strerror(errno) + ")");
  std::unique_ptr<int, void (*)(int*)> closer(new int(fd), [](int* f) { ::close(*f), delete f; });
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  std::string text;
  char chunk[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw JsonInputError("", std::string("read error (") + std::strerror(errno) + ")");
    if (n == 0) break;
    if (text.size() + static_cast<std::size_t>(n) > maxBytes)
      throw JsonInputError("", "the file is larger than " + std::to_string(maxBytes >> 20) + " MiB; expected a smaller file");
    text.append(chunk, static_cast<std::size_t>(n));
  }
  return text;
}

json parseJsonStrict(const std::string& text, int maxDepth, std::size_t maxValues) {
  if (text.size() > kMaxJsonBytes)
    throw JsonInputError("", "the file is " + std::to_string(text.size() >> 20) + " MiB; expected at most " +
                                 std::to_string(kMaxJsonBytes >> 20) + " MiB of JSON");
  // nlohmann's lexer takes a NUL byte for the end of the input (for C strings), and would ignore what
  // follows: a design, profile or manifest with "\0garbage" appended read as valid. JSON holds none.
  if (const std::size_t nul = text.find('\0'); nul != std::string::npos)
    throw JsonInputError("", "malformed JSON at " + lineColumnText(text, nul) + ": a NUL byte (JSON text holds none)");
  try {
    json document;
    StrictDomBuilder builder(document, maxDepth, maxValues);
    json::sax_parse(text, &builder);  // the builder throws at the first problem
    return document;
  } catch (const StrictDomBuilder::TooDeep&) {
    const Found deep = findTooDeep(text, maxDepth);
    throw JsonInputError(deep.path, "nested deeper than " + std::to_string(maxDepth) + " arrays and objects at " +
                                        lineColumnText(text, deep.offset) + " (expected at most " +
                                        std::to_string(maxDepth) + ")");
  } catch (const json::parse_error& e) {
    std::string what = printableJsonError(e.what());  // "[json.exception.parse_error.101] parse error at line 1, column 13: why"
    if (auto pos = what.find("parse error"); pos != std::string::npos) {
      const auto colon = what.find(": ", pos);
      what = colon == std::string::npos ? what.substr(pos) : what.substr(colon + 2);
    }
    throw JsonInputError("", "malformed JSON at " + lineColumnText(text, e.byte > 0 ? e.byte - 1 : 0) + ": " + what);
  } catch (const json::out_of_range&) {  // a number literal beyond a double
    const Found big = findOverflowingNumber(text);
    throw JsonInputError(big.path, "a number beyond the range of a double at " +
                                       lineColumnText(text, big.offset == std::string::npos ? 0 : big.offset) +
                                       "; expected a finite number");
  }
}

std::string printableJsonError(std::string_view what) {
  // nlohmann: "...; last read: 'TOKEN'" and, for some errors, "; expected WHAT" after it.
  static constexpr std::string_view kLastRead = "last read: '";
  const std::size_t open = what.find(kLastRead);
  if (open == std::string_view::npos) return holdsControlCharacters(what) ? printableFromFile(what, what.size()) : std::string(what);
  const std::size_t from = open + kLastRead.size();
  std::size_t close = what.rfind("'; expected ");
  if (close == std::string_view::npos || close < from) close = what.ends_with('\'') && what.size() > from ? what.size() - 1 : what.size();
  const std::string_view token = what.substr(from, close - from);
  std::string out(what.substr(0, from));
  out += printableFromFile(token, 80);
  out += what.substr(close);
  return out;
}

std::string memberPath(const std::string& path, const std::string& key) {
  // A file's unknown key is shown as a path too: escaped and cut, as a file's word in any message.
  const std::string shown = printableFromFile(key, 64);
  return path.empty() ? shown : path + "." + shown;
}

std::string indexPath(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

std::string unknownKeyMessage(const std::set<std::string>& allowed) {
  return "unknown key (expected one of: " + boost::algorithm::join(allowed, ", ") + ")";
}

namespace {

// Whether `j` holds at most `budget` values in all (itself included); stops as soon as it does not.
bool withinValues(const nlohmann::json& j, std::size_t& budget) {
  if (budget == 0) return false;
  --budget;
  if (j.is_structured())
    for (const auto& element : j)
      if (!withinValues(element, budget)) return false;
  return true;
}

// nlohmann's dump escapes C0 controls but writes DEL and the C1 controls (U+0080-U+009F, which some
// terminals obey) as they are: those as \u escapes too, so a message shows them rather than runs them.
std::string escapeDelAndC1(const std::string& dumped) {
  std::string out;
  out.reserve(dumped.size());
  for (std::size_t i = 0; i < dumped.size(); ++i) {
    const auto byte = static_cast<unsigned char>(dumped[i]);
    const bool c1 = byte == 0xc2 && i + 1 < dumped.size() && static_cast<unsigned char>(dumped[i + 1]) >= 0x80 &&
                    static_cast<unsigned char>(dumped[i + 1]) <= 0x9f;
    if (byte != 0x7f && !c1) {
      out += dumped[i];
      continue;
    }
    char escaped[8];
    std::snprintf(escaped, sizeof escaped, "\\u%04x", c1 ? static_cast<unsigned char>(dumped[++i]) : byte);
    out += escaped;
  }
  return out;
}

}  // namespace

std::string describeJson(const nlohmann::json& j, std::size_t maxChars) {
  constexpr std::size_t kMostValuesDumped = 64;
  std::size_t budget = kMostValuesDumped;
  if (!withinValues(j, budget))
    return j.is_array() ? "an array of " + std::to_string(j.size()) + " values"
                        : "an object of " + std::to_string(j.size()) + " members";
  // A long string is cut before it is escaped, so a 100 MB value is not copied whole.
  const nlohmann::json shown = j.is_string() && j.get_ref<const std::string&>().size() > maxChars
                                   ? nlohmann::json(j.get_ref<const std::string&>().substr(0, maxChars))
                                   : nlohmann::json();
  std::string s = escapeDelAndC1((shown.is_null() ? j : shown).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
  if (s.size() > maxChars) s = s.substr(0, maxChars > 3 ? maxChars - 3 : 0) + "...";
  return s;
}

}  // namespace rodfab::common
