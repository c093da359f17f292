#include "libsabo/scene/loader.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cassert>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/hexahedron.hpp"
#include "libsabo/geometry/polygon.hpp"
#include "libsabo/geometry/primitives.hpp"
#include "libsabo/geometry/sphere_fill.hpp"
#include "libsabo/io/gmsh.hpp"
#include "libsabo/io/gmsh_groups.hpp"
#include "libsabo/io/stl.hpp"
#include "libsabo/physics/stable_step.hpp"
#include "libsabo/scene/estimate.hpp"
#include "libsabo/scene/schema.hpp"
#include "libsabo/scene/sensor_patch.hpp"
#include "libsabo/scene/suggest.hpp"

namespace sabo::scene {
namespace {

namespace fs = std::filesystem;
using schema::Key;
using schema::Table;
using schema::Type;

// Random filling jams well before dense packing; past this expected solid
// fraction of the box a fill would likely not fit (docs/scene.md says so).
constexpr double kMaxFillSolidFraction = 0.3;
// Overlap reports beyond this many are summarised in one line.
constexpr std::size_t kMaxOverlapReports = 20;

// ---------------------------------------------------------------- text ----

std::string number_literal(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  if (value == std::floor(value) && std::abs(value) < 1e15) return fmt::format("{:.1f}", value);
  return fmt::format("{}", value);
}

std::string quote_text(std::string_view text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += fmt::format("\\u{:04x}", static_cast<int>(c));
    } else {
      out += c;
    }
  }
  return out + "\"";
}

// A node as TOML-like text for messages, shortened to about `limit` characters.
std::string value_text(const toml::node& node, std::size_t limit = 80) {
  std::string text;
  if (const auto* s = node.as_string()) {
    text = quote_text(s->get());
  } else if (const auto* i = node.as_integer()) {
    text = std::to_string(i->get());
  } else if (const auto* f = node.as_floating_point()) {
    text = number_literal(f->get());
  } else if (const auto* b = node.as_boolean()) {
    text = b->get() ? "true" : "false";
  } else if (const auto* array = node.as_array()) {
    text = "[";
    for (std::size_t k = 0; k < array->size() && text.size() <= limit; ++k) {
      text += (k ? ", " : "") + value_text(*array->get(k), limit);
    }
    text += "]";
  } else if (const auto* table = node.as_table()) {
    text = "{";
    bool first = true;
    for (auto&& [key, value] : *table) {
      if (text.size() > limit) break;
      text += (first ? " " : ", ") + std::string(key.str()) + " = " + value_text(value, limit);
      first = false;
    }
    text += first ? "}" : " }";
  } else {
    std::ostringstream stream;
    node.visit([&](const auto& v) { stream << v; });
    text = stream.str();
  }
  if (text.size() > limit) text = text.substr(0, limit) + "...";
  return text;
}

std::string_view kind_of(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::string: return "a string";
    case toml::node_type::integer: return "an integer";
    case toml::node_type::floating_point: return "a float";
    case toml::node_type::boolean: return "a boolean";
    case toml::node_type::array: return "an array";
    case toml::node_type::table: return "a table";
    default: return "a date/time";
  }
}

std::string_view expected_kind(Type type) {
  switch (type) {
    case Type::boolean: return "true or false";
    case Type::integer: return "an integer";
    case Type::number: return "a number";
    case Type::string: return "a string";
    case Type::vec3: return "an array of 3 numbers [x, y, z]";
    case Type::number_pair: return "an array of 2 numbers [min, max]";
    case Type::pair_list: return "an array of [a, b] number pairs";
    case Type::string_list: return "an array of strings";
    case Type::table: return "a table";
    case Type::table_list: return "an array of tables";
    case Type::named_tables: return "a table of named tables";
  }
  return "?";
}

std::string join(const std::vector<std::string>& words, std::string_view separator = ", ") {
  std::string out;
  for (const auto& word : words) out += (out.empty() ? "" : std::string(separator)) + word;
  return out;
}

std::string noun(std::string_view key_name) {
  std::string text(key_name);
  std::replace(text.begin(), text.end(), '_', ' ');
  return text;
}

std::string unit_suffix(const Key& key) {
  return key.unit.empty() ? "" : " (" + key.unit + ")";
}

int line_of(const toml::node& node) {
  return static_cast<int>(node.source().begin.line);
}

bool valid_name(std::string_view name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' || c == '-';
  });
}

bool valid_endpoint(std::string_view endpoint) {
  if (endpoint == "ipc") return true;
  constexpr std::string_view prefix = "tcp://";
  if (!endpoint.starts_with(prefix)) return false;
  const std::string_view rest = endpoint.substr(prefix.size());
  const auto colon = rest.rfind(':');
  if (colon == std::string_view::npos || colon == 0) return false;
  const std::string_view host = rest.substr(0, colon), port = rest.substr(colon + 1);
  const bool bracketed = host.size() > 2 && host.front() == '[' && host.back() == ']';
  const bool plain_host = std::all_of(host.begin(), host.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '.' || c == '-' || c == '_' || c == '*';
  });
  if (!bracketed && !plain_host) return false;
  if (port.empty() || port.size() > 5 ||
      !std::all_of(port.begin(), port.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); })) {
    return false;
  }
  const int number = std::stoi(std::string(port));
  return number >= 1 && number <= 65535;
}

// A host written as digits and dots is an IPv4 address, four numbers 0 to 255 (tcp://999.1.1.1:5555 used to
// reach the coupler, which could not bind it: "No such device"). The problem, if any.
std::optional<std::string> ipv4_problem(std::string_view endpoint) {
  const std::string_view rest = endpoint.substr(std::string_view("tcp://").size());
  const std::string_view host = rest.substr(0, rest.rfind(':'));
  if (host.empty() || !std::all_of(host.begin(), host.end(), [](char c) { return std::isdigit(c) || c == '.'; })) {
    return std::nullopt;
  }
  std::vector<std::string> parts;
  for (std::size_t start = 0;;) {
    const auto dot = host.find('.', start);
    parts.emplace_back(host.substr(start, dot == std::string_view::npos ? host.npos : dot - start));
    if (dot == std::string_view::npos) break;
    start = dot + 1;
  }
  if (parts.size() != 4) {
    return fmt::format("the host {} is not an IPv4 address: it has {} numbers, an address has 4", host, parts.size());
  }
  for (const auto& part : parts) {
    if (part.empty() || part.size() > 3 || std::stoi(part) > 255) {
      return fmt::format("the host {} is not an IPv4 address: {} is not a number from 0 to 255", host,
                         part.empty() ? "an empty part" : part);
    }
  }
  return std::nullopt;
}

bool is_executable_file(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec) && ::access(path.c_str(), X_OK) == 0;
}

// ---------------------------------------------------------- diagnostics ----

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

// Defaults of the schema, parsed once from their TOML literals.
const toml::node& default_node(const Key& key) {
  static const std::map<const Key*, toml::table> defaults = [] {
    std::map<const Key*, toml::table> parsed;
    for (const Table* table : schema::tables()) {
      for (const Key& k : table->keys) {
        if (!k.default_value.empty()) parsed.emplace(&k, toml::parse("value = " + k.default_value));
      }
    }
    return parsed;
  }();
  auto it = defaults.find(&key);
  assert(it != defaults.end() && "only keys with a default reach here");
  return *it->second.get("value");
}

const toml::table& empty_table() {
  static const toml::table empty;
  return empty;
}

// ---------------------------------------------------------------- reader ----

// Reads the keys of one table against its schema: type, range, choices,
// required and unknown keys, each problem reported once to Diagnostics.
// Getters return nullopt when the key is absent without a default or wrong.
class Reader {
 public:
  Reader(Diagnostics& diagnostics, const Table& spec, const toml::table& table, std::string path)
      : diag_(diagnostics), spec_(spec), table_(table), path_(std::move(path)) {
    for (auto&& [key, node] : table_) {
      if (spec_.find(key.str()) != nullptr) continue;
      const std::string name(key.str());
      const int line = key.source().begin.line != 0 ? static_cast<int>(key.source().begin.line) : line_of(node);
      const auto suggestion = closest_match(name, spec_.key_names());
      if (suggestion) {
        diag_.add(line, key_path(name), value_text(node), fmt::format("unknown key. Did you mean '{}'?", *suggestion),
                  fmt::format("rename it to '{}'", *suggestion));
      } else {
        diag_.add(line, key_path(name), value_text(node), "unknown key",
                  fmt::format("remove it; the keys allowed {} are: {}", place(), join(spec_.key_names())));
      }
    }
  }

  // Picks the keys of one value of the table's selector (structures: the
  // shape) and reports keys given that belong to other values.
  void select(const std::string& variant) {
    variant_ = variant;
    for (const Key& key : spec_.keys) {
      if (key.only_for.empty() || applies(key)) continue;
      if (const toml::node* node = table_.get(key.name)) {
        diag_.add(line_of(*node), key_path(key.name), value_text(*node),
                  fmt::format("belongs to {} = {}, not to {} = {}", spec_.selector,
                              join(quote_all(key.only_for), " or "), spec_.selector, quote_text(variant)),
                  fmt::format("remove it, or change {}", spec_.selector));
      }
    }
  }

  [[nodiscard]] bool has(std::string_view name) const { return table_.get(name) != nullptr; }
  [[nodiscard]] const toml::node* node(std::string_view name) const { return table_.get(name); }
  [[nodiscard]] int line() const { return line_of(table_); }
  [[nodiscard]] int line(std::string_view name) const {
    const toml::node* n = table_.get(name);
    return n != nullptr ? line_of(*n) : line();
  }
  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] std::string key_path(std::string_view name) const {
    return path_.empty() ? std::string(name) : path_ + "." + std::string(name);
  }

  std::optional<double> number(std::string_view name) {
    auto found = lookup(name, Type::number);
    if (!found) return std::nullopt;
    const auto value = as_number(*found->node);
    if (!value) return type_error(*found);
    return checked_number(*found, *value);
  }

  std::optional<std::int64_t> integer(std::string_view name) {
    auto found = lookup(name, Type::integer);
    if (!found) return std::nullopt;
    const auto* node = found->node->as_integer();
    if (node == nullptr) return type_error(*found);
    if (!checked_number(*found, static_cast<double>(node->get()))) return std::nullopt;
    return node->get();
  }

  std::optional<bool> boolean(std::string_view name) {
    auto found = lookup(name, Type::boolean);
    if (!found) return std::nullopt;
    const auto* node = found->node->as_boolean();
    if (node == nullptr) return type_error(*found);
    return node->get();
  }

  std::optional<std::string> string(std::string_view name) {
    auto found = lookup(name, Type::string);
    if (!found) return std::nullopt;
    const auto* node = found->node->as_string();
    if (node == nullptr) return type_error(*found);
    const std::string& value = node->get();
    if (!found->key->choices.empty() && !check_choice(*found, value, *found->node)) return std::nullopt;
    return value;
  }

  std::optional<Vec3> vec3(std::string_view name) {
    auto found = lookup(name, Type::vec3);
    if (!found) return std::nullopt;
    const auto values = numbers(*found->node, 3);
    if (!values) return type_error(*found);
    if (!all_finite(*found, *values)) return std::nullopt;
    return Vec3((*values)[0], (*values)[1], (*values)[2]);
  }

  std::optional<std::array<double, 2>> pair(std::string_view name) {
    auto found = lookup(name, Type::number_pair);
    if (!found) return std::nullopt;
    const auto values = numbers(*found->node, 2);
    if (!values) return type_error(*found);
    if (!all_finite(*found, *values)) return std::nullopt;
    const Key& key = *found->key;
    if (!key.range.contains((*values)[0]) || !key.range.contains((*values)[1])) {
      report(*found,
             fmt::format("every element must be {}{}{}", key.range.min && key.range.max ? "in " : "", key.range.text(),
                         unit_suffix(key)),
             fmt::format("give {} values {}", noun(key.name), key.range.text()));
      return std::nullopt;
    }
    return std::array<double, 2>{(*values)[0], (*values)[1]};
  }

  // An array of [a, b] number pairs (finite); the schema's range is not applied (columns differ).
  std::optional<std::vector<std::array<double, 2>>> pairs(std::string_view name) {
    auto found = lookup(name, Type::pair_list);
    if (!found) return std::nullopt;
    const auto* array = found->node->as_array();
    if (array == nullptr) return type_error(*found);
    std::vector<std::array<double, 2>> rows;
    for (const auto& element : *array) {
      const auto values = numbers(element, 2);
      if (!values) return type_error(*found);
      if (!all_finite(*found, *values)) return std::nullopt;
      rows.push_back({(*values)[0], (*values)[1]});
    }
    return rows;
  }

  std::optional<std::vector<std::string>> strings(std::string_view name) {
    auto found = lookup(name, Type::string_list);
    if (!found) return std::nullopt;
    const auto* array = found->node->as_array();
    if (array == nullptr) return type_error(*found);
    std::vector<std::string> values;
    for (const auto& element : *array) {
      const auto* text = element.as_string();
      if (text == nullptr) return type_error(*found);
      values.push_back(text->get());
    }
    if (!found->key->choices.empty()) {
      for (std::size_t k = 0; k < values.size(); ++k) {
        if (!check_choice(*found, values[k], *array->get(k))) return std::nullopt;
      }
    }
    return values;
  }

  // A sub-table; nullptr when absent or not a table (reported).
  const toml::table* table(std::string_view name) {
    auto found = lookup(name, Type::table);
    if (!found) return nullptr;
    const auto* value = found->node->as_table();
    if (value == nullptr) type_error(*found);
    return value;
  }

  // An array of tables; nullptr when absent or wrong (reported).
  const toml::array* table_list(std::string_view name) {
    auto found = lookup(name, Type::table_list);
    if (!found) return nullptr;
    const auto* array = found->node->as_array();
    if (array == nullptr ||
        !std::all_of(array->begin(), array->end(), [](const toml::node& n) { return n.is_table(); })) {
      type_error(*found);
      return nullptr;
    }
    return array;
  }

  // A table whose values are tables ([materials.NAME]); nullptr when absent.
  // Values that are not tables are reported and left out of the result.
  std::vector<std::pair<std::string, const toml::table*>> named_tables(std::string_view name) {
    std::vector<std::pair<std::string, const toml::table*>> out;
    auto found = lookup(name, Type::named_tables);
    if (!found) return out;
    const auto* container = found->node->as_table();
    if (container == nullptr) {
      type_error(*found);
      return out;
    }
    for (auto&& [key, value] : *container) {
      const std::string entry(key.str());
      if (const auto* entry_table = value.as_table()) {
        out.emplace_back(entry, entry_table);
      } else {
        diag_.add(line_of(value), key_path(name) + "." + entry, value_text(value),
                  fmt::format("must be a table, not {}", kind_of(value)),
                  fmt::format("write it as a [{}.{}] table", name, entry));
      }
    }
    return out;
  }

 private:
  struct Found {
    const Key* key;
    const toml::node* node;
  };

  [[nodiscard]] bool applies(const Key& key) const {
    return key.only_for.empty() || std::find(key.only_for.begin(), key.only_for.end(), variant_) != key.only_for.end();
  }

  [[nodiscard]] std::string place() const { return path_.empty() ? "at the top level" : "in '" + path_ + "'"; }

  static std::vector<std::string> quote_all(const std::vector<std::string>& words) {
    std::vector<std::string> out;
    for (const auto& word : words) out.push_back(quote_text(word));
    return out;
  }

  std::optional<Found> lookup(std::string_view name, Type type) {
    const Key* key = spec_.find(name);
    assert(key != nullptr && key->type == type && "the loader reads only keys of the schema, with their type");
    (void)type;
    if (!applies(*key)) return std::nullopt;
    if (const toml::node* node = table_.get(name)) return Found{key, node};
    if (key->required) {
      const std::string where = path_.empty() ? "the top of the file" : "'" + path_ + "'";
      diag_.add(line(), key_path(name), std::nullopt, fmt::format("missing; it is required{}", unit_suffix(*key)),
                fmt::format("add {} = {} to {}", key->name, key->example, where));
      return std::nullopt;
    }
    if (!key->default_value.empty()) return Found{key, &default_node(*key)};
    return std::nullopt;
  }

  static std::optional<double> as_number(const toml::node& node) {
    if (const auto* f = node.as_floating_point()) return f->get();
    if (const auto* i = node.as_integer()) return static_cast<double>(i->get());
    return std::nullopt;
  }

  static std::optional<std::vector<double>> numbers(const toml::node& node, std::size_t size) {
    const auto* array = node.as_array();
    if (array == nullptr || array->size() != size) return std::nullopt;
    std::vector<double> values;
    for (const auto& element : *array) {
      const auto value = as_number(element);
      if (!value) return std::nullopt;
      values.push_back(*value);
    }
    return values;
  }

  void report(const Found& found, std::string_view problem, std::string_view fix) {
    diag_.add(line_of(*found.node), key_path(found.key->name), value_text(*found.node), problem, fix);
  }

  std::nullopt_t type_error(const Found& found) {
    const Key& key = *found.key;
    const std::string example = key.example.empty() ? key.default_value : key.example;
    std::string fix;
    if (key.type == Type::table_list && path_.empty()) {
      fix = fmt::format("start each entry with a [[{}]] header", key.name);
    } else if (key.type == Type::table && path_.empty()) {
      fix = fmt::format("write it as a [{}] table", key.name);
    } else if (key.type == Type::named_tables) {
      fix = fmt::format("write one [{}.NAME] table per entry", key.name);
    } else if (example.empty()) {
      fix = fmt::format("write it as {}", expected_kind(key.type));
    } else {
      fix = fmt::format("write it as {}, e.g. {} = {}", expected_kind(key.type), key.name, example);
    }
    std::string actual(kind_of(*found.node));
    if (const auto* array = found.node->as_array()) actual = fmt::format("an array of {} elements", array->size());
    report(found, fmt::format("must be {}{}, not {}", expected_kind(key.type), unit_suffix(key), actual), fix);
    return std::nullopt;
  }

  bool all_finite(const Found& found, const std::vector<double>& values) {
    if (std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); })) return true;
    report(found, "every element must be a finite number", "replace nan and inf by finite numbers");
    return false;
  }

  std::optional<double> checked_number(const Found& found, double value) {
    const Key& key = *found.key;
    if (!std::isfinite(value)) {
      report(found, "must be a finite number", fmt::format("give a finite {}", noun(key.name)));
      return std::nullopt;
    }
    if (key.range.contains(value)) return value;
    std::string fix;
    const auto& range = key.range;
    if (range.min && *range.min == 0 && !range.max) {
      fix = fmt::format("give a {} {}", range.min_exclusive ? "positive" : "non-negative", noun(key.name));
    } else if (range.min && range.max) {
      fix = fmt::format("give a {} in {}", noun(key.name), range.text());
    } else {
      fix = fmt::format("give a {} {}", noun(key.name), range.text());
    }
    report(found, fmt::format("must be {}{}{}", range.min && range.max ? "in " : "", range.text(), unit_suffix(key)),
           fix);
    return std::nullopt;
  }

  bool check_choice(const Found& found, const std::string& value, const toml::node& value_node) {
    const Key& key = *found.key;
    if (std::find(key.choices.begin(), key.choices.end(), value) != key.choices.end()) return true;
    const auto suggestion = closest_match(value, key.choices);
    const std::string allowed = join(quote_all(key.choices));
    const std::string problem = key.type == Type::string_list
                                    ? fmt::format("{} is not one of {}", quote_text(value), allowed)
                                    : fmt::format("must be one of {}", allowed);
    if (suggestion) {
      diag_.add(line_of(value_node), key_path(key.name), value_text(*found.node),
                fmt::format("{}. Did you mean {}?", problem, quote_text(*suggestion)),
                fmt::format("write {} instead of {}", quote_text(*suggestion), quote_text(value)));
    } else {
      diag_.add(line_of(value_node), key_path(key.name), value_text(*found.node), problem,
                "use one of the allowed values");
    }
    return false;
  }

  Diagnostics& diag_;
  const Table& spec_;
  const toml::table& table_;
  std::string path_;
  std::string variant_;
};

