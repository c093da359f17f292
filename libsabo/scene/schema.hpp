#pragma once
// The scene file schema as data: every table and key a scene file may hold,
// with its type, default, unit, allowed values and meaning. Each section's
// table is built beside the code that reads it (scene/sections/*.cpp); the
// loader validates against it and takes defaults from it; markdown() renders
// docs/scene.md from it, so the reference cannot drift from the code.
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace sabo::scene::schema {

enum class Type {
  boolean,
  integer,
  number,  // TOML integer or float
  string,
  vec3,          // [x, y, z], numbers
  number_pair,   // [a, b], numbers
  pair_list,     // [[a, b], [c, d], ...], numbers
  string_list,   // [ "a", "b" ]
  table,         // [name] or inline { ... }
  table_list,    // [[name]] or [ { ... }, { ... } ]
  named_tables,  // [name.ANY] tables, each with the same keys
};

[[nodiscard]] std::string_view type_name(Type type);  // for docs: "number", "[x, y, z]" ...

// An interval of allowed numbers; open ends are absent.
struct Range {
  std::optional<double> min, max;
  bool min_exclusive = false, max_exclusive = false;

  [[nodiscard]] bool unbounded() const { return !min && !max; }
  [[nodiscard]] bool contains(double value) const;
  [[nodiscard]] std::string text() const;  // "> 0", ">= 0", "[0, 1)", "(0, 1]"
};

struct Table;

struct Key {
  std::string name;
  Type type = Type::number;
  bool required = false;
  std::string default_value;          // TOML literal used when the key is absent; empty: no default
  std::string when_absent;            // docs: what absence means when there is no default
  std::string example;                // TOML literal shown in fixes (required keys)
  std::string unit;                   // SI unit, empty for dimensionless
  Range range;                        // number, integer, and each element of number_pair
  std::vector<std::string> choices;   // string, and each element of string_list
  std::string allowed;                // docs: allowed values when neither range nor choices says it
  std::vector<std::string> only_for;  // values of the table's selector key this key belongs to
  std::string description;
  const Table* table = nullptr;  // table, table_list, named_tables: the keys inside
};

struct Table {
  std::string title;        // as written in a scene file: "[run]", "[[particles]]"
  std::string anchor;       // markdown anchor / short name
  std::string description;  // may span lines (markdown)
  std::string selector;     // key whose value picks the only_for keys ("shape"), or empty
  std::vector<Key> keys;

  [[nodiscard]] const Key* find(std::string_view name) const;
  [[nodiscard]] std::vector<std::string> key_names() const;
};

// The top level of a scene file.
[[nodiscard]] const Table& root();

// Every table of the schema in document order (root first).
[[nodiscard]] std::vector<const Table*> tables();

// Checks across keys that the per-key rows cannot say (docs only; the loader
// implements them).
[[nodiscard]] const std::vector<std::string>& cross_checks();

// A complete scene that uses most keys (docs; a test loads it).
[[nodiscard]] std::string_view example_scene();

// The markdown reference: docs/scene.md.
[[nodiscard]] std::string markdown();

}  // namespace sabo::scene::schema
