// common/json_input: untrusted JSON is refused with the JSON path of what is wrong.
#include "common/json_input.hpp"

#include <catch2/catch.hpp>

#include <string>
#include <vector>

using rodfab::common::JsonInputError;
using rodfab::common::parseJsonStrict;

namespace {

// The path and message of the error parseJsonStrict throws for `text`.
JsonInputError errorOf(const std::string& text, int maxDepth = rodfab::common::kMaxJsonDepth,
                       std::size_t maxValues = std::numeric_limits<std::size_t>::max()) {
  try {
    parseJsonStrict(text, maxDepth, maxValues);
  } catch (const JsonInputError& e) {
    return e;
  }
  FAIL("no error for " << text);
  return JsonInputError("", "");
}

}  // namespace

TEST_CASE("A number beyond a double is refused at its JSON path, not by nlohmann without a place", "[common]") {
  const JsonInputError e = errorOf(R"({"a": {"list": [1, 2.5e3, -1e309]}, "b": 1e999})");
  CHECK(e.path == "a.list[2]");
  CHECK(e.message.find("line 1, column 27") != std::string::npos);
  CHECK(errorOf("[1e400]").path == "[0]");
  // Underflow is a number (zero), and large finite numbers pass.
  CHECK(parseJsonStrict("[1e-400, 1.7e308, -1.7e308]").size() == 3);
  // A number inside a string is not a number.
  CHECK(parseJsonStrict(R"({"s": "1e999"})")["s"] == "1e999");
}

TEST_CASE("Duplicate keys, depth and the number of values are refused at a path", "[common]") {
  CHECK(errorOf(R"({"rods": [{"name": "a", "name": "b"}]})").path == "rods[0].name");
  CHECK(errorOf("[[[[1]]]]", 3).path == "[0][0][0]");  // the fourth array, inside three
  const JsonInputError many = errorOf(R"({"x": [1, 2, 3, 4]})", 64, 4);
  CHECK(many.message.find("more than 4 values") != std::string::npos);
  CHECK(many.path == "x[2]");  // the object, the array and two numbers are the first four
  CHECK(parseJsonStrict(R"({"x": [1, 2, 3]})", 64, 5)["x"].size() == 3);
}

// nlohmann's lexer ends the input at a NUL byte: "{...}\0garbage" was a valid design, manifest or profile.
TEST_CASE("A NUL byte anywhere is malformed JSON, located", "[common]") {
  using namespace std::string_literals;
  CHECK(errorOf("{\"a\": 1}\0garbage"s).message == "malformed JSON at line 1, column 9: a NUL byte (JSON text holds none)");
  CHECK(errorOf("{\"a\":\n \"x\0y\"}"s).message == "malformed JSON at line 2, column 4: a NUL byte (JSON text holds none)");
  CHECK(parseJsonStrict("{\"a\": \"x\\u0000y\"}")["a"].get<std::string>() == "x\0y"s);  // escaped, it is a character like any other
}

TEST_CASE("The document built in one pass is the one nlohmann's own parser builds", "[common]") {
  // parseJsonStrict builds the document from SAX events itself; nlohmann's DOM parser is the truth.
  const std::vector<std::string> texts = {
      "null", "true", "-0", "0", "18446744073709551615", "-9223372036854775808", "1e-400", "2.5e3", R"("a\u00e9\n\"")",
      "[]", "{}", "[[], {}, [[]], {\"\": {}}]",
      R"({"rods": [{"name": "a", "e": [1, 2.5, -3], "open": true}, {"name": "b", "e": [], "open": null}], "z": {"y": {"x": [0]}}})",
      R"([{"b": 1, "a": 2}, [1, [2, [3, [4]]]], "s", 1.7976931348623157e308, -4.9e-324])",
  };
  for (const std::string& text : texts) {
    INFO(text);
    const nlohmann::json ours = parseJsonStrict(text);
    const nlohmann::json theirs = nlohmann::json::parse(text);
    CHECK(ours == theirs);
    CHECK(ours.dump() == theirs.dump());
    CHECK(ours.type() == theirs.type());
  }
  // Every value's type as nlohmann gives it (unsigned for non-negative integers), not only equal values.
  const nlohmann::json numbers = parseJsonStrict("[1, -1, 1.0, 18446744073709551615]");
  CHECK(numbers[0].is_number_unsigned());
  CHECK(numbers[1].is_number_integer());
  CHECK_FALSE(numbers[1].is_number_unsigned());
  CHECK(numbers[2].is_number_float());
  CHECK(numbers[3].get<std::uint64_t>() == 18446744073709551615ull);
  // Malformed text and trailing bytes are refused as nlohmann refuses them, with a line and column.
  for (const std::string bad : {"[1, 2", "{\"a\" 1}", "[1] x", "", "[01]"}) {
    INFO(bad);
    CHECK(errorOf(bad).message.find("malformed JSON at line 1, column") != std::string::npos);
  }
}

