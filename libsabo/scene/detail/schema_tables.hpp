#pragma once
// The tables of the scene schema, built once (schema.cpp); each section's table is built beside
// the code that reads it (sections/*.cpp).
#include <fmt/format.h>

#include <string>
#include <utility>
#include <vector>

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
  K& def(std::string literal) {
    key_.default_value = std::move(literal);
    return *this;
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
  Key key_;
};

// All tables, built once in place (tables point at each other).
class Schema {
 public:
  Table root, run, solvers, solver, materials, material, particles, sphere, fill, structure, constraint, constraint_box,
      sph, fluid, contact, dem_dem, dem_pair, dem_fem, sph_fem, sph_dem, fem_fem, interaction, recording, gauge, sensor;

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
  void build_sph_fem();
  void build_sph_dem();
  void build_contact();
  void build_fem_fem();
  void build_interactions();
  void build_recording();
  void build_gauges();
  void build_sensors();
};

}  // namespace sabo::scene::schema::detail
