#pragma once
// "Did you mean ...?" for scene errors: the nearest allowed word by edit distance.
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace sabo::scene {

// Optimal-string-alignment distance (insertions, deletions, substitutions and
// transpositions of neighbours each cost 1), ASCII case-insensitive.
[[nodiscard]] std::size_t edit_distance(std::string_view a, std::string_view b);

// The candidate nearest to `word`, if it is near enough to be a likely typo
// (distance 1 for words up to 4 letters, 2 up to 8, 3 beyond). Ties go to the
// earlier candidate.
[[nodiscard]] std::optional<std::string> closest_match(std::string_view word,
                                                       const std::vector<std::string>& candidates);

}  // namespace sabo::scene
