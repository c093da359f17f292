#include "libsabo/scene/detail/text.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>

namespace sabo::scene::detail {

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

std::string printable_text(std::string_view text) {
  std::string out;
  for (char c : text) {
    if (static_cast<unsigned char>(c) < 0x20) {
      out += fmt::format("\\u{:04x}", static_cast<int>(c));
    } else {
      out += c;
    }
  }
  return out;
}

std::string value_text(const toml::node& node, std::size_t limit) {
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
    text += '[';  // text is empty; += sidesteps GCC 12's false -Wrestrict on = "["
    for (std::size_t k = 0; k < array->size() && text.size() <= limit; ++k) {
      text += (k ? ", " : "") + value_text(*array->get(k), limit);
    }
    text += "]";
  } else if (const auto* table = node.as_table()) {
    text += '{';
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

std::string join(const std::vector<std::string>& words, std::string_view separator) {
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
  if (endpoint == "ipc" || endpoint == "tcp") return true;
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
  if (port == "*") return true;
  if (port.empty() || port.size() > 5 ||
      !std::all_of(port.begin(), port.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); })) {
    return false;
  }
  const int number = std::stoi(std::string(port));
  return number >= 1 && number <= 65535;
}

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

}  // namespace sabo::scene::detail
