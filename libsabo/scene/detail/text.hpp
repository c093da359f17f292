#pragma once
// The scene loader's text helpers: values as TOML-like text for messages, names, endpoints.
// Private to libsabo/scene (the loader's sections); not installed, not for solvers.
#include <toml++/toml.h>

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "libsabo/scene/schema.hpp"

namespace sabo::scene::detail {

namespace fs = std::filesystem;
using schema::Key;
using schema::Table;
using schema::Type;

std::string number_literal(double value);
std::string quote_text(std::string_view text);
// `text` with its control characters written as \uXXXX: one line of a message, whatever a file held.
std::string printable_text(std::string_view text);
// A node as TOML-like text for messages, shortened to about `limit` characters.
std::string value_text(const toml::node& node, std::size_t limit = 80);
std::string_view kind_of(const toml::node& node);
std::string_view expected_kind(Type type);
std::string join(const std::vector<std::string>& words, std::string_view separator = ", ");
std::string noun(std::string_view key_name);
std::string unit_suffix(const Key& key);
int line_of(const toml::node& node);
bool valid_name(std::string_view name);
bool valid_endpoint(std::string_view endpoint);
// A host written as digits and dots is an IPv4 address, four numbers 0 to 255 (tcp://999.1.1.1:5555 used to
// reach the coupler, which could not bind it: "No such device"). The problem, if any.
std::optional<std::string> ipv4_problem(std::string_view endpoint);
bool is_executable_file(const fs::path& path);

}  // namespace sabo::scene::detail
