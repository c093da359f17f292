#include "libsabo/scene/detail/reader.hpp"

#include <fmt/format.h>

#include <cassert>
#include <cmath>
#include <map>

#include "libsabo/scene/suggest.hpp"

namespace sabo::scene::detail {

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

Reader::Reader(Diagnostics& diagnostics, const Table& spec, const toml::table& table, std::string path)
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
void Reader::select(const std::string& variant) {
  variant_ = variant;
  for (const Key& key : spec_.keys) {
    if (key.only_for.empty() || applies(key)) continue;
    if (const toml::node* node = table_.get(key.name)) {
      diag_.add(line_of(*node), key_path(key.name), value_text(*node),
                fmt::format("belongs to {} = {}, not to {} = {}", spec_.selector, join(quote_all(key.only_for), " or "),
                            spec_.selector, quote_text(variant)),
                fmt::format("remove it, or change {}", spec_.selector));
    }
  }
}

int Reader::line(std::string_view name) const {
  const toml::node* n = table_.get(name);
  return n != nullptr ? line_of(*n) : line();
}

std::optional<double> Reader::number(std::string_view name) {
  auto found = lookup(name, Type::number);
  if (!found) return std::nullopt;
  const auto value = as_number(*found->node);
  if (!value) return type_error(*found);
  return checked_number(*found, *value);
}

std::optional<std::int64_t> Reader::integer(std::string_view name) {
  auto found = lookup(name, Type::integer);
  if (!found) return std::nullopt;
  const auto* node = found->node->as_integer();
  if (node == nullptr) return type_error(*found);
  if (!checked_number(*found, static_cast<double>(node->get()))) return std::nullopt;
  return node->get();
}

std::optional<bool> Reader::boolean(std::string_view name) {
  auto found = lookup(name, Type::boolean);
  if (!found) return std::nullopt;
  const auto* node = found->node->as_boolean();
  if (node == nullptr) return type_error(*found);
  return node->get();
}

std::optional<std::string> Reader::string(std::string_view name) {
  auto found = lookup(name, Type::string);
  if (!found) return std::nullopt;
  const auto* node = found->node->as_string();
  if (node == nullptr) return type_error(*found);
  const std::string& value = node->get();
  if (!found->key->choices.empty() && !check_choice(*found, value, *found->node)) return std::nullopt;
  return value;
}

std::optional<Vec3> Reader::vec3(std::string_view name) {
  auto found = lookup(name, Type::vec3);
  if (!found) return std::nullopt;
  const auto values = numbers(*found->node, 3);
  if (!values) return type_error(*found);
  if (!all_finite(*found, *values)) return std::nullopt;
  return Vec3((*values)[0], (*values)[1], (*values)[2]);
}

std::optional<std::array<double, 2>> Reader::pair(std::string_view name) {
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
std::optional<std::vector<std::array<double, 2>>> Reader::pairs(std::string_view name) {
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

std::optional<std::vector<std::string>> Reader::strings(std::string_view name) {
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
const toml::table* Reader::table(std::string_view name) {
  auto found = lookup(name, Type::table);
  if (!found) return nullptr;
  const auto* value = found->node->as_table();
  if (value == nullptr) type_error(*found);
  return value;
}

// An array of tables; nullptr when absent or wrong (reported).
const toml::array* Reader::table_list(std::string_view name) {
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
std::vector<std::pair<std::string, const toml::table*>> Reader::named_tables(std::string_view name) {
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

std::vector<std::string> Reader::quote_all(const std::vector<std::string>& words) {
  std::vector<std::string> out;
  for (const auto& word : words) out.push_back(quote_text(word));
  return out;
}

std::optional<Reader::Found> Reader::lookup(std::string_view name, Type type) {
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

std::optional<double> Reader::as_number(const toml::node& node) {
  if (const auto* f = node.as_floating_point()) return f->get();
  if (const auto* i = node.as_integer()) return static_cast<double>(i->get());
  return std::nullopt;
}

std::optional<std::vector<double>> Reader::numbers(const toml::node& node, std::size_t size) {
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

std::nullopt_t Reader::type_error(const Found& found) {
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

bool Reader::all_finite(const Found& found, const std::vector<double>& values) {
  if (std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); })) return true;
  report(found, "every element must be a finite number", "replace nan and inf by finite numbers");
  return false;
}

std::optional<double> Reader::checked_number(const Found& found, double value) {
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

bool Reader::check_choice(const Found& found, const std::string& value, const toml::node& value_node) {
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

const Table& spec(std::string_view anchor) {
  for (const Table* table : schema::tables()) {
    if (table->anchor == anchor) return *table;
  }
  assert(false && "unknown schema table");
  return schema::root();
}

}  // namespace sabo::scene::detail
