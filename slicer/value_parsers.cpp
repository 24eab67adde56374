#include "slicer/value_parsers.hpp"

#include "common/quoted_text.hpp"
#include "printer_profiles/profile.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <sstream>

namespace rodfab::cli {

namespace {

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t"), last = s.find_last_not_of(" \t");
  return first == std::string::npos ? std::string() : s.substr(first, last - first + 1);
}

std::optional<double> parseNumber(const std::string& token) {
  double v = 0.0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (ec != std::errc() || end != token.data() + token.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> tokens;
  std::stringstream in(text);
  for (std::string token; std::getline(in, token, ',');) tokens.push_back(trim(token));
  if (!text.empty() && text.back() == ',') tokens.push_back("");
  return tokens;
}

// A list being read: the values and how each was typed (for the messages).
struct FractionList {
  std::vector<double> values;
  std::vector<std::string> spelled;
};

// Appends the values strictly between list.values.back() and `last` in steps of the last two values.
void continueProgression(FractionList& list, double last, const std::string& lastText, const std::string& fromText,
                         const std::string& option, const std::string& text, std::size_t maxCount) {
  const double from = list.values.back(), step = from - list.values[list.values.size() - 2];
  const double steps = step == 0.0 ? -1.0 : (last - from) / step;
  const double n = std::round(steps);
  if (!(n >= 1.0) || std::abs(steps - n) > 1e-6 * std::max(1.0, n))
    throw BadValue(option + ": steps of " + formatNumber(step) + " from " + fromText + " do not reach " + lastText);
  if (n > static_cast<double>(maxCount) || list.values.size() + static_cast<std::size_t>(n) > maxCount)
    throw BadValue(option + ": " + text + " makes more than " + std::to_string(maxCount) + " values");
  for (int m = 1; m < static_cast<int>(n); ++m) {
    list.values.push_back(std::round((from + m * step) * 1e9) / 1e9);
    list.spelled.push_back(formatNumber(list.values.back()));
  }
}

}  // namespace

std::string formatNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

std::vector<double> parseFractionList(const std::string& option, const std::string& text, std::size_t maxCount) {
  const std::vector<std::string> tokens = splitList(text);
  FractionList list;
  for (std::size_t t = 0; t < tokens.size(); ++t) {
    const std::string& token = tokens[t];
    if (token == "...") {
      if (list.values.size() < 2 || t + 2 != tokens.size())
        throw BadValue(option + ": '...' needs two values before it (the step) and exactly one after it (the last "
                                "value), e.g. 0,0.1,...,1");
      continue;
    }
    const std::optional<double> v = parseNumber(token);
    if (!v) throw BadValue(option + ": '" + token + "' is not a number");
    if (*v < 0.0 || *v > 1.0) throw BadValue(option + ": " + token + " is not a Vero fraction in [0, 1]");
    if (t >= 1 && tokens[t - 1] == "...") continueProgression(list, *v, token, tokens[t - 2], option, text, maxCount);
    list.values.push_back(*v);
    list.spelled.push_back(token);
  }
  if (list.values.empty()) throw BadValue(option + ": expected at least one Vero fraction, e.g. 0,0.1,...,1");
  if (list.values.size() > maxCount)
    throw BadValue(option + ": " + std::to_string(list.values.size()) + " values is more than " + std::to_string(maxCount));
  for (std::size_t a = 0; a < list.values.size(); ++a)
    for (std::size_t b = 0; b < a; ++b)
      if (static_cast<float>(list.values[a]) == static_cast<float>(list.values[b]))
        throw BadValue(option + ": " + list.spelled[a] + " is listed twice (as " + list.spelled[b] + ")");
  return list.values;
}

std::array<double, 3> parseSizeMm(const std::string& option, const std::string& text) {
  std::vector<double> values;
  std::size_t from = 0;
  for (std::size_t x = text.find('x'); from <= text.size(); x = text.find('x', from)) {
    const std::optional<double> v = parseNumber(trim(text.substr(from, x == std::string::npos ? x : x - from)));
    if (!v || !(*v > 0.0)) break;
    values.push_back(*v);
    from = x == std::string::npos ? text.size() + 1 : x + 1;
  }
  if (values.size() != 3 || from != text.size() + 1)
    throw BadValue(option + ": expected LENGTHxWIDTHxHEIGHT in mm, three positive numbers such as 30x5x1.5, got '" + text + "'");
  return {values[0], values[1], values[2]};
}

std::array<int, 3> parseSizeVoxels(const std::string& option, const std::string& text, int maxSide) {
  std::array<int, 3> sides{};
  const char* at = text.c_str();
  bool ok = true;
  for (int a = 0; a < 3 && ok; ++a) {
    ok = (a == 0 || *at++ == 'x') && *at >= '0' && *at <= '9';
    char* end = nullptr;
    errno = 0;
    const long side = ok ? std::strtol(at, &end, 10) : 0;
    ok = ok && errno != ERANGE && side >= 1 && side <= maxSide;
    sides[static_cast<std::size_t>(a)] = static_cast<int>(side);
    at = ok ? end : at;
  }
  if (!ok || *at != '\0')
    throw BadValue(option + ": expected XxYxZ in voxels, three whole numbers from 1 to " + std::to_string(maxSide) +
                   " such as 128x64x180, got '" + text + "'");
  return sides;
}

std::array<double, 3> parseVoxelSizeMm(const std::string& option, const std::string& text) {
  std::array<double, 3> size{};
  std::istringstream in(text);
  bool ok = true;
  for (std::size_t a = 0; a < 3 && ok; ++a) {
    ok = (a == 0 || in.get() == ',') && (in >> size[a]) && size[a] >= 1e-3 && size[a] <= 10.0;
  }
  if (!ok || in.peek() != std::char_traits<char>::eof())
    throw BadValue(option + ": expected three sizes from 0.001 to 10 mm as X,Y,Z (e.g. 0.0423,0.0846,0.030), got '" + text + "'");
  return size;
}

std::array<std::string, 2> parseMaterialPair(const std::string& option, const std::string& text) {
  const std::size_t comma = text.find(',');
  std::array<std::string, 2> pair;
  if (comma != std::string::npos) pair = {text.substr(0, comma), text.substr(comma + 1)};
  if (pair[0].empty() || pair[1].empty() || pair[1].find(',') != std::string::npos)
    throw BadValue(option + ": expected RIGID,RUBBERY (two material names), got " + common::quotedFromFile(text));
  if (pair[0] == pair[1])
    throw BadValue(option + ": expected two different materials (the coupons mix a rigid and a rubbery one), got " + common::quotedFromFile(text));
  // As printer profiles name materials: a calibration's materials are matched against a profile's.
  for (const std::string& name : pair)
    if (const std::string problem = printer_profiles::portableNameProblem(name); !problem.empty())
      throw BadValue(option + ": expected material names as printer profiles give them, got " + common::quotedFromFile(name) + ": " + problem);
  return pair;
}

}  // namespace rodfab::cli
