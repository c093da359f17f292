#include "libsabo/io/pairs_csv.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <optional>
#include <string>

#include "libsabo/core/error.hpp"

namespace sabo::io {
namespace {

std::vector<std::string> split_fields(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  bool blank_run = false;
  for (char c : line) {
    const bool blank = c == ' ' || c == '\t' || c == '\r';
    if (c == ',' || c == ';') {
      fields.push_back(field);
      field.clear();
      blank_run = false;
    } else if (blank) {
      blank_run = !field.empty();
    } else {
      if (blank_run) {  // blanks between two values separate them
        fields.push_back(field);
        field.clear();
        blank_run = false;
      }
      field += c;
    }
  }
  if (!field.empty() || !fields.empty()) fields.push_back(field);
  return fields;
}

std::optional<double> parse_number(const std::string& text) {
  double value = 0;
  const char* end = text.data() + text.size();
  const auto [rest, error] = std::from_chars(text.data(), end, value);
  if (error != std::errc() || rest != end) return std::nullopt;
  return value;
}

}  // namespace

std::vector<CsvPair> read_pairs_csv(const std::filesystem::path& file, const PairsCsvColumns& c) {
  std::ifstream in(file);
  if (!in) {
    throw FileError(
        fmt::format("{}: cannot open the {}. Fix: give the path of a CSV file of {} and {} ({}), relative to the "
                    "scene file's folder",
                    file.string(), c.table, c.first, c.second, c.units));
  }
  std::vector<CsvPair> points;
  std::string text;
  int line = 0;
  bool first_row = true;
  while (std::getline(in, text)) {
    ++line;
    const std::size_t start = text.find_first_not_of(" \t\r");
    if (start == std::string::npos || text[start] == '#') continue;
    const std::vector<std::string> fields = split_fields(text.substr(start));
    const std::optional<double> first = fields.empty() ? std::nullopt : parse_number(fields[0]);
    if (first_row && !first) {  // a header
      first_row = false;
      continue;
    }
    first_row = false;
    const std::optional<double> second = fields.size() >= 2 ? parse_number(fields[1]) : std::nullopt;
    if (fields.size() != 2 || !first || !second || !std::isfinite(*first) || !std::isfinite(*second)) {
      throw FileError(
          fmt::format("{}:{}: '{}' is not a point of the {}. Fix: write two finite numbers, the {} and the {} "
                      "({}), e.g. '{}'",
                      file.string(), line, text, c.table, c.first, c.second, c.units, c.example));
    }
    if (!points.empty() && !(*first > points.back().first)) {
      throw FileError(fmt::format(
          "{}:{}: {} {} does not increase (line {} has {}): a {} is not monotone in {}. Fix: sort "
          "the points by {} and drop repeated ones",
          file.string(), line, c.first, *first, points.back().line, points.back().first, c.table, c.first, c.first));
    }
    if (c.second_non_negative && *second < 0) {
      throw FileError(fmt::format("{}:{}: {} {} is negative. Fix: give a {} of at least 0", file.string(), line,
                                  c.second, *second, c.second));
    }
    points.push_back({*first, *second, line});
  }
  if (in.bad()) throw FileError(fmt::format("{}:{}: cannot read the {}", file.string(), line, c.table));
  if (points.size() < 2) {
    throw FileError(
        fmt::format("{}: {} point{} of the {}; it needs at least two. Fix: one line '{},{}' per point, {} "
                    "increasing",
                    file.string(), points.size(), points.size() == 1 ? "" : "s", c.table, c.first, c.second, c.first));
  }
  return points;
}

}  // namespace sabo::io