// --------------------------------------------------------------- builder ----

const Table& spec(std::string_view anchor) {
  for (const Table* table : schema::tables()) {
    if (table->anchor == anchor) return *table;
  }
  assert(false && "unknown schema table");
  return schema::root();
}

class Builder {
 public:
  Builder(const fs::path& file, const toml::table& document)
      : diag_(file.string()), document_(document), scene_dir_(fs::absolute(file).parent_path()) {
    scene_.file = fs::weakly_canonical(fs::absolute(file));
  }

  Scene build() {
    Reader root(diag_, schema::root(), document_, "");
    if (auto version = root.integer("format_version"); version && *version != 1) {
      diag_.add(root.line("format_version"), "format_version", std::to_string(*version),
                "this build reads format_version 1 only", "write format_version = 1 and use the keys of format 1");
    }
    if (const toml::table* run = root.table("run")) read_run(*run);
    read_materials(root);

    const toml::array* particles = root.table_list("particles");
    const toml::array* structures = root.table_list("structures");
    const toml::array* fluids = root.table_list("fluids");
    has_particles_ = particles != nullptr && !particles->empty();
    has_structures_ = structures != nullptr && !structures->empty();
    has_fluids_ = fluids != nullptr && !fluids->empty();
    const bool lists_readable = (particles != nullptr || !root.has("particles")) &&
                                (structures != nullptr || !root.has("structures")) &&
                                (fluids != nullptr || !root.has("fluids"));
    if (!has_particles_ && !has_structures_ && !has_fluids_ && lists_readable) {
      diag_.add_plain(1, "the scene has no bodies, so there is nothing to simulate",
                      "add at least one [[fluids]], [[particles]] or [[structures]] table");
    }
    read_sph(root);
    if (fluids != nullptr) {
      for (std::size_t k = 0; k < fluids->size(); ++k) read_fluid(*fluids->get(k)->as_table(), k);
    }
    check_fluid_materials();
    if (particles != nullptr) {
      for (std::size_t k = 0; k < particles->size(); ++k) read_particle_set(*particles->get(k)->as_table(), k);
    }
    if (structures != nullptr) {
      for (std::size_t k = 0; k < structures->size(); ++k) read_structure(*structures->get(k)->as_table(), k);
    }
    read_solvers(root);
    read_contact(root);
    read_interactions(root);
    check_sph_dem();
    read_recording(root);
    read_gauges(root);
    read_sensors(root);
    check_overlaps();
    if (diag_.count() == 0) check_costs();
    if (diag_.count() == 0) check_fills();

    diag_.throw_if_any();
    std::sort(scene_.materials.begin(), scene_.materials.end(),
              [](const Material& a, const Material& b) { return a.name < b.name; });
    return std::move(scene_);
  }

 private:
  struct BodyName {
    bool is_particle_set;
    std::string path;
    int line;
    bool is_fluid = false;
  };
  // The fluid keys of a material, for the checks that need the fluids that use it.
  struct FluidMaterialKeys {
    int line = 0;
    bool has_eos_c1 = false;
    // Lines of the Herschel-Bulkley keys (0: absent) and of viscosity.
    int consistency_index_line = 0, flow_index_line = 0, viscosity_line = 0;
  };
  // A sphere of a list, with where it was written, for the overlap check.
  struct ListedSphere {
    Vec3 center;
    double radius;
    std::string path;
    int line;
  };

  [[nodiscard]] Origin origin(int line, std::string key) const { return {scene_.file, line, std::move(key)}; }

  void read_run(const toml::table& table) {
    Reader r(diag_, spec("run"), table, "run");
    RunSettings& run = scene_.run;
    if (auto v = r.number("end_time")) run.end_time = *v;
    if (auto v = r.number("output_interval")) run.output_interval = *v;
    if (auto v = r.string("endpoint")) {
      const auto address = valid_endpoint(*v) && *v != "ipc" ? ipv4_problem(*v) : std::nullopt;
      if (address) {
        diag_.add(r.line("endpoint"), r.key_path("endpoint"), quote_text(*v), *address,
                  "give an address of this machine, e.g. endpoint = \"tcp://127.0.0.1:5555\" (this machine only) or "
                  "\"tcp://0.0.0.0:5555\" (every interface)");
      } else if (valid_endpoint(*v)) {
        run.endpoint = *v;
      } else {
        diag_.add(r.line("endpoint"), r.key_path("endpoint"), quote_text(*v), "must be \"ipc\" or \"tcp://HOST:PORT\"",
                  "write endpoint = \"ipc\" to run on one machine, or e.g. endpoint = \"tcp://127.0.0.1:5555\"");
      }
    }
    if (auto v = r.vec3("gravity")) run.gravity = *v;
    if (auto v = r.number("hang_timeout")) run.hang_timeout = *v;
    run.max_dt = r.number("max_dt");
    run.checkpoint_interval = r.number("checkpoint_interval");
    if (auto v = r.integer("checkpoints_kept")) run.checkpoints_kept = static_cast<std::size_t>(*v);
    if (auto v = r.string("restart")) {
      if (*v == "auto" || *v == "off") {
        run.restart = *v == "auto";
      } else {
        diag_.add(r.line("restart"), r.key_path("restart"), quote_text(*v), "must be \"auto\" or \"off\"",
                  "write restart = \"auto\" to restart a solver that dies, or restart = \"off\" to stop the run");
      }
    }
    if (auto v = r.integer("max_restarts")) run.max_restarts = static_cast<std::size_t>(*v);
  }

  void read_materials(Reader& root) {
    for (const auto& [name, table] : root.named_tables("materials")) {
      const std::string path = "materials." + name;
      material_names_.push_back(name);
      if (!valid_name(name)) {
        diag_.add(line_of(*table), path, std::nullopt, "the name must be made of letters, digits, '_' and '-'",
                  "rename the material");
      }
      Reader r(diag_, spec("materials-name"), *table, path);
      Material material;
      material.name = name;
      material.origin = origin(r.line(), path);
      if (auto v = r.number("density")) material.density = *v;
      if (auto v = r.number("youngs_modulus")) material.youngs_modulus = *v;
      if (auto v = r.number("poisson_ratio")) material.poisson_ratio = *v;
      read_plasticity(r, material);
      read_fluid_material(r, material);
      scene_.materials.push_back(std::move(material));
    }
  }

  // ------------------------------------------------------------- SPH ----

  void read_fluid_material(Reader& r, Material& material) {
    if (auto v = r.string("eos")) material.eos = *v == "polynomial" ? Material::Eos::polynomial : Material::Eos::tait;
    if (auto v = r.number("tait_exponent")) material.tait_exponent = *v;
    if (auto v = r.number("eos_c0")) material.eos_c0 = *v;
    if (auto v = r.number("eos_c1")) material.eos_c1 = *v;
    if (auto v = r.number("eos_c2")) material.eos_c2 = *v;
    if (auto v = r.number("eos_c3")) material.eos_c3 = *v;
    if (auto v = r.string("rheology")) {
      if (*v == "newtonian") material.rheology = Material::Rheology::newtonian;
      if (*v == "bingham") material.rheology = Material::Rheology::bingham;
      if (*v == "herschel_bulkley") material.rheology = Material::Rheology::herschel_bulkley;
      if (*v == "elastic_plastic") material.rheology = Material::Rheology::elastic_plastic;
    }
    if (auto v = r.number("viscosity")) material.viscosity = *v;
    if (auto v = r.number("yield_shear_rate")) material.yield_shear_rate = *v;
    if (auto v = r.number("consistency_index")) material.consistency_index = *v;
    if (auto v = r.number("flow_index")) material.flow_index = *v;
    if (auto v = r.number("fluid_shear_modulus")) material.fluid_shear_modulus = *v;
    material.artificial_stress = r.number("artificial_stress");
    const auto line_if = [&](const char* key) { return r.has(key) ? r.line(key) : 0; };
    fluid_material_keys_[material.name] = {r.line(), r.has("eos_c1"), line_if("consistency_index"),
                                           line_if("flow_index"), line_if("viscosity")};
  }

  void read_sph(Reader& root) {
    const toml::table* table = root.table("sph");
    if (table == nullptr) {
      if (has_fluids_) {
        diag_.add(root.line("fluids"), "sph", std::nullopt, "missing; the scene has [[fluids]]",
                  "add an [sph] table with at least particle_spacing and sound_speed, e.g. [sph] particle_spacing = "
                  "0.02, sound_speed = 30.0");
      }
      return;
    }
    if (!has_fluids_) {
      diag_.add(line_of(*table), "sph", std::nullopt, "there are no fluids, so no SPH settings",
                "remove [sph] or add [[fluids]]");
      return;
    }
    Reader r(diag_, spec("sph"), *table, "sph");
    SphSettings& sph = scene_.sph;
    if (auto v = r.number("particle_spacing")) sph.particle_spacing = *v;
    if (auto v = r.number("smoothing_ratio")) sph.smoothing_ratio = *v;
    if (auto v = r.string("kernel")) sph.kernel = SphSettings::kernel_named(*v);
    if (auto v = r.string("wall_model")) {
      sph.wall_model = *v == "penalty" ? SphSettings::WallModel::penalty : SphSettings::WallModel::boundary_particles;
    }
    if (auto v = r.string("wall_work")) sph.wall_work = SphSettings::wall_work_named(*v);
    if (auto v = r.number("sound_speed")) sph.sound_speed = *v;
    if (auto v = r.number("cfl")) sph.cfl = *v;
    if (auto v = r.number("artificial_viscosity")) sph.artificial_viscosity = *v;
    if (auto v = r.string("density_diffusion")) sph.density_diffusion = SphSettings::density_diffusion_named(*v);
    if (auto v = r.number("density_diffusion_delta")) sph.density_diffusion_delta = *v;
    if (auto v = r.string("viscous_operator")) sph.viscous_operator = SphSettings::viscous_operator_named(*v);
    const auto min = r.vec3("domain_min"), max = r.vec3("domain_max");
    if (r.has("domain_min") != r.has("domain_max")) {
      const char* given = r.has("domain_min") ? "domain_min" : "domain_max";
      diag_.add(r.line(given), r.key_path(given), value_text(*r.node(given)),
                "the domain needs both corners, domain_min and domain_max", "give both corners, or neither");
    } else if (min && max) {
      if (((*max).array() <= (*min).array()).any()) {
        diag_.add(r.line("domain_max"), r.key_path("domain_max"), value_text(*r.node("domain_max")),
                  fmt::format("the domain is empty or inverted: domain_max must exceed domain_min = {} on every axis",
                              value_text(*r.node("domain_min"))),
                  "swap the values where domain_max <= domain_min");
      } else {
        sph.domain = Aabb{*min, *max};
        domain_line_ = r.line("domain_max");
      }
    }
    read_periodic(r, "periodic_x", sph.periodic_x, periodic_line_[0]);
    read_periodic(r, "periodic_y", sph.periodic_y, periodic_line_[1]);
  }

