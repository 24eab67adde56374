#include "calibration/data.hpp"

#include "common/json_input.hpp"
#include "common/quoted_text.hpp"

#include <boost/algorithm/string/case_conv.hpp>
#include <boost/algorithm/string/trim.hpp>
#include <boost/tokenizer.hpp>

#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

namespace rodfab::calibration {

namespace {

std::string formatIssues(const std::string& file, const std::vector<DataIssue>& issues) {
  std::ostringstream out;
  for (std::size_t i = 0; i < issues.size(); ++i) {
    if (i) out << '\n';
    out << file << ": ";
    if (issues[i].line > 0) out << "line " << issues[i].line << ": ";
    out << issues[i].message;
  }
  return out.str();
}

enum class Column { VeroFraction, ModulusMpa, TemperatureC, Specimen, Dither, Date, Notes };

const std::map<std::string, Column, std::less<>> kColumns = {
    {"vero_fraction", Column::VeroFraction}, {"modulus_mpa", Column::ModulusMpa},
    {"temperature_c", Column::TemperatureC}, {"specimen", Column::Specimen},
    {"dither", Column::Dither},              {"date", Column::Date},
    {"notes", Column::Notes}};

constexpr const char* kColumnList = "vero_fraction, modulus_mpa, temperature_c, specimen, dither, date, notes";

// A header name close to a known column but with another unit is the mistake worth naming: a modulus
// in GPa or a fraction in percent would otherwise fit silently wrong.
std::string unknownColumnMessage(const std::string& name) {
  const std::string column = "column " + common::quotedFromFile(name);
  const auto startsWith = [&](const char* prefix) { return name.rfind(prefix, 0) == 0; };
  if (startsWith("modulus") || startsWith("e_") || name == "e" || startsWith("storage_modulus"))
    return column + ": the modulus must be given in MPa, in a column named 'modulus_mpa'";
  if (startsWith("vero") || startsWith("fraction"))
    return column + ": the Vero share must be a fraction from 0 to 1, in a column named 'vero_fraction'";
  if (startsWith("temp"))
    return column + ": the temperature must be given in degrees Celsius, in a column named 'temperature_c'";
  return "unknown " + column + " (expected: " + kColumnList + ")";
}

std::optional<double> parseNumber(const std::string& field) {
  const char* first = field.data();
  const char* last = field.data() + field.size();
  if (first != last && *first == '+') ++first;  // from_chars refuses a leading '+', people write it
  double value = 0.0;
  const auto [end, ec] = std::from_chars(first, last, value);
  if (ec != std::errc() || end != last || first == last || !std::isfinite(value)) return std::nullopt;
  return value;
}

using Tokenizer = boost::tokenizer<boost::escaped_list_separator<char>>;

// A line of more fields is not read on: a header of 20 million unknown columns took 1.3 GB as fields.
constexpr std::size_t kMaxFields = 1024;

// Where the quoting that `line` leaves open began (npos when none is open): a quote that reopens right
// where the last one closed ("" inside a quoted field, RFC 4180's literal quote) continues the same run.
std::size_t openQuoteAt(std::string_view line) {
  constexpr std::size_t none = std::string_view::npos;
  std::size_t began = none, closed = none;
  bool open = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (line[i] == '\\') {
      ++i;
    } else if (line[i] == '"') {
      if (open) closed = i;
      else if (closed == none || closed + 1 != i) began = i;
      open = !open;
    }
  }
  return open ? began : none;
}

// Whether `text` leaves a quote open: an odd count of unescaped quotes.
bool leavesQuoteOpen(std::string_view text) { return openQuoteAt(text) != std::string_view::npos; }

// Splits one CSV record (quotes allowed around fields); nullopt when the quoting is broken. Stops after
// kMaxFields + 1 fields.
std::optional<std::vector<std::string>> splitFields(const std::string& line) {
  // The tokenizer accepts an unterminated quote silently; the count of quotes finds it.
  if (leavesQuoteOpen(line)) return std::nullopt;
  try {
    std::vector<std::string> fields;
    for (std::string field : Tokenizer(line, boost::escaped_list_separator<char>('\\', ',', '"'))) {
      boost::algorithm::trim(field);
      fields.push_back(std::move(field));
      if (fields.size() > kMaxFields) break;
    }
    return fields;
  } catch (const boost::escaped_list_error&) {
    return std::nullopt;
  }
}

using Issues = std::vector<DataIssue>;

constexpr std::size_t kMaxTextBytes = 256;  // a specimen, dither or date field
constexpr double kAbsoluteZeroC = -273.15, kMaxTemperatureC = 1000.0;

void addIssue(Issues& issues, int line, std::string message) { common::listIssue(issues, DataIssue{line, std::move(message)}); }

// The header's columns: per field position (nullopt for a rejected name) and each column's position.
struct Header {
  std::vector<std::optional<Column>> columns;
  std::map<Column, std::size_t> position;
};

// The header line's columns; an issue for every unknown or repeated name and missing required column.
Header readHeader(const std::vector<std::string>& fields, int lineNumber, Issues& issues) {
  const auto fail = [&](std::string message) { addIssue(issues, lineNumber, std::move(message)); };
  Header header;
  for (std::size_t i = 0; i < fields.size() && !common::issueListCut(issues); ++i) {
    const std::string name = boost::algorithm::to_lower_copy(fields[i]);
    const auto known = kColumns.find(name);
    if (known == kColumns.end()) {
      fail(unknownColumnMessage(name));
      header.columns.push_back(std::nullopt);
      continue;
    }
    if (header.position.count(known->second)) fail("column " + common::quotedFromFile(name) + " appears twice");
    header.position[known->second] = i;
    header.columns.push_back(known->second);
  }
  for (const char* required : {"vero_fraction", "modulus_mpa"})
    if (!header.position.count(kColumns.find(required)->second))
      fail(std::string("the header lacks the required column '") + required + "' (expected: " + kColumnList + ")");
  return header;
}

// One data row's measurement; nullopt after an issue for every field that cannot be used.
std::optional<Measurement> readRow(const std::vector<std::string>& fields, const Header& header, int lineNumber, Issues& issues) {
  const auto fail = [&](std::string message) { addIssue(issues, lineNumber, std::move(message)); };
  Measurement m;
  m.line = lineNumber;
  bool ok = true;
  const auto field = [&](Column c) -> const std::string* {
    auto it = header.position.find(c);
    return it == header.position.end() ? nullptr : &fields[it->second];
  };
  const auto number = [&](Column c, const char* name, const char* what, bool required) -> std::optional<double> {
    const std::string* f = field(c);
    if (!f || f->empty()) {
      if (required) fail(std::string(name) + ": missing; expected " + what), ok = false;
      return std::nullopt;
    }
    auto v = parseNumber(*f);
    if (!v) fail(std::string(name) + ": expected " + what + ", got " + common::quotedFromFile(*f)), ok = false;
    return v;
  };
  if (auto f = number(Column::VeroFraction, "vero_fraction", "a Vero fraction from 0 to 1", true)) {
    if (*f < 0.0 || *f > 1.0) {
      fail("vero_fraction: expected a fraction from 0 to 1, got " + common::quotedFromFile(*field(Column::VeroFraction)) +
           (*f > 1.0 && *f <= 100.0 ? " (a percentage? write it as a fraction)" : ""));
      ok = false;
    }
    m.veroFraction = *f;
  }
  if (auto e = number(Column::ModulusMpa, "modulus_mpa", "a modulus in MPa", true)) {
    if (!(*e > 0.0)) fail("modulus_mpa: expected a modulus > 0 MPa, got " + common::quotedFromFile(*field(Column::ModulusMpa))), ok = false;
    m.modulusMpa = *e;
  }
  m.temperatureC = number(Column::TemperatureC, "temperature_c", "a temperature in degrees Celsius", false);
  if (m.temperatureC && !(*m.temperatureC > kAbsoluteZeroC && *m.temperatureC <= kMaxTemperatureC))
    fail("temperature_c: expected a temperature above -273.15 and at most 1000 degrees Celsius, got " +
         common::quotedFromFile(*field(Column::TemperatureC))), ok = false;
  // Text reaches messages, reports and the calibration file: no control characters (a dither of
  // "\x1b[2J" cleared the terminal), and short.
  const auto text = [&](Column c, const char* name) -> std::string {
    const std::string* f = field(c);
    if (!f) return {};
    if (f->size() <= kMaxTextBytes && !common::holdsControlCharacters(*f)) return *f;
    fail(std::string(name) + ": expected text of at most " + std::to_string(kMaxTextBytes) + " bytes without control characters, got " +
         common::quotedFromFile(*f)), ok = false;
    return {};
  };
  m.specimen = text(Column::Specimen, "specimen");
  m.dither = text(Column::Dither, "dither");
  m.date = text(Column::Date, "date");
  if (!ok) return std::nullopt;
  return m;
}

// Whether the quote open at the end of `line` begins a field (after a comma or at the line's start,
// blanks aside), as a spreadsheet quotes a cell holding a line break (RFC 4180). A quote inside a
// field (5" coupon) joins nothing: the line is refused for its unbalanced quotes, as it was, rather
// than swallowing the rows up to the next stray quote into one field.
bool quoteOpensField(std::string_view line) {
  const std::size_t at = openQuoteAt(line);
  if (at == std::string_view::npos) return false;
  const std::size_t before = line.find_last_not_of(" \t", at == 0 ? std::string_view::npos : at - 1);
  return at == 0 || before == std::string_view::npos || line[before] == ',';
}

// Where the last unescaped quote of `line` is (npos when it has none).
std::size_t lastQuoteAt(std::string_view line) {
  std::size_t last = std::string_view::npos;
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (line[i] == '\\') ++i;
    else if (line[i] == '"') last = i;
  }
  return last;
}

