// The PLY checks (ply_checks.hpp): the header, then every list's length, before CGAL's reader.
#include "meshing/ply_checks.hpp"

#include "common/interrupt.hpp"
#include "common/quoted_text.hpp"
#include "meshing/meshing.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <utility>
#include <vector>

namespace rodfab::meshing::detail {

namespace {

// The body of a PLY file as its header lays it out: per element, scalar properties and lists (a count,
// then that many items), typed by name.
struct PlyProperty {
  std::string countType, itemType;  // countType empty: a scalar of itemType
};
struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;
};
struct PlyHeader {
  std::string format;         // ascii, binary_little_endian or binary_big_endian
  std::size_t bodyStart = 0;  // the byte after the end_header line
  std::vector<PlyElement> elements;
};

int plyTypeSize(const std::string& type) {
  if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1;
  if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2;
  if (type == "int" || type == "uint" || type == "int32" || type == "uint32" || type == "float" || type == "float32") return 4;
  if (type == "double" || type == "float64") return 8;
  return 0;
}

bool isPlyFloatType(const std::string& type) { return type == "float" || type == "float32" || type == "double" || type == "float64"; }

// One header line: its words as CGAL's reader extracts them from the line's stream, and where it is.
struct HeaderLine {
  std::istringstream words;
  int number;
  const std::string& source;