  // [min, max) of a periodic axis: a period of at least two kernel supports plus one spacing,
  // so that no particle sees another and its image at once (docs/physics.md).
  void read_periodic(Reader& r, const char* key, std::optional<std::array<double, 2>>& out, int& line) {
    const auto span = r.pair(key);
    if (!span) return;
    const SphSettings& sph = scene_.sph;
    const double period = (*span)[1] - (*span)[0];
    const double least = 2.0 * sph.kernel_support() + sph.particle_spacing;
    if (period <= 0) {
      diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                "the periodic span is empty or inverted: max must exceed min", "give [min, max] with min < max");
    } else if (sph.particle_spacing > 0 && period < least) {
      diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                fmt::format("the period {} m is shorter than two kernel supports plus one spacing, 4h + dx = {} m "
                            "(h = smoothing_ratio * particle_spacing): a particle would see another and its image",
                            number_literal(period), fmt::format("{:.6g}", least)),
                fmt::format("widen the span to at least {:.6g} m or lower sph.particle_spacing", least));
    } else {
      out = *span;
      line = r.line(key);
    }
  }

  void read_fluid(const toml::table& table, std::size_t index) {
    const std::string path = fmt::format("fluids[{}]", index);
    Reader r(diag_, spec("fluids"), table, path);
    FluidBody body;
    body.origin = origin(r.line(), path);
    if (auto v = r.string("name")) {
      body.name = *v;
      register_body(r, body.name, false, true);
    }
    if (auto v = r.string("material")) {
      body.material = *v;
      check_material(r, body.material);
    }
    if (auto v = r.vec3("velocity")) body.velocity = *v;
    if (auto v = r.boolean("hydrostatic")) body.hydrostatic = *v;
    if (auto v = r.number("settle_time")) {
      body.settle_time = *v;
      if (*v > 0 && !body.velocity.isZero(0.0)) {
        diag_.add(r.line("settle_time"), r.key_path("settle_time"), value_text(*r.node("settle_time")),
                  fmt::format("a settling body starts at rest, but its velocity is {}: the settling phase would "
                              "damp that velocity away",
                              value_text(*r.node("velocity"))),
                  "remove settle_time, or set velocity = [0.0, 0.0, 0.0]");
      }
    }
    const auto shape = r.string("shape");
    if (!shape) {
      scene_.fluids.push_back(std::move(body));
      return;
    }
    r.select(*shape);
    const double dx = scene_.sph.particle_spacing;
    Aabb bounds;
    if (*shape == "box") {
      body.shape = FluidBody::Shape::box;
      const auto min = r.vec3("min"), max = r.vec3("max");
      if (min && max) {
        body.box = Aabb{*min, *max};
        bounds = body.box;
        if (((*max - *min).array() < dx).any()) {
          diag_.add(r.line("max"), r.key_path("max"), value_text(*r.node("max")),
                    fmt::format("the box must exceed min = {} by at least the particle spacing {} m on every axis, "
                                "or it holds no particle",
                                value_text(*r.node("min")), number_literal(dx)),
                    "enlarge the box or lower sph.particle_spacing");
        }
      }
    } else {
      body.shape = FluidBody::Shape::extruded_polygon;
      if (auto v = r.vec3("origin")) body.profile_origin = *v;
      if (auto v = r.number("width")) {
        body.width = *v;
        if (body.width < dx) {
          diag_.add(
              r.line("width"), r.key_path("width"), number_literal(body.width),
              fmt::format("narrower than the particle spacing {} m: the body holds no particle", number_literal(dx)),
              "widen the body or lower sph.particle_spacing");
        }
      }
      if (auto v = r.vec3("direction")) {
        if (std::abs(v->z()) > 1e-12 || v->norm() == 0) {
          diag_.add(r.line("direction"), r.key_path("direction"), value_text(*r.node("direction")),
                    "must be horizontal (z = 0) and not zero", "give e.g. direction = [1.0, 0.0, 0.0]");
        } else {
          body.direction = v->normalized();
        }
      }
      if (auto v = r.pairs("profile")) {
        body.profile = *v;
        check_profile(r, body.profile);
        const Vec3 across(-body.direction.y(), body.direction.x(), 0.0);  // z x direction
        for (const auto& [s, z] : body.profile) {
          const Vec3 base = body.profile_origin + s * body.direction;
          bounds.extend(Vec3(base.x(), base.y(), z) + 0.5 * body.width * across);
          bounds.extend(Vec3(base.x(), base.y(), z) - 0.5 * body.width * across);
        }
      }
    }
    if (scene_.sph.domain && !bounds.empty() &&
        !(scene_.sph.domain->contains(bounds.min) && scene_.sph.domain->contains(bounds.max))) {
      diag_.add(
          r.line(), path, std::nullopt,
          fmt::format("the body reaches outside the SPH domain (sph.domain_min/domain_max, line {})", domain_line_),
          "enlarge the domain or move the body into it");
    }
    const std::optional<std::array<double, 2>>* periodic[2] = {&scene_.sph.periodic_x, &scene_.sph.periodic_y};
    for (int axis = 0; axis < 2; ++axis) {
      const auto& span = *periodic[axis];
      if (!span || bounds.empty()) continue;
      const double tolerance = 1e-9 * std::max(1.0, (*span)[1] - (*span)[0]);
      if (bounds.min[axis] < (*span)[0] - tolerance || bounds.max[axis] > (*span)[1] + tolerance) {
        const char* name = axis == 0 ? "periodic_x" : "periodic_y";
        diag_.add(r.line(), path, std::nullopt,
                  fmt::format("the body spans {} = [{}, {}] m, outside the periodic span sph.{} = [{}, {}] (line {})",
                              axis == 0 ? "x" : "y", number_literal(bounds.min[axis]), number_literal(bounds.max[axis]),
                              name, number_literal((*span)[0]), number_literal((*span)[1]), periodic_line_[axis]),
                  fmt::format("move the body into the span or widen sph.{}", name));
      }
    }
    scene_.fluids.push_back(std::move(body));
  }

  void check_profile(Reader& r, const std::vector<std::array<double, 2>>& profile) {
    const int line = r.line("profile");
    const std::string key = r.key_path("profile");
    const std::string value = value_text(*r.node("profile"));
    const std::size_t n = profile.size();
    if (n < 3) {
      diag_.add(line, key, value, fmt::format("a polygon needs at least 3 points, not {}", n),
                "list the corners of the profile in order, e.g. [[0.0, 0.0], [10.0, 0.0], [0.0, 5.0]]");
      return;
    }
    const auto point = [&](std::size_t k) { return profile[k % n]; };
    for (std::size_t k = 0; k < n; ++k) {
      if (point(k) == point(k + 1)) {
        diag_.add(line, key, value, fmt::format("points {} and {} are the same: a zero-length edge", k, (k + 1) % n),
                  "remove the repeated point");
        return;
      }
    }
    if (const auto edges = geometry::first_crossing_edges(profile, /*touching=*/false)) {
      const auto [a, b] = *edges;
      diag_.add(line, key, value, fmt::format("edge {}-{} crosses edge {}-{}", a, (a + 1) % n, b, (b + 1) % n),
                "list the points in order around the polygon, without crossings");
    }
  }

  // Requirements of the materials that fluids use.
  void check_fluid_materials() {
    std::vector<std::string> checked;
    for (const FluidBody& body : scene_.fluids) {
      if (std::find(checked.begin(), checked.end(), body.material) != checked.end()) continue;
      checked.push_back(body.material);
      const auto material = std::find_if(scene_.materials.begin(), scene_.materials.end(),
                                         [&](const Material& m) { return m.name == body.material; });
      if (material == scene_.materials.end()) continue;
      const FluidMaterialKeys keys = fluid_material_keys_[material->name];
      const std::string path = "materials." + material->name;
      const std::string user = fmt::format(" (used by fluid '{}')", body.name);
      if (material->eos == Material::Eos::polynomial && !keys.has_eos_c1) {
        diag_.add(keys.line, path + ".eos_c1", std::nullopt, "missing; eos = \"polynomial\" needs C1" + user,
                  "add eos_c1 = 20e9 (the bulk stiffness of the polynomial EOS), or use eos = \"tait\"");
      }
      using R = Material::Rheology;
      if ((material->rheology == R::newtonian || material->rheology == R::bingham) && material->viscosity <= 0) {
        diag_.add(keys.line, path + ".viscosity", number_literal(material->viscosity),
                  "a newtonian or bingham fluid needs a positive viscosity" + user,
                  "give viscosity > 0 (Pa s), or use rheology = \"inviscid\"");
      }
      if ((material->rheology == R::bingham || material->rheology == R::elastic_plastic) && !material->yield_stress) {
        diag_.add(keys.line, path + ".yield_stress", std::nullopt,
                  "missing; a bingham or elastic_plastic fluid needs a positive yield stress" + user,
                  "give yield_stress > 0 (Pa)");
      }
      if (material->rheology == R::herschel_bulkley) {
        if (keys.consistency_index_line == 0) {
          diag_.add(keys.line, path + ".consistency_index", std::nullopt,
                    "missing; a herschel_bulkley fluid needs its consistency index K (tau = tau_y + K "
                    "gamma_dot^n)" +
                        user,
                    "give consistency_index > 0 (Pa s^n), e.g. consistency_index = 5.0");
        }
        if (keys.viscosity_line != 0) {
          diag_.add(keys.viscosity_line, path + ".viscosity", number_literal(material->viscosity),
                    "herschel_bulkley does not read viscosity: its viscous part is consistency_index K and "
                    "flow_index n (K gamma_dot^n)" +
                        user,
                    "remove viscosity (flow_index = 1 with consistency_index = the plastic viscosity is bingham's "
                    "law)");
        }
      } else {
        const std::tuple<const char*, int, double> given[] = {
            {"consistency_index", keys.consistency_index_line, material->consistency_index},
            {"flow_index", keys.flow_index_line, material->flow_index}};
        for (const auto& [key, line, value] : given) {
          if (line == 0) continue;
          diag_.add(line, path + "." + key, number_literal(value),
                    std::string(key) + " is read only by rheology = \"herschel_bulkley\"" + user,
                    fmt::format("remove {}, or use rheology = \"herschel_bulkley\"", key));
        }
      }
      if (material->rheology != R::elastic_plastic && material->artificial_stress.value_or(0.0) > 0) {
        diag_.add(keys.line, path + ".artificial_stress", number_literal(*material->artificial_stress),
                  "artificial stress acts on the stress tensor of an elastic_plastic fluid only" + user,
                  "remove artificial_stress, or use rheology = \"elastic_plastic\"");
      }
    }
  }

  // Checks `name` (validity, uniqueness among bodies) and records it.
  // Plastic kinematic keys of a material (deformable structures).
  void read_plasticity(Reader& r, Material& material) {
    material.yield_stress = r.number("yield_stress");
    if (auto v = r.number("tangent_modulus")) material.tangent_modulus = *v;
    if (auto v = r.number("hardening")) material.hardening = *v;
    material.cowper_symonds_c = r.number("cowper_symonds_c");
    if (auto v = r.number("cowper_symonds_p")) material.cowper_symonds_p = *v;
    material.failure_strain = r.number("failure_strain");
    if (!material.yield_stress) {
      for (const char* key : {"tangent_modulus", "hardening", "cowper_symonds_c", "cowper_symonds_p"}) {
        if (r.has(key)) {
          diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                    "a plasticity parameter without yield_stress (the material is elastic)",
                    "add yield_stress, or remove the key");
        }
      }
    }
    if (material.youngs_modulus > 0 && material.tangent_modulus >= material.youngs_modulus) {
      diag_.add(
          r.line("tangent_modulus"), r.key_path("tangent_modulus"), value_text(*r.node("tangent_modulus")),
          fmt::format("the tangent modulus must be below youngs_modulus = {}", number_literal(material.youngs_modulus)),
          "give the slope after yield, a fraction of youngs_modulus");
    }
  }

  // Deformable structures: a box meshed with hexahedra, fixed faces, initial velocity.
  void read_deformable(Reader& r, Structure& structure, const std::optional<std::string>& shape) {
    if (auto v = r.strings("fixed")) structure.fixed_faces = *v;
    if (const toml::array* list = r.table_list("constraints")) read_constraints(r, *list, structure);
    if (auto v = r.vec3("velocity")) structure.velocity = *v;
    if (auto v = r.string("element_formulation")) {
      structure.element_formulation = *v == "fully_integrated"  ? Structure::ElementFormulation::fully_integrated
                                      : *v == "enhanced_strain" ? Structure::ElementFormulation::enhanced_strain
                                                                : Structure::ElementFormulation::one_point;
      if (!structure.rigid && structure.thickness > 0 &&
          structure.element_formulation == Structure::ElementFormulation::enhanced_strain) {
        diag_.add(r.line("element_formulation"), r.key_path("element_formulation"),
                  value_text(*r.node("element_formulation")),
                  "enhanced-strain elements exist for solids (hexahedra) only; this structure has a thickness "
                  "(shells)",
                  "use element_formulation = \"fully_integrated\" (MITC4 shells) or \"one_point\", or remove the "
                  "thickness for a solid of hexahedra");
      }
    }
    const bool building_keys = shape && *shape == "box";
    if (building_keys) {
      if (auto v = r.integer("floors")) structure.floors = static_cast<std::size_t>(*v);
      if (auto v = r.number("roof_thickness")) structure.roof_thickness = *v;
      if (auto v = r.string("roof_material")) {
        structure.roof_material = *v;
        check_material(r, *v, "roof_material");
      }
      if (auto v = r.integer("slit_count")) structure.slit_count = static_cast<std::size_t>(*v);
      if (auto v = r.number("slit_width")) structure.slit_width = *v;
      if (auto v = r.number("slit_depth")) structure.slit_depth = *v;
      if (auto v = r.string("slit_axis")) structure.slit_axis = *v == "x" ? 0 : 1;
      if (!structure.rigid && structure.thickness == 0) {
        for (const char* key : {"floors", "roof_thickness", "roof_material"}) {
          if (r.has(key)) {
            diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                      "belongs to thin-walled buildings, but this box has no thickness (a solid)",
                      "give the walls a thickness, or remove the key");
          }
        }
      }
      if (!structure.rigid && structure.thickness > 0) {
        for (const char* key : kSlitKeys) {
          if (r.has(key)) {
            diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                      "belongs to slit dams (solid boxes), but this box has a thickness (a shell building)",
                      "remove the thickness for a solid dam of hexahedra, or remove the key");
          }
        }
      }
    }
    if (structure.rigid) {
      for (const char* key : {"fixed", "constraints", "velocity", "element_formulation", "floors", "roof_thickness",
                              "roof_material", "slit_count", "slit_width", "slit_depth", "slit_axis"}) {
        if (r.has(key)) {
          diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                    "belongs to deformable structures, but this one is rigid",
                    "remove it, or set rigid = false (shape = \"box\")");
        }
      }
      return;
    }
    if (shape && *shape != "box" && *shape != "mesh" && !(*shape == "plane" && structure.thickness > 0)) {
      diag_.add(r.line("rigid"), r.key_path("rigid"), "false",
                fmt::format("deformable structures are boxes (hexahedra, or shells with a thickness), planes "
                            "with a thickness (shells) or Gmsh meshes, not shape = {}{}",
                            quote_text(*shape), *shape == "plane" ? " without a thickness" : ""),
                "use shape = \"box\" with element_size, give the plane a thickness, or set rigid = true");
    }
  }

  static constexpr std::array<const char*, 4> kSlitKeys{"slit_count", "slit_width", "slit_depth", "slit_axis"};

  // Where a constraint's keys were written, for the checks that need the structure's shape (read later).
  struct ConstraintKeys {
    int line = 0, box_line = 0, tag_line = 0;
    std::string path, box_value;
  };

  // The constraints of a deformable structure: each a box or a tag, and its DOFs. What needs the shape
  // (the mesh file, the structure's extent) is checked by check_constraints once the shape is read.
  void read_constraints(Reader& structure_reader, const toml::array& list, Structure& structure) {
    constraint_keys_.clear();
    for (std::size_t k = 0; k < list.size(); ++k) {
      const std::string path = structure_reader.key_path(fmt::format("constraints[{}]", k));
      Reader r(diag_, spec("structures-constraints"), *list.get(k)->as_table(), path);
      Constraint constraint;
      constraint.origin = origin(r.line(), path);
      ConstraintKeys keys{r.line(), r.line("box"), r.line("tag"), path, {}};
      const toml::table* box = r.table("box");
      const auto tag = r.string("tag");
      if (box != nullptr) {
        keys.box_value = value_text(*r.node("box"));
        Reader b(diag_, spec("structures-constraints-box"), *box, r.key_path("box"));
        const auto min = b.vec3("min"), max = b.vec3("max");
        if (min && max) {
          constraint.box = Aabb{*min, *max};
          if (((*max).array() < (*min).array()).any()) {
            diag_.add(b.line("max"), b.key_path("max"), value_text(*b.node("max")),
                      fmt::format("the box is inverted: max must be at least min = {} on every axis",
                                  value_text(*b.node("min"))),
                      "swap the values of min and max where max < min");
          }
        }
      }
      if (tag) {
        constraint.selection = Constraint::Selection::tag;
        constraint.tag = *tag;
      }
      const bool both = r.has("box") && r.has("tag"), neither = !r.has("box") && !r.has("tag");
      if (both || neither) {
        diag_.add(r.line(), path, value_text(*list.get(k)),
                  both ? "gives both box and tag: a constraint selects its nodes one way"
                       : "selects no nodes: it needs a box or a tag",
                  both ? "keep one of box and tag (two constraints for two node sets)"
                       : "add box = { min = [...], max = [...] }, or tag = \"GROUP\" for a mesh's physical group");
      }
      if (auto dofs = r.strings("dofs")) {
        if (dofs->empty()) {
          diag_.add(r.line("dofs"), r.key_path("dofs"), "[]", "holds no degree of freedom",
                    "name at least one of \"x\", \"y\", \"z\", \"rx\", \"ry\", \"rz\" or \"all\"");
        }
        for (const std::string& dof : *dofs) {
          if (dof == "all") {
            constraint.all = true;
            constraint.dofs |= Constraint::translations;
            continue;
          }
          static constexpr std::array<std::pair<const char*, unsigned>, 6> kBits{{{"x", Constraint::x},
                                                                                  {"y", Constraint::y},
                                                                                  {"z", Constraint::z},
                                                                                  {"rx", Constraint::rx},
                                                                                  {"ry", Constraint::ry},
                                                                                  {"rz", Constraint::rz}}};
          for (const auto& [name, bit] : kBits) {
            if (dof == name) constraint.dofs |= bit;
          }
        }
        if ((constraint.dofs & Constraint::rotations) != 0 && structure.thickness == 0) {
          diag_.add(r.line("dofs"), r.key_path("dofs"), value_text(*r.node("dofs")),
                    "rotations belong to shells, and this structure has no thickness (a solid: its nodes have the "
                    "three translations only)",
                    "hold \"x\", \"y\" or \"z\" (or \"all\"), or give the structure a thickness for shells");
        }
      }
      structure.constraints.push_back(std::move(constraint));
      constraint_keys_.push_back(std::move(keys));
    }
  }

  // The constraints' selections against the structure's shape: a tag names a non-empty physical group of
  // the structure's .msh file; a box holds one of its nodes (meshes) or meets its extent (generated shapes,
  // checked node by node by the fem_solver).
  void check_constraints(const Structure& structure, const std::optional<std::string>& shape) {
    if (structure.rigid || structure.constraints.empty() || !shape) return;
    const bool mesh = structure.shape.type == Shape::Type::mesh;
    std::optional<io::GmshGroups> groups;
    std::optional<std::string> unreadable;
    // A missing file or one that is not a .msh file is reported with the key `file`.
    bool reported = false;
    const auto read_groups = [&]() {
      if (groups || unreadable) return;
      std::error_code ec;
      std::string extension = structure.shape.file.extension().string();
      std::transform(extension.begin(), extension.end(), extension.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (structure.shape.file.empty() || !fs::is_regular_file(structure.shape.file, ec) || extension != ".msh") {
        unreadable = "the mesh file is missing";
        reported = true;
        return;
      }
      try {
        groups = io::read_gmsh_groups(structure.shape.file);
      } catch (const Error& error) {
        unreadable = error.what();
      }
    };
    const auto final_position = [&](const Vec3& p) {
      return Vec3(structure.shape.scale * p + structure.shape.translate);
    };
    for (std::size_t k = 0; k < structure.constraints.size(); ++k) {
      const Constraint& c = structure.constraints[k];
      const ConstraintKeys& keys = constraint_keys_[k];
      if (c.selection == Constraint::Selection::tag) {
        const std::string key = keys.path + ".tag";
        if (!mesh) {
          diag_.add(keys.tag_line, key, quote_text(c.tag),
                    fmt::format("a tag names a physical group of a Gmsh mesh, and this structure's shape is {}",
                                quote_text(*shape)),
                    "select the nodes with box = { min = [...], max = [...] }");
          continue;
        }
        read_groups();
        if (unreadable) {
          if (reported) continue;
          diag_.add(
              keys.tag_line, key, quote_text(c.tag),
              fmt::format("cannot read the physical groups of {}: {}", structure.shape.file.string(), *unreadable),
              "repair the mesh file");
          continue;
        }
        const io::GmshGroup* group = groups->find(c.tag);
        if (group == nullptr) {
          const auto names = groups->names();
          const auto suggestion = closest_match(c.tag, names);
          diag_.add(keys.tag_line, key, quote_text(c.tag),
                    fmt::format("{} has no physical group of that name{}", structure.shape.file.filename().string(),
                                suggestion ? fmt::format(". Did you mean '{}'?", *suggestion) : std::string()),
                    names.empty() ? std::string("name the node set in Gmsh (Physical Surface, Physical Curve, ...) "
                                                "and export again, or select the nodes with a box")
                                  : fmt::format("use one of the file's groups: {}", join(names)));
          continue;
        }
        if (group->node.empty()) {
          diag_.add(keys.tag_line, key, quote_text(c.tag),
                    fmt::format("the physical group {} of {} holds no elements, so no nodes", quote_text(c.tag),
                                structure.shape.file.filename().string()),
                    "assign elements to the group in Gmsh and export again (Save all elements off), or select the "
                    "nodes with a box");
        }
        continue;
      }
      if (!(c.box.max.array() >= c.box.min.array()).all()) continue;  // inverted: reported
      const std::string key = keys.path + ".box";
      if (mesh) {
        read_groups();
        if (!groups) continue;  // the file's problem is reported with the file (or by the fem_solver)
        Aabb extent;
        bool hit = false;
        for (const Vec3& p : groups->node) {
          const Vec3 q = final_position(p);
          extent.extend(q);
          hit = hit || c.box.contains(q);
        }
        if (!hit) {
          diag_.add(keys.box_line, key, keys.box_value,
                    fmt::format("the box holds no node of the mesh, whose nodes span {} to {} (after scale and "
                                "translate)",
                                vec_text(extent.min), vec_text(extent.max)),
                    "move or grow the box over the nodes to hold");
        }
        continue;
      }
      const Aabb extent = structure_extent(structure);
      if (!extent.overlaps(c.box)) {
        diag_.add(keys.box_line, key, keys.box_value,
                  fmt::format("the box misses the structure, which spans {} to {}", vec_text(extent.min),
                              vec_text(extent.max)),
                  "move or grow the box over the nodes to hold");
      }
    }
  }

  static std::string vec_text(const Vec3& v) {
    return fmt::format("[{}, {}, {}]", number_literal(v.x()), number_literal(v.y()), number_literal(v.z()));
  }

  // The box around a generated deformable structure (a box, or a plane panel).
  static Aabb structure_extent(const Structure& structure) {
    const Shape& shape = structure.shape;
    if (shape.type != Shape::Type::plane) return shape.box;
    const Vec3 side = shape.normal.cross(shape.direction).normalized();
    Aabb extent;
    for (double a : {-0.5, 0.5}) {
      for (double b : {-0.5, 0.5})
        extent.extend(shape.origin + a * shape.length * shape.direction + b * shape.width * side);
    }
    return extent;
  }

  // A slit dam's slits must fit the (deformable, solid) box read before.
  void check_slits(Reader& r, const Structure& structure) {
    if (structure.rigid || structure.thickness > 0) return;
    const Aabb& box = structure.shape.box;
    if (structure.slit_count == 0) {
      for (const char* key : {"slit_width", "slit_depth", "slit_axis"}) {
        if (r.has(key)) {
          diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                    "a slit dimension without slits (slit_count is 0)",
                    "give slit_count = the number of slits, or remove the key");
        }
      }
      return;
    }
    const int across = structure.slit_axis == 0 ? 1 : 0;  // the axis along which the slits are spaced
    const double length = box.max(across) - box.min(across), height = box.max.z() - box.min.z();
    const char* across_name = across == 0 ? "x" : "y";
    const auto count_text = std::to_string(structure.slit_count);
    if (!(structure.slit_width > 0)) {
      diag_.add(r.has("slit_width") ? r.line("slit_width") : r.line("slit_count"), r.key_path("slit_width"),
                r.has("slit_width") ? std::optional<std::string>(value_text(*r.node("slit_width"))) : std::nullopt,
                fmt::format("slit_count = {} needs the width of the slits", count_text), "give slit_width > 0 (m)");
    } else if (static_cast<double>(structure.slit_count) * structure.slit_width >= length) {
      diag_.add(r.line("slit_width"), r.key_path("slit_width"), value_text(*r.node("slit_width")),
                fmt::format("{} slits of this width take {} m of the box's {} m along {}, leaving no piers", count_text,
                            number_literal(static_cast<double>(structure.slit_count) * structure.slit_width),
                            number_literal(length), across_name),
                fmt::format("give slit_width below {} m, or fewer slits",
                            number_literal(length / static_cast<double>(structure.slit_count))));
    }
    if (!(structure.slit_depth > 0)) {
      diag_.add(r.has("slit_depth") ? r.line("slit_depth") : r.line("slit_count"), r.key_path("slit_depth"),
                r.has("slit_depth") ? std::optional<std::string>(value_text(*r.node("slit_depth"))) : std::nullopt,
                fmt::format("slit_count = {} needs the depth of the slits below the top of the box", count_text),
                fmt::format("give slit_depth in (0, {}] m", number_literal(height)));
    } else if (structure.slit_depth > height) {
      diag_.add(r.line("slit_depth"), r.key_path("slit_depth"), value_text(*r.node("slit_depth")),
                fmt::format("deeper than the box is high ({} m)", number_literal(height)),
                fmt::format("give slit_depth <= {} m (equal: the slits reach the ground)", number_literal(height)));
    }
  }

  void register_body(Reader& r, const std::string& name, bool is_particle_set, bool is_fluid = false) {
    const int line = r.line("name");
    if (!valid_name(name)) {
      diag_.add(line, r.key_path("name"), quote_text(name), "a name must be made of letters, digits, '_' and '-'",
                "rename it, e.g. \"boulders_1\"");
      return;
    }
    auto [it, inserted] = bodies_.try_emplace(name, BodyName{is_particle_set, r.path(), line, is_fluid});
    if (!inserted) {
      diag_.add(line, r.key_path("name"), quote_text(name),
                fmt::format("the name is already used by {} (line {})", it->second.path, it->second.line),
                "give each fluid, particle set and structure its own name");
    }
  }

  void check_material(Reader& r, const std::string& material, const char* key = "material") {
    if (std::find(material_names_.begin(), material_names_.end(), material) != material_names_.end()) return;
    const auto suggestion = closest_match(material, material_names_);
    std::string problem = "no material of that name";
    if (suggestion) problem += fmt::format(". Did you mean '{}'?", *suggestion);
    const std::string fix = material_names_.empty() ? fmt::format("add a [materials.{}] table", material)
                                                    : fmt::format("define [materials.{}] or use one of: {}", material,
                                                                  join(material_names_));
    diag_.add(r.line(key), r.key_path(key), quote_text(material), problem, fix);
  }

  void read_particle_set(const toml::table& table, std::size_t index) {
    const std::string path = fmt::format("particles[{}]", index);
    Reader r(diag_, spec("particles"), table, path);
    ParticleSet set;
    set.origin = origin(r.line(), path);
    if (auto v = r.string("name")) {
      set.name = *v;
      register_body(r, set.name, true);
    }
    if (auto v = r.string("material")) {
      set.material = *v;
      check_material(r, set.material);
    }
    if (auto v = r.boolean("fixed")) set.fixed = *v;
    const bool has_spheres = r.has("spheres"), has_fill = r.has("fill");
    if (has_spheres && has_fill) {
      diag_.add(r.line("fill"), r.key_path("fill"), value_text(*r.node("fill")),
                "a particle set gives either 'spheres' or 'fill', not both",
                "remove 'fill' or 'spheres', or split them into two [[particles]] sets");
    } else if (!has_spheres && !has_fill) {
      diag_.add(r.line(), path, std::nullopt, "has neither 'spheres' nor 'fill'",
                "add spheres = [ { center = [x, y, z], radius = R } ] or fill = { min = [...], max = [...], count = N, "
                "diameter = [dmin, dmax] }");
    }
    if (const toml::array* spheres = r.table_list("spheres"); spheres != nullptr && !has_fill) {
      set.kind = ParticleSet::Kind::list;
      if (spheres->empty()) {
        diag_.add(r.line("spheres"), r.key_path("spheres"), "[]", "the list has no spheres",
                  "add at least one sphere, or remove the particle set");
      }
      for (std::size_t k = 0; k < spheres->size(); ++k) {
        const toml::table& entry = *spheres->get(k)->as_table();
        const std::string sphere_path = fmt::format("{}.spheres[{}]", path, k);
        const std::size_t errors_before = diag_.count();
        Reader s(diag_, spec("particles-spheres"), entry, sphere_path);
        Sphere sphere;
        if (auto v = s.vec3("center")) sphere.center = *v;
        if (auto v = s.number("radius")) sphere.radius = *v;
        if (auto v = s.vec3("velocity")) sphere.velocity = *v;
        if (auto v = s.vec3("angular_velocity")) sphere.angular_velocity = *v;
        if (diag_.count() == errors_before) {
          listed_.push_back({sphere.center, sphere.radius, sphere_path, line_of(entry)});
        }
        set.spheres.push_back(sphere);
      }
    }
    if (const toml::table* fill = r.table("fill"); fill != nullptr && !has_spheres) {
      set.kind = ParticleSet::Kind::fill;
      read_fill(*fill, path + ".fill", set);
    }
    scene_.particle_sets.push_back(std::move(set));
  }

  void read_fill(const toml::table& table, const std::string& path, ParticleSet& set) {
    Reader f(diag_, spec("particles-fill"), table, path);
    const std::size_t errors_before = diag_.count();
    if (const auto distribution = f.string("distribution")) {
      f.select(*distribution);
      set.distribution = *distribution == "normal"  ? SizeDistribution::normal
                         : *distribution == "sieve" ? SizeDistribution::sieve
                                                    : SizeDistribution::uniform;
    }
    const auto count = f.integer("count");
    if (count) set.count = static_cast<std::size_t>(*count);
    if (auto v = f.integer("seed")) set.seed = static_cast<std::uint64_t>(*v);
    if (auto v = f.vec3("velocity")) set.velocity = *v;
    if (auto v = f.number("settle_time")) set.settle_time = *v;
    read_fill_region(f, set);
    read_fill_sizes(f, set);
    if (diag_.count() != errors_before) return;

    const Vec3 extent = set.region.max - set.region.min;
    const char* region_key = set.polygon_xz.empty() ? "max" : "polygon_xz";
    if (extent.minCoeff() < set.diameter_max) {
      diag_.add(f.line(region_key), f.key_path(region_key), value_text(*f.node(region_key)),
                fmt::format("the region spans {} x {} x {} m, too small for a sphere of the largest diameter {} m",
                            number_literal(extent.x()), number_literal(extent.y()), number_literal(extent.z()),
                            number_literal(set.diameter_max)),
                "enlarge the region so that it spans at least the largest diameter on every axis");
      return;
    }
    const double solid_volume = static_cast<double>(set.count) * set.mean_sphere_volume();
    const double fraction = solid_volume / set.region_volume();
    if (fraction > kMaxFillSolidFraction) {
      diag_.add(f.line("count"), f.key_path("count"), std::to_string(set.count),
                fmt::format("{} spheres fill {:.0f} % of the region's volume on average; random filling needs at "
                            "most {:.0f} %",
                            set.count, 100.0 * fraction, 100.0 * kMaxFillSolidFraction),
                fmt::format("enlarge the region to at least {:.1f} m^3, lower the count or the diameters",
                            solid_volume / kMaxFillSolidFraction));
    }
  }

  void read_fill_region(Reader& f, ParticleSet& set) {
    const bool has_box = f.has("min") || f.has("max");
    const bool has_polygon = f.has("polygon_xz") || f.has("y_range");
    if (has_box && has_polygon) {
      const char* key = f.has("polygon_xz") ? "polygon_xz" : "y_range";
      diag_.add(f.line(key), f.key_path(key), value_text(*f.node(key)),
                "a fill region is a box (min, max) or a polygon (polygon_xz, y_range), not both",
                "remove min and max, or polygon_xz and y_range");
      return;
    }
    if (!has_box && !has_polygon) {
      diag_.add(f.line(), f.path(), std::nullopt, "the fill has no region",
                "add min = [x, y, z] and max = [x, y, z] (a box), or polygon_xz = [[x, z], ...] and y_range = "
                "[y_min, y_max] (a polygon extruded along y)");
      return;
    }
    if (has_box) {
      const auto min = f.vec3("min"), max = f.vec3("max");
      for (const char* key : {"min", "max"}) {
        if (!f.has(key)) {
          diag_.add(f.line(), f.key_path(key), std::nullopt, "missing; a box region needs both min and max (m)",
                    fmt::format("add {} = [x, y, z] to '{}'", key, f.path()));
        }
      }
      if (!min || !max) return;
      set.region = Aabb{*min, *max};
      if (((*max).array() <= (*min).array()).any()) {
        diag_.add(f.line("max"), f.key_path("max"), value_text(*f.node("max")),
                  fmt::format("the region is empty or inverted: max must exceed min = {} on every axis",
                              value_text(*f.node("min"))),
                  "swap the values of min and max where max <= min");
      }
      return;
    }
    const auto polygon = f.pairs("polygon_xz");
    const auto y_range = f.pair("y_range");
    for (const char* key : {"polygon_xz", "y_range"}) {
      if (!f.has(key)) {
        diag_.add(
            f.line(), f.key_path(key), std::nullopt, "missing; a polygon region needs both polygon_xz and y_range",
            fmt::format("add {} to '{}'",
                        std::string_view(key) == "y_range" ? "y_range = [y_min, y_max]" : "polygon_xz = [[x, z], ...]",
                        f.path()));
      }
    }
    if (!polygon || !y_range) return;
    const int line = f.line("polygon_xz");
    const std::string value = value_text(*f.node("polygon_xz"));
    if ((*y_range)[0] >= (*y_range)[1]) {
      diag_.add(f.line("y_range"), f.key_path("y_range"), value_text(*f.node("y_range")),
                "the extrusion is empty or inverted: it is [min, max] with min < max",
                "give y_range = [y_min, y_max] with y_min < y_max");
      return;
    }
    const std::size_t n = polygon->size();
    if (n < 3) {
      diag_.add(line, f.key_path("polygon_xz"), value, fmt::format("a polygon has at least 3 vertices, not {}", n),
                "list the vertices [x, z] of the region's outline in order");
      return;
    }
    if (const auto edges = geometry::first_crossing_edges(*polygon, /*touching=*/true)) {
      const auto [i, j] = *edges;
      diag_.add(
          line, f.key_path("polygon_xz"), value,
          fmt::format("the polygon is not simple: edge {} (vertices {} and {}) meets edge {} (vertices {} and {})", i,
                      i, (i + 1) % n, j, j, (j + 1) % n),
          "list the vertices in order around the outline, without crossing edges");
      return;
    }
    set.polygon_xz = *polygon;
    Vec3 low((*polygon)[0][0], (*y_range)[0], (*polygon)[0][1]);
    Vec3 high((*polygon)[0][0], (*y_range)[1], (*polygon)[0][1]);
    for (const auto& vertex : *polygon) {
      low.x() = std::min(low.x(), vertex[0]);
      high.x() = std::max(high.x(), vertex[0]);
      low.z() = std::min(low.z(), vertex[1]);
      high.z() = std::max(high.z(), vertex[1]);
    }
    set.region = Aabb{low, high};
    if (!(set.region_volume() > 0)) {
      diag_.add(line, f.key_path("polygon_xz"), value, "the polygon has zero area",
                "give vertices that enclose an area (not all on one line)");
    }
  }

  void read_fill_sizes(Reader& f, ParticleSet& set) {
    if (set.distribution == SizeDistribution::sieve) {
      if (auto basis = f.string("sieve_basis")) set.sieve_by_mass = *basis == "mass";
      const auto rows = f.pairs("sieve");
      if (!rows) return;
      const int line = f.line("sieve");
      const std::string value = value_text(*f.node("sieve"));
      const auto refuse = [&](const std::string& problem) {
        diag_.add(line, f.key_path("sieve"), value, problem,
                  "give rows [diameter (m), fraction finer] with diameters > 0 strictly increasing and fractions "
                  "rising from 0.0 (first row) to 1.0 (last row), e.g. sieve = [[1.0, 0.0], [1.5, 0.4], [2.0, 1.0]]");
      };
      if (rows->size() < 2) return refuse(fmt::format("a grading curve has at least 2 rows, not {}", rows->size()));
      for (std::size_t k = 0; k < rows->size(); ++k) {
        const auto& row = (*rows)[k];
        if (!(row[0] > 0)) return refuse(fmt::format("row {}: the diameter {} m is not positive", k, row[0]));
        if (row[1] < 0 || row[1] > 1) return refuse(fmt::format("row {}: the fraction {} is not in [0, 1]", k, row[1]));
        if (k > 0 && !(row[0] > (*rows)[k - 1][0])) {
          return refuse(fmt::format("row {}: the diameter {} m does not exceed the previous row's", k, row[0]));
        }
        if (k > 0 && row[1] < (*rows)[k - 1][1]) {
          return refuse(fmt::format("row {}: the fraction {} is below the previous row's", k, row[1]));
        }
      }
      if (rows->front()[1] != 0.0 || rows->back()[1] != 1.0) {
        return refuse(fmt::format("the fractions run from {} to {}; a grading curve runs from 0 to 1", rows->front()[1],
                                  rows->back()[1]));
      }
      set.sieve = *rows;
      set.diameter_min = rows->front()[0];
      set.diameter_max = rows->back()[0];
      return;
    }
    const auto diameter = f.pair("diameter");
    if (!diameter) return;
    set.diameter_min = (*diameter)[0];
    set.diameter_max = (*diameter)[1];
    if (set.diameter_min > set.diameter_max) {
      diag_.add(
          f.line("diameter"), f.key_path("diameter"), value_text(*f.node("diameter")),
          "the diameter range is inverted: it is [min, max] with min <= max",
          fmt::format("write diameter = [{}, {}]", number_literal(set.diameter_max), number_literal(set.diameter_min)));
      return;
    }
    if (set.distribution != SizeDistribution::normal) return;
    const auto mean = f.number("mean_diameter");
    const auto deviation = f.number("std_diameter");
    if (!mean || !deviation) return;
    set.mean_diameter = *mean;
    set.std_diameter = *deviation;
    if (*mean < set.diameter_min || *mean > set.diameter_max) {
      diag_.add(f.line("mean_diameter"), f.key_path("mean_diameter"), number_literal(*mean),
                fmt::format("the mean lies outside the clip range diameter = [{}, {}]",
                            number_literal(set.diameter_min), number_literal(set.diameter_max)),
                "give a mean inside the clip range, or widen diameter");
    }
  }

  void read_structure(const toml::table& table, std::size_t index) {
    const std::string path = fmt::format("structures[{}]", index);
    Reader r(diag_, spec("structures"), table, path);
    Structure structure;
    structure.origin = origin(r.line(), path);
    if (auto v = r.string("name")) {
      structure.name = *v;
      register_body(r, structure.name, false);
    }
    if (auto v = r.string("material")) {
      structure.material = *v;
      check_material(r, structure.material);
    }
    if (auto v = r.boolean("rigid")) structure.rigid = *v;
    if (auto v = r.number("thickness")) structure.thickness = *v;
    const auto shape = r.string("shape");
    if (!shape) {
      scene_.structures.push_back(std::move(structure));
      return;
    }
    r.select(*shape);
    read_deformable(r, structure, shape);
    Shape& s = structure.shape;
    if (*shape == "plane") {
      s.type = Shape::Type::plane;
      if (auto v = r.vec3("origin")) s.origin = *v;
      if (auto v = r.number("length")) s.length = *v;
      if (auto v = r.number("width")) s.width = *v;
      const auto normal = r.vec3("normal");
      const auto direction = r.vec3("direction");
      if (normal) {
        if (normal->norm() == 0.0) {
          diag_.add(r.line("normal"), r.key_path("normal"), value_text(*r.node("normal")), "the normal is zero",
                    "give the direction the plane faces, e.g. normal = [0.0, 0.0, 1.0]");
        } else {
          s.normal = normal->normalized();
          if (direction) {
            const Vec3 in_plane = *direction - direction->dot(s.normal) * s.normal;
            if (in_plane.norm() <= 1e-9 * direction->norm()) {
              diag_.add(r.line("direction"), r.key_path("direction"),
                        r.has("direction") ? value_text(*r.node("direction")) : std::string("[1.0, 0.0, 0.0]"),
                        "the direction is zero or along the normal, so it gives no direction in the plane",
                        "give a direction that is not parallel to the normal");
            } else {
              s.direction = in_plane.normalized();
            }
          }
        }
      }
    } else if (*shape == "box") {
      s.type = Shape::Type::box;
      const auto min = r.vec3("min"), max = r.vec3("max");
      if (min && max) {
        s.box = Aabb{*min, *max};
        if (((*max).array() <= (*min).array()).any()) {
          diag_.add(r.line("max"), r.key_path("max"), value_text(*r.node("max")),
                    fmt::format("the box is empty or inverted: max must exceed min = {} on every axis",
                                value_text(*r.node("min"))),
                    "swap the values of min and max where max <= min");
        }
      }
      if (min && max && ((*max).array() > (*min).array()).all()) check_slits(r, structure);
    } else if (*shape == "chute") {
      s.type = Shape::Type::chute;
      if (auto v = r.vec3("origin")) s.origin = *v;
      if (auto v = r.number("length")) s.length = *v;
      if (auto v = r.number("width")) s.width = *v;
      if (auto v = r.number("slope_deg")) s.slope_deg = *v;
      if (auto v = r.number("wall_height")) s.wall_height = *v;
      if (auto v = r.number("end_wall_height")) s.end_wall_height = *v;
      if (auto direction = r.vec3("direction")) {
        const double horizontal = std::hypot(direction->x(), direction->y());
        if (horizontal == 0.0 || std::abs(direction->z()) > 1e-9 * horizontal) {
          diag_.add(r.line("direction"), r.key_path("direction"),
                    r.has("direction") ? value_text(*r.node("direction")) : std::string("[1.0, 0.0, 0.0]"),
                    "a chute's direction must be horizontal (z = 0) and not zero; slope_deg sets the descent",
                    fmt::format("write direction = [{}, {}, 0.0]", number_literal(direction->x()),
                                number_literal(direction->y())));
        } else {
          s.direction = Vec3(direction->x(), direction->y(), 0.0) / horizontal;
        }
      }
    } else if (*shape == "mesh") {
      s.type = Shape::Type::mesh;
      if (auto v = r.number("scale")) s.scale = *v;
      if (auto v = r.vec3("translate")) s.translate = *v;
      if (auto v = r.string("file")) {
        const std::size_t problems = diag_.count();
        s.file = resolve_mesh(r, *v, structure.rigid);
        if (diag_.count() == problems) read_mesh(r, *v, structure);
      }
    }
    if (s.type != Shape::Type::mesh) {
      if (auto v = r.number("element_size")) s.element_size = *v;
    }
    check_constraints(structure, shape);
    scene_.structures.push_back(std::move(structure));
  }

  // Rigid structures take STL surfaces; deformable ones Gmsh .msh volume or shell meshes.
  fs::path resolve_mesh(Reader& r, const std::string& file, bool rigid = true) {
    const fs::path given(file);
    const fs::path full = (given.is_absolute() ? given : scene_dir_ / given).lexically_normal();
    const int line = r.line("file");
    std::error_code ec;
    if (!fs::exists(full, ec)) {
      diag_.add(line, r.key_path("file"), quote_text(file),
                fmt::format("file not found (looked for {})", full.string()),
                "correct the path; it is relative to the scene file's folder");
    } else if (!fs::is_regular_file(full, ec)) {
      diag_.add(line, r.key_path("file"), quote_text(file), fmt::format("{} is not a regular file", full.string()),
                "give the path of an STL file");
    } else {
      std::string extension = full.extension().string();
      std::transform(extension.begin(), extension.end(), extension.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (rigid && extension != ".stl") {
        diag_.add(line, r.key_path("file"), quote_text(file), "a mesh must be an STL file ending in .stl",
                  "convert the mesh to STL (ASCII or binary)");
      }
      if (!rigid && extension != ".msh") {
        diag_.add(line, r.key_path("file"), quote_text(file),
                  "a deformable structure's mesh must be a Gmsh file ending in .msh (hexahedra or quadrangles)",
                  "export the mesh from Gmsh as msh 4.1 ASCII, or set rigid = true for an STL surface");
      }
    }
    return fs::weakly_canonical(full, ec);
  }

  // Reads the mesh file through the reader its solver uses (io/stl.hpp for rigid structures, io/gmsh.hpp
  // for deformable ones), so that a file the fem_solver would die of is refused here, and keeps its size
  // for the estimate of the scene (scene/estimate.hpp).
  void read_mesh(Reader& r, const std::string& file, Structure& structure) {
    const int line = r.line("file");
    const std::string key = r.key_path("file");
    MeshSize size;
    try {
      if (structure.rigid) {
        const io::StlMesh stl = io::read_stl(structure.shape.file);
        size.nodes = stl.mesh.node_position.size();
        size.triangles = stl.mesh.triangle.size();
        for (const auto& t : stl.mesh.triangle) {
          const auto& x = stl.mesh.node_position;
          size.area += 0.5 * (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]).norm();
        }
      } else {
        const io::GmshMesh gmsh = io::read_gmsh(structure.shape.file);
        size.nodes = gmsh.node.size();
        size.hexahedra = gmsh.hexahedra.size();
        size.quads = gmsh.quads.size();
        double smallest = std::numeric_limits<double>::infinity();
        for (const auto& e : gmsh.hexahedra) {
          std::array<Vec3, 8> x;
          for (std::size_t a = 0; a < 8; ++a) x[a] = gmsh.node[e[a]];
          smallest = std::min(smallest, std::cbrt(geometry::hexahedron_volume(x)));
        }
        for (const auto& q : gmsh.quads) {
          const auto& x = gmsh.node;
          const double area = 0.5 * ((x[q[1]] - x[q[0]]).cross(x[q[2]] - x[q[0]]).norm() +
                                     (x[q[2]] - x[q[0]]).cross(x[q[3]] - x[q[0]]).norm());
          smallest = std::min(smallest, std::sqrt(area));
        }
        size.smallest = smallest;
        if (!gmsh.quads.empty() && gmsh.hexahedra.empty() && !(structure.thickness > 0)) {
          diag_.add(line, key, quote_text(file),
                    fmt::format("the mesh holds {} quadrangles (shells) but the structure has no thickness",
                                gmsh.quads.size()),
                    "give thickness = the shells' thickness in m");
        }
      }
    } catch (const Error& error) {
      // The reader's message is "FILE[:LINE]: problem. Fix: fix".
      const std::string text = error.what();
      const auto fix = text.rfind(". Fix: ");
      diag_.add(line, key, quote_text(file),
                fmt::format("the mesh cannot be read: {}", fix == std::string::npos ? text : text.substr(0, fix)),
                fix == std::string::npos
                    ? std::string("export the mesh again")
                    : text.substr(fix + 7, text.ends_with('.') ? text.size() - fix - 8 : text.npos));
      return;
    }
    structure.shape.mesh_size = size;
  }

  void read_solvers(Reader& root) {
    const toml::table* table = root.table("solvers");
    Reader solvers(diag_, spec("solvers"), table != nullptr ? *table : empty_table(), "solvers");
    struct RoleInfo {
      Role role;
      const char* key;
      bool needed;
      const char* bodies;
    };
    const RoleInfo roles[] = {
        {Role::sph, "sph", has_fluids_, "[[fluids]]"},
        {Role::dem, "dem", has_particles_, "[[particles]]"},
        {Role::fem, "fem", has_structures_, "[[structures]]"},
    };
    for (const RoleInfo& info : roles) {
      const toml::table* role_table = solvers.table(info.key);
      const std::string path = std::string("solvers.") + info.key;
      if (!info.needed) {
        if (role_table != nullptr) {
          diag_.add(line_of(*role_table), path, std::nullopt,
                    fmt::format("no bodies need the {}", role_name(info.role)),
                    fmt::format("remove [{}] or add {}", path, info.bodies));
        }
        continue;
      }
      Reader r(diag_, spec("solvers-role"), role_table != nullptr ? *role_table : empty_table(), path);
      SolverSettings solver;
      solver.role = info.role;
      solver.origin = origin(r.line(), path);
      if (auto v = r.number("beta")) solver.beta = *v;
      if (auto command = r.strings("command")) {
        solver.command = *command;
        check_command(r, solver);
      }
      scene_.solvers.push_back(std::move(solver));
    }
  }

  void check_command(Reader& r, SolverSettings& solver) {
    const int line = r.line("command");
    const std::string value = value_text(*r.node("command"));
    const std::string fallback = fmt::format("remove 'command' to run the built {}", role_name(solver.role));
    if (solver.command.empty() || solver.command.front().empty()) {
      diag_.add(line, r.key_path("command"), value, "the command names no program",
                "give the program first, e.g. command = [\"/opt/solver/bin/dem\"], or " + fallback);
      return;
    }
    const std::string& program = solver.command.front();
    if (program.find('/') != std::string::npos) {
      const fs::path given(program);
      const fs::path full = (given.is_absolute() ? given : scene_dir_ / given).lexically_normal();
      if (!is_executable_file(full)) {
        diag_.add(line, r.key_path("command"), value,
                  given.is_absolute() ? fmt::format("program '{}' does not exist or is not executable", program)
                                      : fmt::format("program '{}' does not exist or is not executable (looked for {})",
                                                    program, full.string()),
                  "give an existing executable (absolute, or relative to the scene file's folder), or " + fallback);
        return;
      }
      solver.command.front() = full.string();
      return;
    }
    const char* path_variable = std::getenv("PATH");
    std::stringstream directories(path_variable != nullptr ? path_variable : "");
    std::string directory;
    while (std::getline(directories, directory, ':')) {
      if (!directory.empty() && is_executable_file(fs::path(directory) / program)) return;
    }
    diag_.add(line, r.key_path("command"), value, fmt::format("program '{}' is not found on PATH", program),
              "give the full path of the program, add its folder to PATH, or " + fallback);
  }

  // The law of a sphere-structure pair: penalty (eqs. 3-6) or Hertz-Mindlin. `contact` holds the law this
  // table starts from (the defaults, or [contact.dem_fem] for an interaction); restitution is refused where
  // the resulting law is the penalty one, which has no use for it.
  void read_surface_contact_law(Reader& r, SurfaceContact& contact, const char* model_fix) {
    if (auto v = r.string("model")) {
      contact.model = *v == "hertz_mindlin" ? SurfaceContact::Model::hertz_mindlin : SurfaceContact::Model::penalty;
    }
    if (auto v = r.number("restitution")) contact.restitution = *v;
    if (r.has("restitution") && contact.model != SurfaceContact::Model::hertz_mindlin) {
      diag_.add(r.line("restitution"), r.key_path("restitution"), value_text(*r.node("restitution")),
                "restitution applies to model = \"hertz_mindlin\", and this contact uses the penalty law",
                fmt::format("remove restitution, or set model = \"hertz_mindlin\" {}", model_fix));
    }
  }

  // The penalty keys every particle-structure pair has.
  static void read_surface_contact(Reader& r, SurfaceContact& contact) {
    if (auto v = r.number("friction")) contact.friction = *v;
    if (auto v = r.number("penalty_scale")) contact.penalty_scale = *v;
    if (auto v = r.number("normal_stiffness")) contact.normal_stiffness = *v;
    if (auto v = r.number("normal_damping_ratio")) contact.normal_damping_ratio = *v;
    if (auto v = r.number("tangential_damping_ratio")) contact.tangential_damping_ratio = *v;
  }

  // A sphere's rolling resistance against a structure ([contact.dem_fem] or a set's interaction): the
  // viscosity only with the viscous model, and a viscous model only with a viscosity.
  void read_surface_rolling(Reader& r, SurfaceContact& contact) {
    if (auto v = r.string("rolling"))
      contact.rolling = *v == "viscous" ? RollingModel::viscous : RollingModel::constant;
    if (auto v = r.number("rolling_friction")) contact.rolling_friction = *v;
    if (auto v = r.number("rolling_viscosity")) contact.rolling_viscosity = *v;
    if (r.has("rolling_viscosity") && contact.rolling != RollingModel::viscous) {
      diag_.add(r.line("rolling_viscosity"), r.key_path("rolling_viscosity"), value_text(*r.node("rolling_viscosity")),
                "rolling_viscosity applies to rolling = \"viscous\", and this contact uses the constant model",
                "remove rolling_viscosity, or set rolling = \"viscous\"");
    }
    if (r.has("rolling") && contact.rolling == RollingModel::viscous && !(contact.rolling_viscosity > 0)) {
      diag_.add(r.line("rolling"), r.key_path("rolling"), "\"viscous\"",
                "viscous rolling resistance needs rolling_viscosity > 0",
                "give rolling_viscosity (s/m), e.g. rolling_viscosity = 0.05");
    }
  }

  // The keys of one DEM-DEM contact law ([contact.dem_dem] or one of its pairs).
  static void read_dem_law(Reader& r, DemContactLaw& law) {
    if (auto v = r.string("model")) law.model = *v == "hertz_mindlin" ? DemLaw::hertz_mindlin : DemLaw::linear;
    if (auto v = r.number("normal_damping_ratio")) law.normal_damping_ratio = *v;
    if (auto v = r.number("tangential_damping_ratio")) law.tangential_damping_ratio = *v;
    if (auto v = r.number("restitution")) law.restitution = *v;
    if (auto v = r.number("friction")) law.friction = *v;
    if (auto v = r.string("rolling")) law.rolling = *v == "viscous" ? RollingModel::viscous : RollingModel::constant;
    if (auto v = r.number("rolling_friction")) law.rolling_friction = *v;
    if (auto v = r.number("rolling_viscosity")) law.rolling_viscosity = *v;
  }

  // Keys that the law of this table does not use are errors, not silently ignored.
  void check_dem_law_keys(Reader& r, const DemContactLaw& law, bool any_hertz, bool any_viscous) {
    if (r.has("restitution") && !any_hertz) {
      diag_.add(r.line("restitution"), r.key_path("restitution"), value_text(*r.node("restitution")),
                "restitution applies to model = \"hertz_mindlin\", and no pair uses it",
                "remove restitution, or set model = \"hertz_mindlin\"");
    }
    if (r.has("rolling_viscosity") && !any_viscous) {
      diag_.add(r.line("rolling_viscosity"), r.key_path("rolling_viscosity"), value_text(*r.node("rolling_viscosity")),
                "rolling_viscosity applies to rolling = \"viscous\", and no pair uses it",
                "remove rolling_viscosity, or set rolling = \"viscous\"");
    }
    if (law.rolling == RollingModel::viscous && !(law.rolling_viscosity > 0) && (r.has("rolling"))) {
      diag_.add(r.line("rolling"), r.key_path("rolling"), "\"viscous\"",
                "viscous rolling resistance needs rolling_viscosity > 0",
                "give rolling_viscosity (s/m), e.g. rolling_viscosity = 0.05");
    }
  }

  void read_contact(Reader& root) {
    const toml::table* table = root.table("contact");
    Reader contact(diag_, spec("contact"), table != nullptr ? *table : empty_table(), "contact");

    const toml::table* dem_dem = contact.table("dem_dem");
    if (dem_dem != nullptr && !has_particles_) {
      diag_.add(line_of(*dem_dem), "contact.dem_dem", std::nullopt,
                "there are no particles, so no sphere-sphere contact", "remove [contact.dem_dem] or add [[particles]]");
    }
    Reader dd(diag_, spec("contact-dem_dem"), dem_dem != nullptr ? *dem_dem : empty_table(), "contact.dem_dem");
    DemContact& dem = scene_.dem_contact;
    read_dem_law(dd, dem);
    if (auto v = dd.number("normal_stiffness")) dem.normal_stiffness = *v;
    if (auto v = dd.number("normal_stiffness_scale")) dem.normal_stiffness_scale = *v;
    if (auto v = dd.number("tangential_stiffness_ratio")) dem.tangential_stiffness_ratio = *v;
    if (dd.has("normal_stiffness") && dd.has("normal_stiffness_scale")) {
      diag_.add(dd.line("normal_stiffness_scale"), dd.key_path("normal_stiffness_scale"),
                value_text(*dd.node("normal_stiffness_scale")),
                "give either normal_stiffness or normal_stiffness_scale, not both", "remove one of the two keys");
    }
    std::vector<Reader> pair_readers;
    std::vector<DemContactLaw> pair_laws;  // of every pair table, valid or not, for the key checks
    if (const toml::array* pairs = dd.table_list("pairs")) {
      std::map<std::pair<std::string, std::string>, int> seen;
      pair_readers.reserve(pairs->size());
      for (std::size_t k = 0; k < pairs->size(); ++k) {
        const std::string path = fmt::format("contact.dem_dem.pairs[{}]", k);
        Reader& r = pair_readers.emplace_back(diag_, spec("contact-dem_dem-pairs"), *pairs->get(k)->as_table(), path);
        DemPairLaw pair;
        pair.origin = origin(r.line(), path);
        pair.law = static_cast<const DemContactLaw&>(dem);
        read_dem_law(r, pair.law);
        pair_laws.push_back(pair.law);
        const auto materials = r.strings("materials");
        if (!materials) continue;
        const int line = r.line("materials");
        const std::string value = value_text(*r.node("materials"));
        if (materials->size() != 2) {
          diag_.add(line, r.key_path("materials"), value,
                    fmt::format("a pair names exactly two materials, not {}", materials->size()),
                    "write materials = [\"A\", \"B\"] (the same name twice for a material with itself)");
          continue;
        }
        bool known = true;
        for (const auto& name : *materials) {
          if (std::find(material_names_.begin(), material_names_.end(), name) != material_names_.end()) continue;
          known = false;
          const auto suggestion = closest_match(name, material_names_);
          diag_.add(line, r.key_path("materials"), value,
                    fmt::format("no material is named {}{}", quote_text(name),
                                suggestion ? fmt::format(". Did you mean '{}'?", *suggestion) : std::string()),
                    fmt::format("use the names of [materials.NAME]: {}", join(material_names_)));
        }
        if (!known) continue;
        pair.material_a = std::min((*materials)[0], (*materials)[1]);
        pair.material_b = std::max((*materials)[0], (*materials)[1]);
        auto [it, inserted] = seen.try_emplace({pair.material_a, pair.material_b}, line);
        if (!inserted) {
          diag_.add(line, r.key_path("materials"), value,
                    fmt::format("this pair of materials is already given at line {}", it->second),
                    "merge the two tables of this pair");
          continue;
        }
        dem.pairs.push_back(std::move(pair));
      }
    }
    bool any_hertz = dem.model == DemLaw::hertz_mindlin, any_viscous = dem.rolling == RollingModel::viscous;
    for (const auto& pair : dem.pairs) {
      any_hertz = any_hertz || pair.law.model == DemLaw::hertz_mindlin;
      any_viscous = any_viscous || pair.law.rolling == RollingModel::viscous;
    }
    check_dem_law_keys(dd, dem, any_hertz, any_viscous);
    for (std::size_t k = 0; k < pair_readers.size(); ++k) {
      const DemContactLaw& law = pair_laws[k];
      check_dem_law_keys(pair_readers[k], law, law.model == DemLaw::hertz_mindlin,
                         law.rolling == RollingModel::viscous);
    }

    const toml::table* dem_fem = contact.table("dem_fem");
    if (dem_fem != nullptr && !(has_particles_ && has_structures_)) {
      diag_.add(line_of(*dem_fem), "contact.dem_fem", std::nullopt,
                "sphere-structure contact needs both particles and structures",
                "remove [contact.dem_fem] or add the missing [[particles]] or [[structures]]");
    }
    Reader df(diag_, spec("contact-dem_fem"), dem_fem != nullptr ? *dem_fem : empty_table(), "contact.dem_fem");
    read_surface_contact_law(df, scene_.dem_fem_default, "in [contact.dem_fem]");
    read_surface_contact(df, scene_.dem_fem_default);
    read_surface_rolling(df, scene_.dem_fem_default);

    const toml::table* sph_fem = contact.table("sph_fem");
    if (sph_fem != nullptr && !(has_fluids_ && has_structures_)) {
      diag_.add(line_of(*sph_fem), "contact.sph_fem", std::nullopt,
                "fluid-structure contact needs both fluids and structures",
                "remove [contact.sph_fem] or add the missing [[fluids]] or [[structures]]");
    }
    Reader sf(diag_, spec("contact-sph_fem"), sph_fem != nullptr ? *sph_fem : empty_table(), "contact.sph_fem");
    read_surface_contact(sf, scene_.sph_fem_default);

    const toml::table* sph_dem = contact.table("sph_dem");
    if (sph_dem != nullptr && !(has_fluids_ && has_particles_)) {
      diag_.add(line_of(*sph_dem), "contact.sph_dem", std::nullopt,
                "fluid-sphere contact needs both fluids and particles",
                "remove [contact.sph_dem] or add the missing [[fluids]] or [[particles]]");
    }
    const toml::table* fem_fem = contact.table("fem_fem");
    if (fem_fem != nullptr && !deformable_pair_possible()) {
      diag_.add(line_of(*fem_fem), "contact.fem_fem", std::nullopt,
                "structure-structure contact needs two structures, one of them deformable",
                "remove [contact.fem_fem], or add the structures (rigid = false for a deformable one)");
    }
    Reader ff(diag_, spec("contact-fem_fem"), fem_fem != nullptr ? *fem_fem : empty_table(), "contact.fem_fem");
    if (auto v = ff.boolean("enabled")) scene_.fem_fem_default.enabled = *v;
    read_surface_contact(ff, scene_.fem_fem_default);

    Reader sd(diag_, spec("contact-sph_dem"), sph_dem != nullptr ? *sph_dem : empty_table(), "contact.sph_dem");
    read_sph_dem_contact(sd, scene_.sph_dem_default);
    if (sph_dem != nullptr) {
      sph_dem_default_where_ = {sd.has("normal_stiffness") ? sd.line("normal_stiffness") : line_of(*sph_dem),
                                sd.has("normal_stiffness") ? "contact.sph_dem.normal_stiffness" : "contact.sph_dem"};
    }
  }

  // The keys of a fluid/particle-set contact ([contact.sph_dem] or an interaction of the two).
  static void read_sph_dem_contact(Reader& r, SphDemContact& contact) {
    if (auto v = r.string("model")) {
      contact.model = *v == "penalty" ? SphDemContact::Model::penalty : SphDemContact::Model::boundary_particles;
    }
    if (auto v = r.number("normal_stiffness")) contact.normal_stiffness = *v;
    if (auto v = r.number("normal_damping_ratio")) contact.normal_damping_ratio = *v;
    if (auto v = r.number("friction")) contact.friction = *v;
  }

  // Whether two structures, one deformable, are in the scene (FEM-FEM contact can exist).
  [[nodiscard]] bool deformable_pair_possible() const {
    const bool deformable =
        std::any_of(scene_.structures.begin(), scene_.structures.end(), [](const Structure& s) { return !s.rigid; });
    return scene_.structures.size() >= 2 && deformable;
  }

  [[nodiscard]] const Structure* structure_named(const std::string& name) const {
    for (const auto& s : scene_.structures) {
      if (s.name == name) return &s;
    }
    return nullptr;
  }

  // An interaction of two structures (FEM-FEM contact in the fem_solver): the penalty keys of
  // [contact.fem_fem]; the pair is in contact unless it says enabled = false.
  void read_fem_fem_interaction(Reader& r, FemFemInteraction& interaction) {
    interaction.contact = scene_.fem_fem_default;
    interaction.contact.enabled = true;
    for (const char* key : {"restitution", "rolling", "rolling_friction", "rolling_viscosity"}) {
      if (r.has(key)) {
        diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                  "two structures meet through the penalty law of paper eqs. 3-6 (node to segment), which has no "
                  "such key",
                  "remove the key; friction, penalty_scale, normal_stiffness and the damping ratios apply");
      }
    }
    if (auto model = r.string("model"); model && *model != "penalty") {
      diag_.add(r.line("model"), r.key_path("model"), quote_text(*model),
                "two structures meet through the penalty law (node to segment) only",
                "write model = \"penalty\", or remove model");
    }
    read_surface_contact(r, interaction.contact);
    if (auto v = r.boolean("enabled")) interaction.contact.enabled = *v;
  }

  void read_interactions(Reader& root) {
    const toml::array* interactions = root.table_list("interactions");
    if (interactions == nullptr || interactions->empty()) return;
    if (!((has_particles_ || has_fluids_) && has_structures_) && !(has_fluids_ && has_particles_) &&
        scene_.structures.size() < 2) {
      diag_.add(root.line("interactions"), "interactions", std::nullopt,
                "interactions pair a particle set or fluid with a structure, a fluid with a particle set, or two "
                "structures, but the scene lacks the bodies for any",
                "remove the [[interactions]] tables or add the missing bodies");
      return;
    }
    std::vector<std::string> body_names;
    for (const auto& [name, body] : bodies_) body_names.push_back(name);
    std::map<std::pair<std::string, std::string>, int> seen;  // (set or fluid, structure or set) -> line
    for (std::size_t k = 0; k < interactions->size(); ++k) {
      const toml::table& table = *interactions->get(k)->as_table();
      const std::string path = fmt::format("interactions[{}]", k);
      Reader r(diag_, spec("interactions"), table, path);
      const auto pair = r.strings("pair");
      // Which kind of pair it is decides which keys apply; an unreadable pair reads as a particle set and
      // a structure, so that its other keys are still checked.
      const BodyName* bodies[2] = {nullptr, nullptr};
      if (pair && pair->size() == 2) {
        for (int b = 0; b < 2; ++b) {
          const auto it = bodies_.find((*pair)[static_cast<std::size_t>(b)]);
          if (it != bodies_.end()) bodies[b] = &it->second;
        }
      }
      const auto is_fluid = [](const BodyName* body) { return body != nullptr && body->is_fluid; };
      const auto is_set = [](const BodyName* body) { return body != nullptr && body->is_particle_set; };
      const bool fluid_and_set =
          (is_fluid(bodies[0]) && is_set(bodies[1])) || (is_set(bodies[0]) && is_fluid(bodies[1]));
      const bool names_fluid = is_fluid(bodies[0]) || is_fluid(bodies[1]);
      const bool two_structures = bodies[0] != nullptr && bodies[1] != nullptr && !is_fluid(bodies[0]) &&
                                  !is_set(bodies[0]) && !is_fluid(bodies[1]) && !is_set(bodies[1]);
      Interaction interaction;
      SphDemInteraction sph_dem;
      FemFemInteraction fem_fem;
      interaction.origin = sph_dem.origin = fem_fem.origin = origin(r.line(), path);
      if (two_structures) {
        read_fem_fem_interaction(r, fem_fem);
      } else if (fluid_and_set) {
        sph_dem.contact = scene_.sph_dem_default;
        for (const char* key : {"restitution", "penalty_scale", "tangential_damping_ratio", "rolling",
                                "rolling_friction", "rolling_viscosity"}) {
          if (r.has(key)) {
            diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                      "a fluid and a particle set meet through boundary particles or the penalty law of paper "
                      "eqs. 1-2, which has no such key",
                      "remove the key, or give normal_stiffness, normal_damping_ratio or friction");
          }
        }
        if (auto model = r.string("model"); model && *model == "hertz_mindlin") {
          diag_.add(r.line("model"), r.key_path("model"), "\"hertz_mindlin\"",
                    "a fluid and a particle set meet through \"boundary_particles\" or \"penalty\"",
                    "write model = \"boundary_particles\" or model = \"penalty\"");
        } else {
          read_sph_dem_contact(r, sph_dem.contact);
        }
        if (auto v = r.boolean("enabled")) sph_dem.contact.enabled = *v;
      } else {
        interaction.contact = names_fluid ? scene_.sph_fem_default : scene_.dem_fem_default;
        if (auto model = r.string("model"); model && *model == "boundary_particles") {
          diag_.add(r.line("model"), r.key_path("model"), "\"boundary_particles\"",
                    "boundary particles are a law between a fluid and a particle set; a structure meets a fluid "
                    "through [sph] wall_model",
                    names_fluid ? "remove model (set [sph] wall_model for the fluid's walls)"
                                : "write model = \"penalty\" or model = \"hertz_mindlin\"");
        } else if (names_fluid) {
          for (const char* key : {"model", "restitution", "rolling", "rolling_friction", "rolling_viscosity"}) {
            if (r.has(key)) {
              diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                        "fluid particles meet structures through the penalty law only",
                        "remove the key from this fluid's interaction");
            }
          }
        } else {
          read_surface_contact_law(r, interaction.contact, "in this interaction or in [contact.dem_fem]");
        }
        read_surface_contact(r, interaction.contact);
        if (!names_fluid) read_surface_rolling(r, interaction.contact);
        if (auto v = r.boolean("enabled")) interaction.contact.enabled = *v;
      }
      if (!pair) continue;
      const int line = r.line("pair");
      const std::string value = value_text(*r.node("pair"));
      if (pair->size() != 2) {
        diag_.add(line, r.key_path("pair"), value, fmt::format("a pair names exactly two bodies, not {}", pair->size()),
                  "write pair = [\"PARTICLE_SET\", \"STRUCTURE\"]");
        continue;
      }
      bool known = true;
      for (const auto& name : *pair) {
        if (bodies_.count(name) != 0) continue;
        known = false;
        const auto suggestion = closest_match(name, body_names);
        diag_.add(line, r.key_path("pair"), value,
                  fmt::format("no fluid, particle set or structure is named {}{}", quote_text(name),
                              suggestion ? fmt::format(". Did you mean '{}'?", *suggestion) : std::string()),
                  fmt::format("use the names of [[fluids]], [[particles]] and [[structures]]: {}", join(body_names)));
      }
      if (!known) continue;
      const BodyName& first = *bodies[0];
      const BodyName& second = *bodies[1];
      if (fluid_and_set) {
        sph_dem.fluid = first.is_fluid ? (*pair)[0] : (*pair)[1];
        sph_dem.set = first.is_fluid ? (*pair)[1] : (*pair)[0];
        auto [it, inserted] = seen.try_emplace({sph_dem.fluid, sph_dem.set}, line);
        if (!inserted) {
          diag_.add(line, r.key_path("pair"), value, fmt::format("this pair is already given at line {}", it->second),
                    "merge the two [[interactions]] tables of this pair");
          continue;
        }
        sph_dem_where_[{sph_dem.fluid, sph_dem.set}] = {
            r.has("normal_stiffness") ? r.line("normal_stiffness") : r.line(),
            r.has("normal_stiffness") ? r.key_path("normal_stiffness") : path};
        scene_.sph_dem_interactions.push_back(std::move(sph_dem));
        continue;
      }
      const bool first_moves = first.is_particle_set || first.is_fluid;
      const bool second_moves = second.is_particle_set || second.is_fluid;
      if (first_moves && second_moves) {
        diag_.add(line, r.key_path("pair"), value,
                  fmt::format("both are {}; a pair is a fluid or particle set and a structure, or a fluid and a "
                              "particle set",
                              first.is_fluid ? "fluids" : "particle sets"),
                  first.is_fluid ? "pair a fluid with a structure or a particle set"
                                 : "sphere-sphere contact is set in [contact.dem_dem]; pair a particle set with a "
                                   "structure or a fluid here");
        continue;
      }
      if (!first_moves && !second_moves) {
        const Structure* a = structure_named((*pair)[0]);
        const Structure* b = structure_named((*pair)[1]);
        if ((*pair)[0] == (*pair)[1]) {
          diag_.add(line, r.key_path("pair"), value,
                    "names one structure twice; a structure does not meet its own faces (there is no self-contact)",
                    "pair two different structures");
          continue;
        }
        if (a != nullptr && b != nullptr && a->rigid && b->rigid) {
          diag_.add(line, r.key_path("pair"), value,
                    "both structures are rigid: they never move, so they never come into contact",
                    "pair a deformable structure (rigid = false) with another structure");
          continue;
        }
        fem_fem.a = (*pair)[0];
        fem_fem.b = (*pair)[1];
        auto [it, inserted] = seen.try_emplace({std::min(fem_fem.a, fem_fem.b), std::max(fem_fem.a, fem_fem.b)}, line);
        if (!inserted) {
          diag_.add(line, r.key_path("pair"), value, fmt::format("this pair is already given at line {}", it->second),
                    "merge the two [[interactions]] tables of this pair");
          continue;
        }
        scene_.fem_fem_interactions.push_back(std::move(fem_fem));
        continue;
      }
      interaction.a = first_moves ? (*pair)[0] : (*pair)[1];
      interaction.b = first_moves ? (*pair)[1] : (*pair)[0];
      interaction.fluid = first.is_fluid || second.is_fluid;
      auto [it, inserted] = seen.try_emplace({interaction.a, interaction.b}, line);
      if (!inserted) {
        diag_.add(line, r.key_path("pair"), value, fmt::format("this pair is already given at line {}", it->second),
                  "merge the two [[interactions]] tables of this pair");
        continue;
      }
      scene_.interactions.push_back(std::move(interaction));
    }
  }

  void read_recording(Reader& root) {
    const toml::table* table = root.table("recording");
    Reader r(diag_, spec("recording"), table != nullptr ? *table : empty_table(), "recording");
    Recording& recording = scene_.recording;
    if (auto v = r.boolean("enabled")) recording.enabled = *v;
    if (auto v = r.strings("fields")) recording.fields = *v;
    if (auto v = r.integer("every")) recording.every = static_cast<std::uint64_t>(*v);
    const auto first = r.integer("first_step");
    const auto last = r.integer("last_step");
    if (first) recording.first_step = static_cast<std::uint64_t>(*first);
    if (last) recording.last_step = static_cast<std::uint64_t>(*last);
    if (first && last && *first > *last) {
      diag_.add(r.line("last_step"), r.key_path("last_step"), std::to_string(*last),
                fmt::format("the last step comes before first_step = {}", *first),
                "give last_step >= first_step, or swap the two");
    }
    if (auto v = r.number("flush_interval")) recording.flush_interval = *v;
  }

  // A gauge or sensor name: valid and unique among its kind (`names`).
  void register_instrument(Reader& r, const std::string& name, std::map<std::string, int>& names, const char* kind) {
    const int line = r.line("name");
    if (!valid_name(name)) {
      diag_.add(line, r.key_path("name"), quote_text(name), "a name must be made of letters, digits, '_' and '-'",
                fmt::format("rename it, e.g. \"{}_1\"", kind));
      return;
    }
    auto [it, inserted] = names.try_emplace(name, line);
    if (!inserted) {
      diag_.add(line, r.key_path("name"), quote_text(name),
                fmt::format("another {} has that name (line {})", kind, it->second),
                fmt::format("give each {} its own name", kind));
    }
  }

  void read_gauges(Reader& root) {
    const toml::array* gauges = root.table_list("gauges");
    if (gauges == nullptr || gauges->empty()) return;
    if (!has_fluids_) {
      diag_.add(root.line("gauges"), "gauges", std::nullopt,
                "gauges measure the fluid, but the scene has no [[fluids]]", "remove the [[gauges]] or add a fluid");
      return;
    }
    std::map<std::string, int> names;
    for (std::size_t k = 0; k < gauges->size(); ++k) {
      const std::string path = fmt::format("gauges[{}]", k);
      Reader r(diag_, spec("gauges"), *gauges->get(k)->as_table(), path);
      Gauge gauge;
      gauge.origin = origin(r.line(), path);
      if (auto v = r.string("name")) {
        gauge.name = *v;
        register_instrument(r, gauge.name, names, "gauge");
      }
      if (auto v = r.number("interval")) gauge.interval = *v;
      const auto kind = r.string("kind");
      if (!kind) continue;
      r.select(*kind);
      std::vector<std::string> point_keys;
      if (*kind == "point") {
        if (auto v = r.vec3("position")) gauge.start = gauge.end = *v;
        point_keys = {"position"};
      } else {
        const auto start = r.vec3("start"), end = r.vec3("end");
        if (auto v = r.integer("points")) gauge.points = static_cast<std::size_t>(*v);
        if (start) gauge.start = *start;
        if (end) gauge.end = *end;
        if (start && end && *start == *end) {
          diag_.add(r.line("end"), r.key_path("end"), value_text(*r.node("end")),
                    "a line ends where it starts, so it has no direction", "give an end point other than start");
        }
        point_keys = {"start", "end"};
      }
      if (scene_.sph.domain) {
        for (const std::string& key : point_keys) {
          const toml::node* node = r.node(key);
          if (node == nullptr) continue;
          const Vec3 point = key == "end" ? gauge.end : gauge.start;
          if (!scene_.sph.domain->contains(point)) {
            diag_.add(r.line(key), r.key_path(key), value_text(*node),
                      fmt::format("outside the SPH domain [{}, {}] (sph.domain_min/domain_max, line {}): no fluid "
                                  "can ever reach it",
                                  vec_text(scene_.sph.domain->min), vec_text(scene_.sph.domain->max), domain_line_),
                      "move the gauge into the domain or enlarge the domain");
          }
        }
      }
      scene_.gauges.push_back(std::move(gauge));
    }
  }

  void read_sensors(Reader& root) {
    const toml::array* sensors = root.table_list("sensors");
    if (sensors == nullptr || sensors->empty()) return;
    std::vector<std::string> structure_names;
    for (const Structure& structure : scene_.structures) structure_names.push_back(structure.name);
    std::map<std::string, int> names;
    for (std::size_t k = 0; k < sensors->size(); ++k) {
      const std::string path = fmt::format("sensors[{}]", k);
      Reader r(diag_, spec("sensors"), *sensors->get(k)->as_table(), path);
      Sensor sensor;
      sensor.origin = origin(r.line(), path);
      if (auto v = r.string("name")) {
        sensor.name = *v;
        register_instrument(r, sensor.name, names, "sensor");
      }
      if (auto v = r.string("part")) {
        sensor.part = *v;
        if (std::find(structure_names.begin(), structure_names.end(), *v) == structure_names.end()) {
          const auto suggestion = closest_match(*v, structure_names);
          std::string problem = "no structure of that name";
          if (suggestion) problem += fmt::format(". Did you mean '{}'?", *suggestion);
          diag_.add(r.line("part"), r.key_path("part"), quote_text(*v), problem,
                    structure_names.empty() ? std::string("add the [[structures]] the sensor sits on")
                                            : fmt::format("use one of: {}", join(structure_names)));
        }
      }
      const auto min = r.vec3("min"), max = r.vec3("max");
      if (min.has_value() != max.has_value()) {
        const char* given = min ? "min" : "max";
        diag_.add(r.line(given), r.key_path(given), value_text(*r.node(given)),
                  fmt::format("a sensor box needs both min and max; {} is missing", min ? "max" : "min"),
                  "give both corners, or neither for a sensor of the whole part");
      } else if (min && max) {
        if (((*max - *min).array() <= 0).any()) {
          diag_.add(r.line("max"), r.key_path("max"), value_text(*r.node("max")),
                    fmt::format("the box must exceed min = {} on every axis", value_text(*r.node("min"))),
                    "give max > min on x, y and z (a box around the patch, a few mm thick across a flat face)");
        } else {
          sensor.box = Aabb{*min, *max};
          check_sensor_box(r, sensor);
        }
      }
      scene_.sensors.push_back(std::move(sensor));
    }
  }

  // The box must meet the part's surface. Checked here where the surface follows from the scene (rigid
  // shapes, generated deformable boxes and panels); a .msh part's surface is checked by the coupler when
  // the fem_solver has registered it.
  void check_sensor_box(Reader& r, const Sensor& sensor) {
    const auto patch = sensor_patch(scene_.structures, sensor);
    if (!patch || patch->area > 0) return;
    diag_.add(r.line("min"), r.key_path("min"), value_text(*r.node("min")),
              fmt::format("the box [{}, {}] meets none of the surface of '{}', which spans {} to {}",
                          vec_text(sensor.box->min), vec_text(sensor.box->max), sensor.part,
                          vec_text(patch->part_bounds.min), vec_text(patch->part_bounds.max)),
              "move the box onto the part's face (a box a few mm thick across the face)");
  }

  // Listed spheres must not overlap: sweep along x over spheres sorted by
  // their lowest x (deterministic order: ties broken by file order).
  void check_overlaps() {
    std::vector<std::size_t> order(listed_.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return listed_[a].center.x() - listed_[a].radius < listed_[b].center.x() - listed_[b].radius;
    });
    std::size_t reported = 0, more = 0;
    for (std::size_t i = 0; i < order.size(); ++i) {
      const ListedSphere& a = listed_[order[i]];
      for (std::size_t j = i + 1; j < order.size(); ++j) {
        const ListedSphere& b = listed_[order[j]];
        if (b.center.x() - b.radius >= a.center.x() + a.radius) break;
        const double depth = a.radius + b.radius - (a.center - b.center).norm();
        if (depth <= 1e-9 * (a.radius + b.radius)) continue;
        const bool a_first = order[i] < order[j];
        const ListedSphere& earlier = a_first ? a : b;
        const ListedSphere& later = a_first ? b : a;
        if (reported == kMaxOverlapReports) {
          ++more;
          continue;
        }
        ++reported;
        diag_.add(
            later.line, later.path,
            fmt::format("{{ center = [{}, {}, {}], radius = {} }}", number_literal(later.center.x()),
                        number_literal(later.center.y()), number_literal(later.center.z()),
                        number_literal(later.radius)),
            fmt::format("overlaps {} (line {}) by {} m", earlier.path, earlier.line, fmt::format("{:.4g}", depth)),
            "move the spheres apart or make them smaller; initial spheres must not overlap");
      }
    }
    if (more > 0) {
      diag_.add_plain(listed_[order.front()].line, fmt::format("{} more pairs of listed spheres overlap", more),
                      "separate every overlapping pair");
    }
  }

  // Where a fluid/particle-set contact's settings were written: the line and key of its
  // normal_stiffness, else of its table.
  struct Where {
    int line = 0;
    std::string key;
  };
  [[nodiscard]] Where sph_dem_where(const std::string& fluid, const std::string& set) const {
    const auto it = sph_dem_where_.find({fluid, set});
    return it != sph_dem_where_.end() ? it->second : sph_dem_default_where_;
  }

  // Fluid/particle-set contacts (after every body, [sph] and the interactions are read): boulder sizes for
  // boundary particles, one law per set against every fluid, a penalty stiffness the SPH step can carry,
  // and spheres starting inside a fluid only where their places are known before the run.
  void check_sph_dem() {
    if (!has_fluids_ || !has_particles_ || !(scene_.sph.particle_spacing > 0) || !(scene_.sph.sound_speed > 0)) return;
    if (std::any_of(scene_.fluids.begin(), scene_.fluids.end(), [&](const FluidBody& f) {
          return std::find(material_names_.begin(), material_names_.end(), f.material) == material_names_.end();
        })) {
      return;  // reported already; the stiffness needs the fluid's density
    }
    const double dx = scene_.sph.particle_spacing;
    const auto material_of = [&](const std::string& name) -> const Material& {
      return *std::find_if(scene_.materials.begin(), scene_.materials.end(),
                           [&](const Material& m) { return m.name == name; });
    };
    bool settled_before = false;
    for (const ParticleSet& set : scene_.particle_sets) {
      const bool position_unknown = set.kind == ParticleSet::Kind::fill && (settled_before || set.settle_time > 0);
      settled_before = settled_before || (set.kind == ParticleSet::Kind::fill && set.settle_time > 0);
      const std::string set_key = set.origin.key;
      bool any_boundary = false, any_other = false;
      std::string boundary_fluid, other_fluid;
      for (const FluidBody& fluid : scene_.fluids) {
        const SphDemContact contact = scene_.sph_dem_contact(fluid.name, set.name);
        const bool boundary = contact.enabled && contact.model == SphDemContact::Model::boundary_particles;
        (boundary ? any_boundary : any_other) = true;
        (boundary ? boundary_fluid : other_fluid) = fluid.name;
        if (contact.enabled && contact.model == SphDemContact::Model::penalty && contact.normal_stiffness &&
            material_names_.end() != std::find(material_names_.begin(), material_names_.end(), fluid.material)) {
          // The materials are not sorted yet: the pair step from the fluid's own density.
          const double rho0 = material_of(fluid.material).density;
          const double pair_dt = physics::spring_stable_dt(rho0 * dx * dx * dx, *contact.normal_stiffness);
          const double sph_dt = scene_.sph.cfl * scene_.sph.smoothing_length() / scene_.sph.sound_speed;
          if (pair_dt < sph_dt) {
            const double largest = physics::stiffness_for_stable_dt(rho0 * dx * dx * dx, sph_dt);
            const Where where = sph_dem_where(fluid.name, set.name);
            diag_.add(
                where.line, where.key, number_literal(*contact.normal_stiffness),
                fmt::format("the penalty spring of fluid '{}' against particle set '{}' has the stable step "
                            "0.2 pi sqrt(m / K) = {:.3g} s (m = rho0 dx^3 = {:.3g} kg), below the SPH step "
                            "cfl h / c = {:.3g} s: every step of the run would shrink to {:.2g} of the SPH's, "
                            "or the spring would be unstable at the SPH step",
                            fluid.name, set.name, pair_dt, rho0 * dx * dx * dx, sph_dt, pair_dt / sph_dt),
                fmt::format("give normal_stiffness <= {:.3g} N/m, or leave it out for the derived stiffness", largest));
          }
        }
        if (!contact.enabled) continue;
        if (!position_unknown || !set.region.overlaps(fluid.bounds())) continue;
        diag_.add(set.origin.line, set_key + ".fill", std::nullopt,
                  fmt::format("the fill region of particle set '{}' reaches into fluid body '{}'{}: where its spheres "
                              "come to rest is only known once the dem_solver has settled them, so the sph_solver "
                              "cannot leave their places free of fluid",
                              set.name, fluid.name,
                              set.settle_time > 0 ? " and the set settles (settle_time)"
                                                  : " and an earlier fill set settles, which moves its obstacles"),
                  "move the fill region out of the fluid body (e.g. above it: the spheres fall in), list the "
                  "spheres, or drop settle_time");
      }
      if (any_boundary && any_other) {
        const Where where = sph_dem_where(other_fluid, set.name);
        diag_.add(where.line, where.key, std::nullopt,
                  fmt::format("particle set '{}' meets fluid '{}' as boundary particles but fluid '{}' otherwise; "
                              "the sph_solver sees a boulder's wall particles whatever fluid body is near it",
                              set.name, boundary_fluid, other_fluid),
                  "give the set the same contact model (and enabled) against every fluid body");
      }
      if (!any_boundary) continue;
      double smallest = std::numeric_limits<double>::infinity();
      if (set.kind == ParticleSet::Kind::list) {
        for (const Sphere& sphere : set.spheres) smallest = std::min(smallest, 2 * sphere.radius);
      } else {
        smallest = set.diameter_min;
      }
      if (smallest < kMinBoundaryParticleDiameter * dx) {
        diag_.add(
            set.origin.line, set_key + (set.kind == ParticleSet::Kind::list ? ".spheres" : ".fill"), std::nullopt,
            fmt::format("a sphere of diameter {:g} m spans {:.2g} SPH spacings (dx = {:g} m); as boundary "
                        "particles a boulder needs at least {:g} spacings to have a surface the fluid can push",
                        smallest, smallest / dx, dx, kMinBoundaryParticleDiameter),
            fmt::format("use spheres of at least {:g} m, a finer sph.particle_spacing (<= {:g} m), or model = "
                        "\"penalty\" for this set (in [contact.sph_dem] or an interaction of '{}' with the fluid)",
                        kMinBoundaryParticleDiameter * dx, smallest / kMinBoundaryParticleDiameter, set.name));
      }
    }
  }

  // The fills placed as the dem_solver places them (the same function, the same seed): the 30 % rule is a quick
  // estimate, and a region narrower than its spheres somewhere (a slanted strip whose bounding box is wide
  // enough) passes it and still cannot be filled.
  void check_fills() {
    try {
      (void)geometry::initial_spheres(scene_);
    } catch (const geometry::FillError& error) {
      std::size_t k = 0;
      while (k + 1 < scene_.particle_sets.size() && scene_.particle_sets[k].name != error.set_name()) ++k;
      const std::string key = fmt::format("particles[{}].fill.count", k);
      diag_.add(line_of_key(key), key, value_of_key(key), error.problem(),
                "enlarge the region (it must be wider than the largest diameter everywhere, not only its bounding "
                "box), or lower 'count' or the diameters");
    }
  }

  // ------------------------------------------------------- costs ----

  // The line of a dotted key of the document ("sph.particle_spacing", "particles[2].fill.count"), else of the
  // nearest table above it that is written, else 1.
  [[nodiscard]] int line_of_key(std::string path) const {
    while (!path.empty()) {
      const toml::node_view<const toml::node> node = toml::at_path(document_, path);
      if (node && line_of(*node.node()) > 0) return line_of(*node.node());
      const auto cut = path.find_last_of(".[");
      path = cut == std::string::npos ? std::string() : path.substr(0, cut);
    }
    return 1;
  }
  [[nodiscard]] std::optional<std::string> value_of_key(const std::string& path) const {
    const toml::node_view<const toml::node> node = toml::at_path(document_, path);
    if (!node) return std::nullopt;
    return value_text(*node.node());
  }

  // What the scene would cost (scene/estimate.hpp): refused when it cannot be run on this machine, naming
  // the estimate and the key to change.
  void check_costs() {
    const SceneEstimate estimate = estimate_scene(scene_);
    const RunSettings& run = scene_.run;
    if (estimate.outputs > kMaxOutputs) {
      diag_.add(
          line_of_key("run.output_interval"), "run.output_interval", number_literal(run.output_interval),
          fmt::format("end_time = {} s holds {:.3g} output times, each writing a file per solver; at most {:g} "
                      "are allowed",
                      number_literal(run.end_time), estimate.outputs, kMaxOutputs),
          fmt::format("give output_interval >= end_time / {:g} = {:.3g} s", kMaxOutputs, run.end_time / kMaxOutputs));
    }
    if (estimate.steps > kMaxSteps) {
      const std::string& key = estimate.dt_key;
      diag_.add(line_of_key(key), key, value_of_key(key),
                fmt::format("the run would take about {:.3g} steps, more than the {:g} that can be run: {} gives a "
                            "stable step of about {:.3g} s for end_time = {} s",
                            estimate.steps, kMaxSteps, estimate.dt_what, estimate.dt, number_literal(run.end_time)),
                key.ends_with("youngs_modulus")
                    ? "check the modulus (rock and concrete: 1e10 to 1e11 Pa; a softer material gives a longer step), "
                      "or shorten run.end_time"
                    : fmt::format("raise {} (the step grows with it), or shorten run.end_time", key));
    }
    const double memory = physical_memory_bytes();
    if (memory > 0 && estimate.memory_bytes > memory) report_memory(estimate, memory);
  }

  // The scene needs more memory than the machine has: the estimate, and the key of its largest share.
  void report_memory(const SceneEstimate& e, double memory) {
    struct Share {
      double bytes;
      std::string what, key, fix;
    };
    std::vector<Share> shares;
    const double fluid = e.total_fluid_particles();
    if (fluid > 0) {
      shares.push_back({fluid * kBytesPerFluidParticle,
                        fmt::format("{:.3g} fluid particles of {:g} B", fluid, kBytesPerFluidParticle),
                        "sph.particle_spacing",
                        "raise sph.particle_spacing (doubling it divides the fluid particles by 8 and the wall "
                        "particles by 4)"});
    }
    if (e.wall_particles > 0) {
      shares.push_back({e.wall_particles * kBytesPerWallParticle,
                        fmt::format("{:.3g} wall particles of {:g} B", e.wall_particles, kBytesPerWallParticle),
                        "sph.particle_spacing",
                        "raise sph.particle_spacing (doubling it divides the wall particles by 4), or use "
                        "sph.wall_model = \"penalty\""});
    }
    for (std::size_t k = 0; k < e.spheres.size(); ++k) {
      if (scene_.particle_sets[k].kind != ParticleSet::Kind::fill) continue;
      shares.push_back({e.spheres[k] * kBytesPerSphere,
                        fmt::format("{:.3g} spheres of {:g} B in particles[{}]", e.spheres[k], kBytesPerSphere, k),
                        fmt::format("particles[{}].fill.count", k), "lower the count"});
    }
    for (std::size_t k = 0; k < scene_.structures.size(); ++k) {
      const Structure& s = scene_.structures[k];
      const bool mesh = s.shape.type == Shape::Type::mesh;
      shares.push_back({e.structure_bytes[k],
                        s.rigid ? fmt::format("{:.3g} surface triangles in structures[{}]", e.surface_triangles[k], k)
                                : fmt::format("{:.3g} elements in structures[{}]", e.elements[k], k),
                        fmt::format("structures[{}].{}", k, mesh ? "file" : "element_size"),
                        mesh ? std::string("give a coarser mesh") : std::string("raise element_size")});
    }
    std::vector<std::string> parts;
    for (const Share& share : shares) parts.push_back(share.what);
    const auto largest = std::max_element(shares.begin(), shares.end(),
                                          [](const Share& a, const Share& b) { return a.bytes < b.bytes; });
    const std::string key = largest != shares.end() ? largest->key : std::string("run");
    diag_.add(line_of_key(key), key, value_of_key(key),
              fmt::format("the scene needs about {:.3g} GiB of memory ({}), more than this machine's {:.3g} GiB",
                          e.memory_bytes / kGiB, join(parts), memory / kGiB),
              largest != shares.end() ? largest->fix : std::string("make the scene smaller"));
  }

  static constexpr double kGiB = 1024.0 * 1024.0 * 1024.0;

  Diagnostics diag_;
  const toml::table& document_;
  fs::path scene_dir_;
  Scene scene_;
  bool has_particles_ = false, has_structures_ = false, has_fluids_ = false;
  std::map<std::string, FluidMaterialKeys> fluid_material_keys_;
  int domain_line_ = 0;
  int periodic_line_[2] = {0, 0};
  std::vector<std::string> material_names_;
  std::map<std::string, BodyName> bodies_;
  std::vector<ConstraintKeys> constraint_keys_;  // of the structure being read
  std::vector<ListedSphere> listed_;
  Where sph_dem_default_where_{0, "contact.sph_dem"};
  std::map<std::pair<std::string, std::string>, Where> sph_dem_where_;  // (fluid, set) -> its interaction
};

