#pragma once
// A longitudinal profile from a CSV file: one point per line, "distance,elevation" (m), the distance
// strictly increasing. Blank lines and lines starting with '#' are skipped; the first other line may be
// a header (its first field not a number). Fields are separated by a comma, a semicolon or blanks.
#include <array>
#include <filesystem>
#include <vector>

namespace sabo::io {

struct ProfilePoint {
  double distance = 0;   // m, along the profile's horizontal direction
  double elevation = 0;  // m, absolute
  int line = 0;          // in the file, from 1
};

// Throws FileError naming the file, the line, the text there and the fix: a file that does not open, a
// line that is not two finite numbers, a distance that does not increase, fewer than two points.
[[nodiscard]] std::vector<ProfilePoint> read_profile_csv(const std::filesystem::path& file);

}  // namespace sabo::io