  [[noreturn]] void fail(const std::string& what) const {
    throw MeshError(source, "PLY header line " + std::to_string(number) + ": " + what);
  }
};

// Line 2, "format ascii 1.0": CGAL takes the format from the second word of line 2 whatever the first
// ("*format binary_little_endian" read as binary), and needs a version after it.
std::string readFormat(HeaderLine& line, const std::string& keyword) {
  std::string format, version;
  line.words >> format >> version;
  if (keyword != "format" || version.empty()) line.fail("expected 'format ascii 1.0' (or binary_little_endian, binary_big_endian)");
  if (format != "ascii" && format != "binary_little_endian" && format != "binary_big_endian")
    line.fail("unknown format " + common::quotedFromFile(format) + " (expected ascii, binary_little_endian or binary_big_endian)");
  return format;
}

// "element NAME COUNT", the count read as CGAL reads it: a std::size_t from the line's stream ("12ex" is
// 12, "-1" wraps to 2^64 - 1). A count read any other way let the list check walk another layout than
// CGAL's (a double's "0010000000000ex" failed to 0 while CGAL read 10^10 elements: fuzz_mesh_reader).
// Each element takes at least one byte of the file.
PlyElement readElement(HeaderLine& line, std::size_t fileBytes) {
  PlyElement element;
  std::size_t count = 0;
  if (!(line.words >> element.name >> count)) line.fail("expected 'element NAME COUNT'");
  if (count > fileBytes) line.fail("an element count the file's " + std::to_string(fileBytes) + " bytes cannot hold");
  element.count = count;
  return element;
}

// "property TYPE NAME" or "property list COUNT_TYPE ITEM_TYPE NAME". CGAL skips a property of a type it
// does not know (and reads the body as if it were not there), where the list check would read nothing
// (a list length of 1.7 GB passed: fuzz_mesh_reader); it reads a vertex's x, y, z as float or double
// whatever their declared type, and as scalars (a member call on a null pointer for a list: fuzzing).
PlyProperty readProperty(HeaderLine& line, const std::string& elementName) {
  PlyProperty property;
  std::string name;
  line.words >> property.itemType >> name;
  if (property.itemType == "list") {
    property.countType = std::exchange(name, {});  // a failed read would leave name as it was
    line.words >> property.itemType >> name;
  }
  if (plyTypeSize(property.itemType) == 0 || (!property.countType.empty() && plyTypeSize(property.countType) == 0))
    line.fail("a property of unknown type " + common::quotedFromFile(plyTypeSize(property.itemType) == 0 ? property.itemType : property.countType) +
              " (expected char, uchar, short, ushort, int, uint, float or double, or int8 to float64)");
  // CGAL generates lists only for integer counts and skips one counted by a float or double, reading
  // the body without it (a short count read from the wrong bytes went negative: a 2^64-element resize,
  // fuzz_mesh_reader).
  if (!property.countType.empty() && isPlyFloatType(property.countType))
    line.fail("a list counted by a " + property.countType + " (expected an integer count type: char, uchar, short, ushort, int or uint)");
  if (name.empty()) line.fail("a property without a name");
  const bool coordinate = (elementName == "vertex" || elementName == "vertices") && (name == "x" || name == "y" || name == "z");
  if (coordinate && !property.countType.empty()) line.fail("vertex coordinate " + name + " is a list (expected a float or double)");
  if (coordinate && !isPlyFloatType(property.itemType))
    line.fail("vertex coordinate " + name + " of type " + common::quotedFromFile(property.itemType) + " (expected float or double)");
  return property;
}

// The header read line by line as CGAL's PLY_reader::init reads it, so the list check walks the layout
// CGAL will read; what CGAL would misread is refused on the way (each undefined behaviour or an
// unbounded read in CGAL, found by fuzzing): a property before any element (CGAL adds it to the last
// element without checking there is one), a format line other than line 2 (CGAL ignores it), no
// end_header (CGAL then reads the body past the end of the file: a 3.4 GB allocation). Other lines
// (comments, obj_info) are CGAL's to read or refuse.
PlyHeader readPlyHeader(const std::string& bytes, const std::string& source) {
  PlyHeader header;
  std::size_t at = 0;
  for (int number = 1; at < bytes.size(); ++number) {
    const std::size_t eol = std::min(bytes.find('\n', at), bytes.size());
    HeaderLine line{std::istringstream(bytes.substr(at, eol - at)), number, source};
    at = eol + 1;
    std::string keyword;
    line.words >> keyword;
    if (number == 1) {
      if (keyword != "ply") line.fail("expected 'ply' (a PLY file's first word)");
    } else if (number == 2) {
      header.format = readFormat(line, keyword);
    } else if (keyword == "end_header") {
      header.bodyStart = std::min(at, bytes.size());
      return header;
    } else if (keyword == "format") {
      line.fail("a format line where PLY has it on line 2 only");
    } else if (keyword == "element") {
      header.elements.push_back(readElement(line, bytes.size()));
    } else if (keyword == "property") {
      if (header.elements.empty()) line.fail("a property before any element");
      header.elements.back().properties.push_back(readProperty(line, header.elements.back().name));
    }
  }
  throw MeshError(source, "the PLY header has no end_header line (was the file cut short?)");
}

// A binary number of `type` at `p` as a double.
double plyNumber(const char* p, const std::string& type, bool bigEndian) {
  char raw[8];
  const int size = plyTypeSize(type);
  std::memcpy(raw, p, static_cast<std::size_t>(size));
  if (bigEndian != (std::endian::native == std::endian::big)) std::reverse(raw, raw + size);
  const auto as = [&raw]<typename T>(T) {
    T value;
    std::memcpy(&value, raw, sizeof value);
    return static_cast<double>(value);
  };
  if (type == "char" || type == "int8") return as(std::int8_t{});
  if (type == "uchar" || type == "uint8") return as(std::uint8_t{});
  if (type == "short" || type == "int16") return as(std::int16_t{});
  if (type == "ushort" || type == "uint16") return as(std::uint16_t{});
  if (type == "int" || type == "int32") return as(std::int32_t{});
  if (type == "uint" || type == "uint32") return as(std::uint32_t{});
  if (type == "float" || type == "float32") return as(float{});
  return as(double{});
}

// The body's cursor: binary records or ASCII words, and the check of each list's declared length
// against the bytes left (an item takes its size in binary, a digit and a separator in ASCII).
class PlyBody {
public:
  PlyBody(const std::string& bytes, const PlyHeader& header, const std::string& source)
      : bytes_(bytes), at_(header.bodyStart), ascii_(header.format == "ascii"),
        bigEndian_(header.format == "binary_big_endian"), source_(source) {}
  // False at the end of the file.
  bool skip(const PlyProperty& property, const std::string& element, std::uint64_t index) {
    element_ = &element, index_ = index;
    if (property.countType.empty()) return advance(property.itemType);
    double count = 0;
    if (!read(property.countType, count)) return false;
    const std::size_t left = bytes_.size() - at_;
    const double room = ascii_ ? (double(left) + 1) / 2 : double(left) / plyTypeSize(property.itemType);
    if (!(count >= 0) || count != std::floor(count) || count > room)
      throw MeshError(source_, "PLY " + common::printableFromFile(element) + " " + std::to_string(index) + ": a list of " + formatCount(count) +
                                   " entries, more than the " + std::to_string(left) + " bytes after it can hold");
    for (double i = 0; i < count; ++i)
      if (!advance(property.itemType)) return false;
    return true;
  }