// "FILE:LINE:COL: key 'k' = v: TOML syntax error: ..." from toml++'s error.
std::string syntax_message(const std::string& file, const std::string& text, const toml::parse_error& error) {
  const auto line = error.source().begin.line, column = error.source().begin.column;
  std::string line_text;
  {
    std::istringstream stream(text);
    for (std::size_t k = 0; k < line && std::getline(stream, line_text); ++k) {
    }
  }
  const auto trim = [](std::string s) {
    const auto first = s.find_first_not_of(" \t\r");
    const auto last = s.find_last_not_of(" \t\r");
    return first == std::string::npos ? std::string() : s.substr(first, last - first + 1);
  };
  std::string where;
  const auto equals = line_text.find('=');
  const std::string trimmed = trim(line_text);
  if (equals != std::string::npos && !trimmed.starts_with('[') && !trimmed.starts_with('#')) {
    where = fmt::format(" key '{}' = {}:", trim(line_text.substr(0, equals)), trim(line_text.substr(equals + 1)));
  } else if (!trimmed.empty()) {
    where = fmt::format(" the line reads '{}':", trimmed);
  }
  return fmt::format(
      "{}:{}:{}:{} TOML syntax error: {}. Fix: correct the TOML at line {}, column {} (strings in \"quotes\", "
      "arrays in [ ], inline tables {{ ... }} on one line; see https://toml.io).",
      file, line, column, where, error.description(), line, column);
}

