#pragma once
// Seeded mutations of valid inputs for the fuzz test (tests/fuzz) and the fuzz
// campaign (bench/fuzz_campaign.cpp): scene files, mesh files and protocol
// frames, each mutation a pure function of the seed (the same seed, the same
// input), so that any failure is replayed from the seed it prints.
#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

namespace sabo::testing::fuzz {

std::string read_file(const std::filesystem::path& path);

void write_file(const std::filesystem::path& path, std::string_view data);

class Mutator {
 public:
  explicit Mutator(std::uint64_t seed) : rng_(seed) {}

  std::size_t below(std::size_t n) { return n == 0 ? 0 : std::uniform_int_distribution<std::size_t>(0, n - 1)(rng_); }
  bool chance(double p) { return std::uniform_real_distribution<double>(0, 1)(rng_) < p; }
  std::uint8_t byte() { return static_cast<std::uint8_t>(below(256)); }
  std::string bytes(std::size_t n) {
    std::string out(n, '\0');
    for (char& c : out) c = static_cast<char>(byte());
    return out;
  }

  // Text (TOML, ASCII STL, Gmsh): 1-3 of number replaced by an extreme, token or line deleted, duplicated or
  // swapped, a byte flipped or inserted (NUL, non-UTF-8), the text cut short. `what` says which, for messages.
  std::string mutate_text(std::string text, std::string* what = nullptr) {
    const std::size_t count = 1 + below(3);
    for (std::size_t k = 0; k < count && !text.empty(); ++k) {
      switch (below(9)) {
        case 0:
        case 1:
        case 2: replace_number(text, what); break;
        case 3: line_operation(text, what); break;
        case 4: {
          const std::size_t at = below(text.size());
          text[at] = static_cast<char>(text[at] ^ (1 << below(8)));
          note(what, "bit flip at " + std::to_string(at));
          break;
        }
        case 5: {
          static constexpr std::array<std::string_view, 6> kInserts{
              std::string_view("\0", 1), "\xff", "\xc3", "[", "\"", "="};
          const std::size_t at = below(text.size() + 1);
          text.insert(at, kInserts[below(kInserts.size())]);
          note(what, "byte inserted at " + std::to_string(at));
          break;
        }
        case 6: {
          const std::size_t at = below(text.size());
          text.resize(at);
          note(what, "cut at " + std::to_string(at));
          break;
        }
        case 7: replace_token(text, what); break;
        default: {
          const std::size_t at = below(text.size());
          const std::size_t length = std::min(text.size() - at, 1 + below(40));
          text.insert(at, text.substr(below(text.size()), length));
          note(what, "span copied to " + std::to_string(at));
          break;
        }
      }
    }
    return text;
  }

  // Binary data (binary STL, protobuf bodies): bit flips, bytes set, a little-endian 32-bit word set to an
  // extreme (counts: 0, 2^31, 4e9), cut short or extended with random bytes.
  std::string mutate_bytes(std::string data, std::string* what = nullptr) {
    const std::size_t count = 1 + below(4);
    for (std::size_t k = 0; k < count; ++k) {
      if (data.empty()) {
        data = bytes(1 + below(64));
        continue;
      }
      switch (below(5)) {
        case 0: {
          const std::size_t at = below(data.size());
          data[at] = static_cast<char>(data[at] ^ (1 << below(8)));
          note(what, "bit flip at " + std::to_string(at));
          break;
        }
        case 1: {
          const std::size_t at = below(data.size());
          data[at] = static_cast<char>(byte());
          note(what, "byte set at " + std::to_string(at));
          break;
        }
        case 2: {
          if (data.size() < 4) break;
          static constexpr std::array<std::uint32_t, 5> kWords{0, 1, 0x80000000u, 4000000000u, 0xffffffffu};
          const std::uint32_t word = kWords[below(kWords.size())];
          const std::size_t at = below(data.size() - 3);
          for (int b = 0; b < 4; ++b)
            data[at + static_cast<std::size_t>(b)] = static_cast<char>((word >> (8 * b)) & 0xff);
          note(what, "word set at " + std::to_string(at));
          break;
        }
        case 3: {
          const std::size_t at = below(data.size());
          data.resize(at);
          note(what, "cut at " + std::to_string(at));
          break;
        }
        default: {
          data += bytes(1 + below(32));
          note(what, "extended");
          break;
        }
      }
    }
    return data;
  }