// A field quoted across line breaks continues on the next lines: they are joined to `record`, each
// break read as a space, while its quote is open. Only a quote that opens a field (quoteOpensField)
// joins lines, and it must close a field too: its closing quote followed by a comma or the line's end
// (a missing closing quote, then a stray one inside a later field, would take the rows between into one
// text field). Empty when joined or nothing to join, else how the quote fails: still open at the end of
// the text or past kMaxRecordBytes, or closing inside a field.
constexpr std::size_t kMaxRecordBytes = 64 * 1024;
std::string joinQuotedLines(std::istream& lines, std::string& record, int& lineNumber) {
  if (!quoteOpensField(record)) return {};  // closed, or unbalanced within its line: splitFields says so
  std::string raw;
  // The quote's state carried line by line (splitFields checks the joined record again), so a long
  // record of short lines costs its length, not its length squared.
  for (bool open = true; open; open ^= leavesQuoteOpen(raw)) {
    if (record.size() > kMaxRecordBytes) return "is not closed within 64 KiB";
    if (!std::getline(lines, raw)) return "is not closed by the end of the file";
    ++lineNumber;
    if (!raw.empty() && raw.back() == '\r') raw.pop_back();
    record += ' ';
    record += raw;
  }
  // An odd count of quotes in the last line, starting inside the quote: its last one closes it.
  const std::size_t after = raw.find_first_not_of(" \t", lastQuoteAt(raw) + 1);
  if (after != std::string::npos && raw[after] != ',')
    return "closes inside a field on line " + std::to_string(lineNumber) + " (" + common::quotedFromFile(raw) +
           "), not at a comma or the line's end";
  return {};
}

}  // namespace

