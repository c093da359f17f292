#pragma once
// The problems a scene file has, collected while it is read and thrown together as one
// SceneError, sorted by line: every message names the file, line, key, value and the fix.
#include <fmt/format.h>

#include <algorithm>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "libsabo/core/error.hpp"

namespace sabo::scene::detail {

class Diagnostics {
 public:
  explicit Diagnostics(std::string file) : file_(std::move(file)) {}

  // "FILE:LINE: key 'K' = VALUE: PROBLEM. Fix: FIX."
  void add(int line, std::string_view key, const std::optional<std::string>& value, std::string_view problem,
           std::string_view fix) {
    std::string text = fmt::format("{}:{}: key '{}'", file_, line, key);
    if (value) text += " = " + *value;
    text += fmt::format(": {}", problem);
    if (!problem.ends_with('?') && !problem.ends_with('.')) text += '.';
    if (!fix.empty()) text += fmt::format(" Fix: {}.", fix);
    problems_.push_back({line, std::move(text)});
  }
  // A problem of the file as a whole (no key).
  void add_plain(int line, std::string_view problem, std::string_view fix) {
    problems_.push_back({line, fmt::format("{}:{}: {}. Fix: {}.", file_, line, problem, fix)});
  }

  [[nodiscard]] std::size_t count() const { return problems_.size(); }

  void throw_if_any() {
    if (problems_.empty()) return;
    std::stable_sort(problems_.begin(), problems_.end(),
                     [](const Problem& a, const Problem& b) { return a.line < b.line; });
    std::string message;
    for (const auto& problem : problems_) message += (message.empty() ? "" : "\n") + problem.text;
    throw SceneError(message);
  }

 private:
  struct Problem {
    int line;
    std::string text;
  };
  std::string file_;
  std::vector<Problem> problems_;
};

}  // namespace sabo::scene::detail
