#include "libsabo/io/profile_csv.hpp"

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

std::vector<ProfilePoint> read_profile_csv(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) {
    throw FileError(
        fmt::format("{}: cannot open the profile. Fix: give the path of a CSV file of distance and "
                    "elevation (m), relative to the scene file's folder",
                    file.string()));
  }
  std::vector<ProfilePoint> points;
  std::string text;
  int line = 0;
  bool first_row = true;
  while (std::getline(in, text)) {
    ++line;
    const std::size_t start = text.find_first_not_of(" \t\r");
    if (start == std::string::npos || text[start] == '#') continue;
    const std::vector<std::string> fields = split_fields(text.substr(start));
    const std::optional<double> distance = fields.empty() ? std::nullopt : parse_number(fields[0]);
    if (first_row && !distance) {  // a header
      first_row = false;
      continue;
    }
    first_row = false;
    const std::optional<double> elevation = fields.size() >= 2 ? parse_number(fields[1]) : std::nullopt;
    if (fields.size() != 2 || !distance || !elevation || !std::isfinite(*distance) || !std::isfinite(*elevation)) {
      throw FileError(
          fmt::format("{}:{}: '{}' is not a point of the profile. Fix: write two finite numbers, the "
                      "distance and the elevation in m, e.g. '120.0,1250.5'",
                      file.string(), line, text));
    }
    if (!points.empty() && !(*distance > points.back().distance)) {
      throw FileError(
          fmt::format("{}:{}: distance {} does not increase (line {} has {}): a profile is not "
                      "monotone in distance. Fix: sort the points by distance and drop repeated ones",
                      file.string(), line, *distance, points.back().line, points.back().distance));
    }
    points.push_back({*distance, *elevation, line});
  }
  if (in.bad()) throw FileError(fmt::format("{}:{}: cannot read the profile", file.string(), line));
  if (points.size() < 2) {
    throw FileError(
        fmt::format("{}: {} point{} of the profile; it needs at least two. Fix: one line "
                    "'distance,elevation' per point, distance increasing",
                    file.string(), points.size(), points.size() == 1 ? "" : "s"));
  }
  return points;
}

}  // namespace sabo::io
