// common/json_input: untrusted JSON is refused with the JSON path of what is wrong.
#include "common/json_input.hpp"

#include <catch2/catch.hpp>

#include <string>

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
