#pragma once
// The tables of the scene schema, built once (schema.cpp); each section's table is built beside
// the code that reads it (sections/*.cpp).
#include <fmt/format.h>

#include <cassert>
#include <concepts>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "libsabo/scene/names.hpp"
#include "libsabo/scene/scene.hpp"
#include "libsabo/scene/schema.hpp"

namespace sabo::scene::schema::detail {

// Fluent construction of one Key, so that the tables below read like the docs.
class K {
 public:
  K(std::string name, Type type) {
    key_.name = std::move(name);
    key_.type = type;
  }
  K& required(std::string example) {
    key_.required = true;
    key_.example = std::move(example);
    return *this;
  }
  // The default a key takes when absent, rendered as a TOML literal from the initialiser of the
  // scene model's member (scene.hpp), the one place a default is written: pass that member.
  K& def(double value) { return literal(number_literal(value)); }
  template <std::integral Integer>
  requires(!std::same_as<Integer, bool>) K& def(Integer value) { return literal(std::to_string(value)); }
  K& def(bool value) { return literal(value ? "true" : "false"); }
  K& def(const Vec3& value) {
    return literal(
        fmt::format("[{}, {}, {}]", number_literal(value.x()), number_literal(value.y()), number_literal(value.z())));
  }
  K& def(const std::array<double, 2>& pair) {
    return literal(fmt::format("[{}, {}]", number_literal(pair[0]), number_literal(pair[1])));
  }
  K& def(std::string_view text) {
    assert(text.find_first_of("\"\\") == std::string_view::npos && "a plain TOML basic string");
    return literal(fmt::format("\"{}\"", text));
  }
  K& def(const char* text) { return def(std::string_view(text)); }
  K& def(const std::vector<std::string>& words) {
    std::string text = "[";
    for (const std::string& word : words) text += (text.size() > 1 ? ", \"" : "\"") + word + "\"";
    return literal(text + "]");
  }
  // An enum's default also gives the key its choices (names.hpp).
  template <NamedEnum Enum>
  K& def(Enum value) {
    choices_of<Enum>();
    return def(name_of(value));
  }
  template <NamedEnum Enum>
  K& choices_of() {
    return choices(choice_names<Enum>());
  }
  K& absent(std::string meaning) {
    key_.when_absent = std::move(meaning);
    return *this;
  }
  K& example(std::string literal) {
    key_.example = std::move(literal);
    return *this;
  }
  K& unit(std::string unit) {
    key_.unit = std::move(unit);
    return *this;
  }
  K& gt(double v) { return lower(v, true); }
  K& ge(double v) { return lower(v, false); }
  K& lt(double v) { return upper(v, true); }
  K& le(double v) { return upper(v, false); }
  K& choices(std::vector<std::string> values) {
    key_.choices = std::move(values);
    return *this;
  }
  K& allowed(std::string text) {
    key_.allowed = std::move(text);
    return *this;
  }
  K& only_for(std::vector<std::string> selector_values) {
    key_.only_for = std::move(selector_values);
    return *this;
  }
  K& inside(const Table& table) {
    key_.table = &table;
    return *this;
  }
  K& doc(std::string description) {
    key_.description = std::move(description);
    return *this;
  }
  operator Key() const { return key_; }  // NOLINT(google-explicit-constructor): builder

 private:
  K& lower(double v, bool exclusive) {
    key_.range.min = v;
    key_.range.min_exclusive = exclusive;
    return *this;
  }
  K& upper(double v, bool exclusive) {
    key_.range.max = v;
    key_.range.max_exclusive = exclusive;
    return *this;
  }
  K& literal(std::string text) {
    key_.default_value = std::move(text);
    return *this;
  }
  // Shortest text that reads back as the same double, with a decimal point (TOML float).
  static std::string number_literal(double value) {
    std::string text = fmt::format("{}", value);
    if (text.find_first_not_of("-0123456789") == std::string::npos) text += ".0";
    return text;
  }
  Key key_;
};

// All tables, built once in place (tables point at each other).
class Schema {
 public:
  Table root, run, solvers, solver, materials, material, particles, sphere, fill, structure, constraint, constraint_box,
      sph, fluid, inflow, contact, dem_dem, dem_pair, dem_fem, sph_fem, sph_dem, fem_fem, interaction, recording, gauge, front,
      front_station, sensor;

  Schema(const Schema&) = delete;
  Schema& operator=(const Schema&) = delete;
  Schema();
  [[nodiscard]] std::vector<const Table*> ordered() const;

 private:
  void build_root();
  void build_run();
  void build_solvers();
  void build_materials();
  void add_plasticity_keys();
  void build_particles();
  void build_structures();
  void build_sph();
  void build_inflows();
  void build_sph_fem();
  void build_sph_dem();
  void build_contact();
  void build_fem_fem();
  void build_interactions();
  void build_recording();
  void build_gauges();
  void build_fronts();
  void build_sensors();
};

}  // namespace sabo::scene::schema::detail
