#pragma once
// The generic reader of the scene loader: one TOML table against its schema table.
#include <toml++/toml.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "libsabo/core/types.hpp"
#include "libsabo/scene/detail/diagnostics.hpp"
#include "libsabo/scene/detail/text.hpp"
#include "libsabo/scene/schema.hpp"

namespace sabo::scene::detail {

// Defaults of the schema, parsed once from their TOML literals.
const toml::node& default_node(const Key& key);
const toml::table& empty_table();

// Reads the keys of one table against its schema: type, range, choices,
// required and unknown keys, each problem reported once to Diagnostics.
// Getters return nullopt when the key is absent without a default or wrong.
class Reader {
 public:
  Reader(Diagnostics& diagnostics, const Table& spec, const toml::table& table, std::string path);
  void select(const std::string& variant);

  [[nodiscard]] bool has(std::string_view name) const { return table_.get(name) != nullptr; }
  [[nodiscard]] const toml::node* node(std::string_view name) const { return table_.get(name); }
  [[nodiscard]] int line() const { return line_of(table_); }
  [[nodiscard]] int line(std::string_view name) const;
  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] std::string key_path(std::string_view name) const {
    return path_.empty() ? std::string(name) : path_ + "." + std::string(name);
  }
  std::optional<double> number(std::string_view name);
  std::optional<std::int64_t> integer(std::string_view name);
  std::optional<bool> boolean(std::string_view name);
  std::optional<std::string> string(std::string_view name);
  std::optional<Vec3> vec3(std::string_view name);
  std::optional<std::array<double, 2>> pair(std::string_view name);
  std::optional<std::vector<std::array<double, 2>>> pairs(std::string_view name);
  std::optional<std::vector<std::string>> strings(std::string_view name);
  const toml::table* table(std::string_view name);
  const toml::array* table_list(std::string_view name);
  std::vector<std::pair<std::string, const toml::table*>> named_tables(std::string_view name);

 private:
  struct Found {
    const Key* key;
    const toml::node* node;
  };

  [[nodiscard]] bool applies(const Key& key) const {
    return key.only_for.empty() || std::find(key.only_for.begin(), key.only_for.end(), variant_) != key.only_for.end();
  }

  [[nodiscard]] std::string place() const { return path_.empty() ? "at the top level" : "in '" + path_ + "'"; }
  static std::vector<std::string> quote_all(const std::vector<std::string>& words);
  std::optional<Found> lookup(std::string_view name, Type type);
  static std::optional<double> as_number(const toml::node& node);
  static std::optional<std::vector<double>> numbers(const toml::node& node, std::size_t size);

  void report(const Found& found, std::string_view problem, std::string_view fix) {
    diag_.add(line_of(*found.node), key_path(found.key->name), value_text(*found.node), problem, fix);
  }
  std::nullopt_t type_error(const Found& found);
  bool all_finite(const Found& found, const std::vector<double>& values);
  std::optional<double> checked_number(const Found& found, double value);
  bool check_choice(const Found& found, const std::string& value, const toml::node& value_node);

  Diagnostics& diag_;
  const Table& spec_;
  const toml::table& table_;
  std::string path_;
  std::string variant_;
};

const Table& spec(std::string_view anchor);

}  // namespace sabo::scene::detail