 private:
  static void note(std::string* what, const std::string& text) {
    if (what != nullptr) *what += (what->empty() ? "" : "; ") + text;
  }

  // The positions and lengths of the numbers of `text` (digits with their sign, point and exponent).
  static std::vector<std::pair<std::size_t, std::size_t>> numbers(const std::string& text) {
    std::vector<std::pair<std::size_t, std::size_t>> found;
    for (std::size_t k = 0; k < text.size();) {
      if (std::isdigit(static_cast<unsigned char>(text[k])) != 0 &&
          (k == 0 || std::isalpha(static_cast<unsigned char>(text[k - 1])) == 0)) {
        std::size_t end = k;
        while (end < text.size() &&
               (std::isdigit(static_cast<unsigned char>(text[end])) != 0 || text[end] == '.' || text[end] == 'e' ||
                text[end] == 'E' ||
                ((text[end] == '-' || text[end] == '+') && (text[end - 1] == 'e' || text[end - 1] == 'E')))) {
          ++end;
        }
        const std::size_t begin = k > 0 && text[k - 1] == '-' ? k - 1 : k;
        found.emplace_back(begin, end - begin);
        k = end;
      } else {
        ++k;
      }
    }
    return found;
  }

  void replace_number(std::string& text, std::string* what) {
    static constexpr std::array<std::string_view, 18> kExtremes{
        "0",    "-1",  "1e300", "-1e300", "1e-300", "nan", "inf", "-inf", "4294967296",
        "1e19", "0.0", "1e-4",  "-0.0",   "1e9",    "1e6", "2",   "0.5",  "18446744073709551615"};
    const auto found = numbers(text);
    if (found.empty()) return;
    const auto [at, length] = found[below(found.size())];
    const std::string_view replacement = kExtremes[below(kExtremes.size())];
    note(what, "number '" + text.substr(at, length) + "' -> '" + std::string(replacement) + "'");
    text.replace(at, length, replacement);
  }

  void replace_token(std::string& text, std::string* what) {
    static constexpr std::array<std::string_view, 10> kTokens{
        "true", "\"\"", "[]", "{}", "\"box\"", "\"mesh\"", "false", "[1.0, 2.0]", "\"x\"", "[[0.0, 0.0]]"};
    const std::size_t equals = text.find('=', below(text.size()));
    if (equals == std::string::npos) return;
    const std::size_t end = std::min(text.find('\n', equals), text.size());
    note(what, "value after '=' at " + std::to_string(equals) + " replaced");
    text.replace(equals + 1, end - equals - 1, " " + std::string(kTokens[below(kTokens.size())]));
  }

  void line_operation(std::string& text, std::string* what) {
    std::vector<std::string> lines;
    std::istringstream stream(text);
    for (std::string line; std::getline(stream, line);) lines.push_back(line);
    if (lines.empty()) return;
    const std::size_t a = below(lines.size()), b = below(lines.size());
    switch (below(3)) {
      case 0:
        note(what, "line " + std::to_string(a + 1) + " deleted");
        lines.erase(lines.begin() + static_cast<std::ptrdiff_t>(a));
        break;
      case 1:
        note(what, "line " + std::to_string(a + 1) + " repeated");
        lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(a), lines[a]);
        break;
      default:
        note(what, "lines " + std::to_string(a + 1) + " and " + std::to_string(b + 1) + " swapped");
        std::swap(lines[a], lines[b]);
        break;
    }
    text.clear();
    for (const auto& line : lines) text += line + "\n";
  }

  std::mt19937_64 rng_;
};

}  // namespace sabo::testing::fuzz