DataError::DataError(std::string file, std::vector<DataIssue> issues)
    : IssueListError(formatIssues(file, issues), file, issues) {}

DataSet parseData(std::string_view text, const std::string& sourceName) {
  DataSet data;
  data.source = sourceName;
  data.sha256 = sha256Hex(text);
  Issues issues;
  const auto fail = [&](int line, std::string message) { addIssue(issues, line, std::move(message)); };

  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);  // spreadsheet exports start with a BOM

  std::optional<Header> header;
  std::istringstream lines{std::string(text)};
  std::string raw;
  int lineNumber = 0;
  while (!common::issueListCut(issues) && std::getline(lines, raw)) {
    ++lineNumber;
    if (!raw.empty() && raw.back() == '\r') raw.pop_back();
    std::string line = boost::algorithm::trim_copy(raw);
    if (line.empty() || line.front() == '#') continue;
    const int recordLine = lineNumber;
    if (const std::string first = line, why = joinQuotedLines(lines, line, lineNumber); !why.empty()) {
      fail(recordLine, "unbalanced quotes: the quote opened in " + common::quotedFromFile(first) + " " + why);
      break;  // what follows cannot be told apart from the inside of the quote
    }
    const auto fields = splitFields(line);
    if (!fields) {
      fail(recordLine, "unbalanced quotes or a bad escape in " + common::quotedFromFile(line));
      continue;
    }
    if (fields->size() > kMaxFields) {
      fail(recordLine, "more than " + std::to_string(kMaxFields) + " fields; expected the columns " + kColumnList);
      break;
    }
    if (!header) {
      header = readHeader(*fields, recordLine, issues);
      if (!issues.empty()) break;  // rows cannot be read against a broken header
      continue;
    }
    if (fields->size() != header->columns.size()) {
      fail(recordLine, "expected " + std::to_string(header->columns.size()) + " fields (as in the header), got " +
                           std::to_string(fields->size()));
      continue;
    }
    if (std::optional<Measurement> m = readRow(*fields, *header, recordLine, issues)) data.measurements.push_back(std::move(*m));
    if (data.measurements.size() > kMaxMeasurements) {
      fail(recordLine, "more than " + std::to_string(kMaxMeasurements) + " measurements; a calibration fits at most that many");
      break;
    }
  }
  if (issues.empty() && !header)
    fail(0, std::string("no header line; expected a header naming the columns (") + kColumnList + ")");
  else if (issues.empty() && data.measurements.empty())
    fail(0, "no measurements after the header");
  if (!issues.empty()) throw DataError(sourceName, std::move(issues));
  return data;
}

DataSet readData(const std::filesystem::path& file) {
  std::string text;
  try {
    text = common::readBoundedFile(file.string(), kMaxDataBytes);
  } catch (const common::JsonInputError& e) {
    throw DataError(file.string(), {{0, e.message}});
  }
  return parseData(text, file.string());
}

}  // namespace rodfab::calibration