// Where `text` stops being UTF-8 text: a NUL byte (TOML allows none), a UTF-16 or UTF-32 file, or a byte
// sequence that is not UTF-8; the byte offset and what is there. toml++ would read on and report the key
// before it with no reason.
struct NotText {
  enum class Kind { nul, utf16, other };
  std::size_t offset;
  std::string what;
  Kind kind = Kind::other;
};
std::optional<NotText> not_utf8_text(std::string_view text) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[k]); };
  if (text.size() >= 2 && ((byte(0) == 0xFF && byte(1) == 0xFE) || (byte(0) == 0xFE && byte(1) == 0xFF))) {
    return NotText{0, fmt::format("the UTF-16 byte-order mark {:02X} {:02X}", byte(0), byte(1)), NotText::Kind::utf16};
  }
  for (std::size_t k = 0; k < text.size();) {
    const unsigned char c = byte(k);
    if (c == 0) {
      // UTF-16 text of ASCII characters has a NUL in every other byte.
      std::size_t nul[2] = {0, 0};
      const std::size_t head = std::min<std::size_t>(text.size(), 256);
      for (std::size_t i = 0; i < head; ++i) nul[i % 2] += byte(i) == 0 ? 1 : 0;
      const bool utf16 = std::max(nul[0], nul[1]) * 4 >= head && std::min(nul[0], nul[1]) == 0;
      return utf16 ? NotText{k, "a NUL byte (0x00), and every other byte is one: the file looks like UTF-16",
                             NotText::Kind::utf16}
                   : NotText{k, "a NUL byte (0x00)", NotText::Kind::nul};
    }
    std::size_t length = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    bool valid = length > 0 && k + length <= text.size();
    for (std::size_t i = 1; valid && i < length; ++i) valid = (byte(k + i) & 0xC0) == 0x80;
    if (valid && length == 2) valid = c >= 0xC2;  // overlong
    if (valid && length == 3) {
      const unsigned next = byte(k + 1);
      valid = !(c == 0xE0 && next < 0xA0) && !(c == 0xED && next >= 0xA0);  // overlong, surrogates
    }
    if (valid && length == 4) {
      const unsigned next = byte(k + 1);
      valid = c <= 0xF4 && !(c == 0xF0 && next < 0x90) && !(c == 0xF4 && next >= 0x90);
    }
    if (!valid) return NotText{k, fmt::format("the byte 0x{:02X}, which does not start a UTF-8 character", c)};
    k += length;
  }
  return std::nullopt;
}

}  // namespace

