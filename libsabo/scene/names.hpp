#pragma once
// The scene file's name of each value of the scene model's enums, in the order of the enum's
// values: one home for them. The schema lists them as the key's choices and renders the default
// from scene.hpp's initialiser; the loader maps a name to its value; outputs (summary.json) print
// them.
#include <array>
#include <cassert>
#include <cstddef>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "libsabo/scene/scene.hpp"

namespace sabo::scene {

// names(E{}) is found by argument-dependent lookup for every enum below.
constexpr std::array<std::string_view, 2> names(Material::Eos) {
  return {"tait", "polynomial"};
}
constexpr std::array<std::string_view, 5> names(Material::Rheology) {
  return {"inviscid", "newtonian", "bingham", "herschel_bulkley", "elastic_plastic"};
}
constexpr std::array<std::string_view, 2> names(Material::FailureMeasure) {
  return {"principal_strain", "plastic_strain"};
}
constexpr std::array<std::string_view, 3> names(SizeDistribution) {
  return {"uniform", "normal", "sieve"};
}
constexpr std::array<std::string_view, 2> names(DemLaw) {
  return {"linear", "hertz_mindlin"};
}
constexpr std::array<std::string_view, 2> names(RollingModel) {
  return {"constant", "viscous"};
}
constexpr std::array<std::string_view, 3> names(Structure::ElementFormulation) {
  return {"one_point", "fully_integrated", "enhanced_strain"};
}
constexpr std::array<std::string_view, 2> names(SurfaceContact::Model) {
  return {"penalty", "hertz_mindlin"};
}
constexpr std::array<std::string_view, 2> names(SphDemContact::Model) {
  return {"boundary_particles", "penalty"};
}
constexpr std::array<std::string_view, 2> names(SphSettings::Kernel) {
  return {"wendland_c2", "cubic_spline"};
}
constexpr std::array<std::string_view, 2> names(SphSettings::WallModel) {
  return {"penalty", "boundary_particles"};
}
constexpr std::array<std::string_view, 3> names(SphSettings::WallWork) {
  return {"bounded", "stored", "unstored"};
}
constexpr std::array<std::string_view, 3> names(SphSettings::DensityDiffusion) {
  return {"none", "molteni", "fourtakas"};
}
constexpr std::array<std::string_view, 2> names(SphSettings::ViscousOperator) {
  return {"strain_rate", "morris"};
}
constexpr std::array<std::string_view, 2> names(RunSettings::TcpSecurity) {
  return {"curve", "none"};
}

template <class Enum>
concept NamedEnum = std::is_enum_v<Enum> && requires(Enum value) {
  names(value);
};

template <NamedEnum Enum>
[[nodiscard]] constexpr std::string_view name_of(Enum value) {
  constexpr auto all = names(Enum{});
  const auto index = static_cast<std::size_t>(value);
  assert(index < all.size());
  return all[index];
}

// The value a scene name stands for; the name is one of names(Enum{}) (the schema's choices
// checked it).
template <NamedEnum Enum>
[[nodiscard]] constexpr Enum value_named(std::string_view name) {
  constexpr auto all = names(Enum{});
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (all[i] == name) return static_cast<Enum>(i);
  }
  assert(false && "a name the schema's choices allow");
  return Enum{};
}

template <NamedEnum Enum>
[[nodiscard]] std::vector<std::string> choice_names() {
  constexpr auto all = names(Enum{});
  return {all.begin(), all.end()};
}

}  // namespace sabo::scene