  // Bytes after the cursor other than white space (after a binary body: up to 16 bytes of line breaks
  // and spaces, which some writers end the file with, pass too).
  std::size_t bytesAfter() const {
    const std::size_t left = bytes_.size() - at_;
    const std::size_t next = bytes_.find_first_not_of(" \t\n\v\f\r", at_);
    if (next == std::string::npos) return ascii_ || left <= 16 ? 0 : left;  // white space only
    return ascii_ ? bytes_.size() - next : left;
  }

private:
  static std::string formatCount(double count) {
    char text[32];
    std::snprintf(text, sizeof text, "%.10g", count);
    return text;
  }
  bool read(const std::string& type, double& value) {
    if (!ascii_) {
      if (bytes_.size() - at_ < std::size_t(plyTypeSize(type))) return false;
      value = plyNumber(bytes_.data() + at_, type, bigEndian_);
      at_ += std::size_t(plyTypeSize(type));
      return true;
    }
    const std::size_t begin = skipWord();
    if (begin == std::string::npos) return false;
    value = asciiNumber(begin, type);
    return true;
  }
  bool advance(const std::string& type) {
    if (ascii_) {
      const std::size_t begin = skipWord();
      if (begin != std::string::npos) asciiNumber(begin, type);
      return begin != std::string::npos;
    }
    if (bytes_.size() - at_ < std::size_t(plyTypeSize(type))) return false;
    at_ += std::size_t(plyTypeSize(type));
    return true;
  }
  // Moves past the next ASCII word (separated as CGAL's stream extraction separates them); its start,
  // or npos at the end of the file.
  std::size_t skipWord() {
    static constexpr const char* kSpace = " \t\n\v\f\r";
    const std::size_t begin = bytes_.find_first_not_of(kSpace, at_);
    if (begin != std::string::npos) at_ = std::min(bytes_.find_first_of(kSpace, begin), bytes_.size());
    return begin;
  }
  // The ASCII word from `begin` to the cursor as a number of `type`. The whole word must be one: CGAL
  // extracts an integer from "0-1" and reads "-1" as the next number (as 4294967295 for a list's
  // length: a 4 GB allocation, found by fuzzing), so any other word would make its reading and this
  // check's part ways.
  double asciiNumber(std::size_t begin, const std::string& type) {
    const std::string word(bytes_, begin, std::min<std::size_t>(at_ - begin, 64));
    const bool integer = !isPlyFloatType(type);
    char* end = nullptr;
    const double value = std::strtod(word.c_str(), &end);
    const std::size_t digits = !word.empty() && (word[0] == '+' || word[0] == '-') ? 1 : 0;  // after the sign
    const bool whole = at_ - begin <= 64 && (integer ? word.size() > digits && word.find_first_not_of("0123456789", digits) == std::string::npos
                                                     : !word.empty() && end == word.c_str() + word.size());
    if (!whole)
      throw MeshError(source_, "PLY " + common::printableFromFile(*element_) + " " + std::to_string(index_) + ": " + common::quotedFromFile(word, 32) + " is not " +
                                   (integer ? "an integer" : "a number") + " (a " + type + " property)");
    return value;
  }

  const std::string& bytes_;
  std::size_t at_;
  bool ascii_, bigEndian_;
  const std::string* element_ = nullptr;  // where the cursor is, for messages
  std::uint64_t index_ = 0;
  const std::string& source_;
};

}  // namespace

// CGAL's PLY reader sizes a list from its declared length before reading it, so one lying length (a
// face of 2,000,000,000 corners in a 150-byte file) grew the process to the memory budget (7.9 GB, 39 s
// on a 24 GiB machine) before it failed. Every list's length is checked against the bytes left first.
// A body shorter than its header declares is refused too: past the end CGAL's reads leave their number
// uninitialised (a binary read keeps its buffer; an ASCII read on a stream already failed stores
// nothing), so a list's length there is whatever the stack held (a 3.4 GB allocation and a loop of 14 s
// in fuzz_mesh_reader, 2026-12-05). The header is read once, as CGAL reads it (readPlyHeader), for both
// checks: four fuzz findings were places where two parses of it, or one of them and CGAL's, differed.
void checkPly(const std::string& bytes, const std::string& source) {
  const PlyHeader header = readPlyHeader(bytes, source);
  PlyBody body(bytes, header, source);
  for (const PlyElement& element : header.elements)
    for (std::uint64_t i = 0; i < element.count; ++i) {
      if (i % 65536 == 0) common::throwIfInterrupted();
      for (const PlyProperty& property : element.properties)
        if (!body.skip(property, element.name, i))
          throw MeshError(source, "PLY " + common::printableFromFile(element.name) + " " + std::to_string(i) + ": the file ends inside it (its " +
                                      std::to_string(bytes.size()) + " bytes hold less than the header declares: was it cut short?)");
    }
  // CGAL stops at the declared counts: faces written past them (a header count left stale) were dropped
  // without a word, half a sphere read as a whole one.
  if (const std::size_t extra = body.bytesAfter(); extra > 0)
    throw MeshError(source, "PLY: " + std::to_string(extra) + " bytes follow the elements the header declares (" +
                                common::printableFromFile(header.elements.empty() ? std::string() : header.elements.back().name) +
                                " last): a count in the header is smaller than the data (nothing was read)");
}

}  // namespace rodfab::meshing::detail