Scene load_scene(const std::filesystem::path& file) {
  std::error_code ec;
  if (fs::is_directory(file, ec)) {
    throw FileError(
        fmt::format("{}: is a folder, not a scene file. Fix: give the path of a .toml file.", file.string()));
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    throw FileError(
        fmt::format("{}: cannot open the scene file ({}). Fix: check the path.", file.string(), std::strerror(errno)));
  }
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (const auto problem = not_utf8_text(text)) {
    const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(problem->offset), '\n');
    const std::string name = file.filename().string();
    std::string fix;
    switch (problem->kind) {
      case NotText::Kind::utf16:
        fix = fmt::format("save the scene as UTF-8 text (e.g. iconv -f UTF-16 -t UTF-8 {} > scene.toml)", name);
        break;
      case NotText::Kind::nul:
        fix = fmt::format(
            "remove the NUL byte (most editors do not show it; tr -d '\\000' < {} > scene.toml removes "
            "every one)",
            name);
        break;
      case NotText::Kind::other:
        fix = fmt::format(
            "save the scene as UTF-8 text (a file in another encoding, e.g. Latin-1: iconv -f LATIN1 "
            "-t UTF-8 {} > scene.toml)",
            name);
        break;
    }
    throw SceneError(fmt::format("{}:{}: the file is not UTF-8 text: at byte offset {} there is {}. Fix: {}.",
                                 file.string(), line, problem->offset, problem->what, fix));
  }
  toml::table document;
  try {
    document = toml::parse(std::string_view(text), file.string());
  } catch (const toml::parse_error& error) {
    throw SceneError(syntax_message(file.string(), text, error));
  }
  return Builder(file, document).build();
}

}  // namespace sabo::scene
