#pragma once
// A table of two columns from a CSV file (a channel's longitudinal profile, an inflow's hydrograph): one
// point per line, the first column strictly increasing. Blank lines and lines starting with '#' are
// skipped; the first other line may be a header (its first field not a number). Fields are separated by
// a comma, a semicolon or blanks.
#include <filesystem>
#include <string>
#include <vector>

namespace sabo::io {

// What a file holds, for its messages.
struct PairsCsvColumns {
  std::string table;    // "profile"
  std::string first;    // "distance": the column that increases
  std::string second;   // "elevation"
  std::string units;    // "m"
  std::string example;  // a line of the file: "120.0,1250.5"
  bool second_non_negative = false;
};
inline const PairsCsvColumns kProfileColumns{"profile", "distance", "elevation", "m", "120.0,1250.5"};
inline const PairsCsvColumns kHydrographColumns{"hydrograph", "time", "discharge", "s and m^3/s", "12.0,1530.0", true};

struct CsvPair {
  double first = 0;
  double second = 0;
  int line = 0;  // in the file, from 1
};

// Throws FileError naming the file, the line, the text there and the fix: a file that does not open, a
// line that is not two finite numbers, a first column that does not increase, a negative second column
// where it may not be, fewer than two points.
[[nodiscard]] std::vector<CsvPair> read_pairs_csv(const std::filesystem::path& file, const PairsCsvColumns& columns);

}  // namespace sabo::io