TEST_CASE("Messages name JSON paths and show values cut to a bounded size", "[common]") {
  using rodfab::common::describeJson;
  using rodfab::common::indexPath;
  using rodfab::common::memberPath;
  CHECK(memberPath("", "rods") == "rods");
  CHECK(memberPath(indexPath("rods", 3), "modulus") == "rods[3].modulus");
  CHECK(describeJson(nlohmann::json::parse(R"({"a":[1,2.5,"x"]})")) == R"({"a":[1,2.5,"x"]})");
  CHECK(describeJson(nlohmann::json("stiff")) == "\"stiff\"");

  SECTION("a long string is cut to the limit, quotes and dots included") {
    const std::string shown = describeJson(nlohmann::json(std::string(1'000'000, 'a')));
    CHECK(shown.size() == 40);
    std::string expected = "\"";  // not "\"" + ...: GCC 12 warns of a false overlap there (-Wrestrict)
    expected += std::string(36, 'a') + "...";
    CHECK(shown == expected);
  }
  SECTION("control characters are shown escaped, never written to the terminal as they are") {
    CHECK(describeJson(nlohmann::json(std::string("a\x1b[2J"))) == "\"a\\u001b[2J\"");  // nlohmann's own escape
    CHECK(describeJson(nlohmann::json(std::string("a\x7f" "b\xc2\x9b" "c\xc3\xa9"))) == "\"a\\u007fb\\u009bc\xc3\xa9\"");
    // A file's unknown key in a path: escaped and cut like any word of a file.
    CHECK(memberPath("rods[0]", "k\x1b[2J") == "rods[0].k\\x1b[2J");
    CHECK(memberPath("", std::string(1000, 'k')) == std::string(64, 'k') + "...");
  }
  SECTION("bytes that are not UTF-8 are replaced, not thrown on") {
    CHECK(describeJson(nlohmann::json(std::string("a\xff" "b"))) == "\"a\xef\xbf\xbd" "b\"");
  }
  SECTION("containers of more than 64 values are named by kind and size, nested or not") {
    CHECK(describeJson(nlohmann::json(std::vector<int>(20000, 7))) == "an array of 20000 values");
    nlohmann::json nested = nlohmann::json::array();
    for (int i = 0; i < 8; ++i) nested.push_back(std::vector<int>(10, i));
    CHECK(describeJson(nested) == "an array of 8 values");
    nlohmann::json small = nlohmann::json::object();
    small["k"] = std::vector<int>(3, 1);
    CHECK(describeJson(small) == R"({"k":[1,1,1]})");
  }
}

namespace {

// Whether `text` holds a byte a terminal may take for a command or show as garbage: C0 controls, DEL,
// anything from 0x80 on (this test's inputs quote no UTF-8 letters).
bool holdsRawBytes(const std::string& text) {
  for (const char c : text)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) return true;
  return false;
}

}  // namespace

TEST_CASE("A syntax error quotes the file's bytes escaped: C1 controls, DEL, ESC and bytes that are not UTF-8", "[common]") {
  // nlohmann quotes what it last read as it is (C0 controls as <U+001B>, everything else raw).
  const JsonInputError c1 = errorOf("{\"a\": tru\xc2\x9b}");
  CHECK_FALSE(holdsRawBytes(c1.message));
  CHECK(c1.message.find("last read: '\"a\": tru\\xc2'") != std::string::npos);
  const JsonInputError invalid = errorOf("{\"a\": \"x\xff\"}");
  CHECK_FALSE(holdsRawBytes(invalid.message));
  CHECK(invalid.message.find("\\xff'") != std::string::npos);
  const JsonInputError del = errorOf("[tru\x7f]");
  CHECK_FALSE(holdsRawBytes(del.message));
  CHECK(del.message.find("\\x7f") != std::string::npos);
  // A duplicate or too-deep key holding ESC is shown escaped in the path, as memberPath shows keys.
  const JsonInputError key = errorOf("{\"k\\u001b[2J\": 1, \"k\\u001b[2J\": 2}");  // ESC, as JSON must write it
  CHECK(key.path == "k\\x1b[2J");
  CHECK(errorOf("{\"\xc2\x9b\": [[1]]}", 2).path == "\\xc2\\x9b[0]");
}

TEST_CASE("printableJsonError escapes only the text quoted from the file, the library's words stay", "[common]") {
  using rodfab::common::printableJsonError;
  CHECK(printableJsonError("[json.exception.parse_error.101] parse error at line 1, column 3: syntax error while parsing value - "
                           "invalid literal; last read: 'x\xff'; expected end of input") ==
        "[json.exception.parse_error.101] parse error at line 1, column 3: syntax error while parsing value - invalid literal; "
        "last read: 'x\\xff'; expected end of input");
  CHECK(printableJsonError("invalid string: control character U+0000 (NUL) must be escaped to \\u0000; last read: '\"a<U+0000>'") ==
        "invalid string: control character U+0000 (NUL) must be escaped to \\u0000; last read: '\"a<U+0000>'");
  CHECK(printableJsonError("number overflow parsing '1e400'") == "number overflow parsing '1e400'");
  CHECK(printableJsonError("odd \x1b text") == "odd \\x1b text");
}
