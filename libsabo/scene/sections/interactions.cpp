// [[interactions]]: contact settings per pair of bodies: the schema of the section and its reader.

#include "libsabo/scene/detail/builder.hpp"
#include "libsabo/scene/detail/schema_tables.hpp"

namespace sabo::scene::schema::detail {

void Schema::build_interactions() {
  interaction.title = "[[interactions]]";
  interaction.anchor = "interactions";
  interaction.description =
      "Contact settings of one pair, each pair at most once, its two bodies in either order: a particle set "
      "or a fluid body with a structure, a fluid body with a particle set, or two structures (not both rigid; "
      "naming them puts them in contact). Keys left out take their value from `[contact.dem_fem]` (a particle "
      "set and a structure), `[contact.sph_fem]` (a fluid and a structure), `[contact.sph_dem]` (a fluid and "
      "a particle set) or `[contact.fem_fem]` (two structures: the penalty keys, `friction` and the damping "
      "ratios only).";
  const std::string from_default =
      "as in `[contact.dem_fem]` / `[contact.sph_fem]` / `[contact.sph_dem]` / `[contact.fem_fem]`";
  interaction.keys = {
      K("pair", Type::string_list)
          .required("[\"boulders\", \"chute\"]")
          .allowed("a particle set or fluid body and a structure, a fluid body and a particle set, or two "
                   "structures")
          .doc("The two bodies."),
      K("enabled", Type::boolean)
          .def(SurfaceContact{}.enabled)
          .doc("`false` switches contact of this pair off (two structures: also when `[contact.fem_fem]` "
               "enables every pair)."),
      K("model", Type::string)
          .absent(from_default)
          .example("\"hertz_mindlin\"")
          .choices({"penalty", "hertz_mindlin", "boundary_particles"})
          .doc("Contact law: `penalty` or `hertz_mindlin` for a particle set and a structure (a fluid and a "
               "structure: penalty only); `boundary_particles` or `penalty` for a fluid and a particle set."),
      K("restitution", Type::number)
          .absent(from_default)
          .example("0.5")
          .gt(0)
          .le(1)
          .doc("Coefficient of restitution (particle sets only; refused unless the pair's law is hertz_mindlin)."),
      K("friction", Type::number).absent(from_default).example("0.4").ge(0).doc("Coulomb friction coefficient."),
      K("penalty_scale", Type::number)
          .absent(from_default)
          .example("0.1")
          .gt(0)
          .doc("k1 of eq. 6 (not for a fluid and a particle set)."),
      K("normal_stiffness", Type::number)
          .absent(from_default)
          .example("1e8")
          .unit("N/m")
          .gt(0)
          .doc("Normal stiffness replacing eq. 6."),
      K("normal_damping_ratio", Type::number)
          .absent(from_default)
          .example("0.2")
          .ge(0)
          .lt(1)
          .doc("Normal damping ratio."),
      K("tangential_damping_ratio", Type::number)
          .absent(from_default)
          .example("0.0")
          .ge(0)
          .lt(1)
          .doc("Tangential damping ratio (not for a fluid and a particle set)."),
      K("rolling", Type::string)
          .absent(from_default)
          .example("\"viscous\"")
          .choices_of<RollingModel>()
          .doc("Rolling resistance model (a particle set and a structure)."),
      K("rolling_friction", Type::number)
          .absent(from_default)
          .example("0.1")
          .ge(0)
          .doc("Constant rolling resistance coefficient (a particle set and a structure)."),
      K("rolling_viscosity", Type::number)
          .absent(from_default)
          .example("0.05")
          .unit("s/m")
          .ge(0)
          .doc("Viscous rolling resistance coefficient (a particle set and a structure)."),
  };
}

}  // namespace sabo::scene::schema::detail

namespace sabo::scene::detail {

const Structure* Builder::structure_named(const std::string& name) const {
  for (const auto& s : scene_.structures) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

// An interaction of two structures (FEM-FEM contact in the fem_solver): the penalty keys of
// [contact.fem_fem]; the pair is in contact unless it says enabled = false.
void Builder::read_fem_fem_interaction(Reader& r, FemFemInteraction& interaction) {
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

void Builder::read_interactions(Reader& root) {
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
    const bool fluid_and_set = (is_fluid(bodies[0]) && is_set(bodies[1])) || (is_set(bodies[0]) && is_fluid(bodies[1]));
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
      for (const char* key : {"restitution", "penalty_scale", "tangential_damping_ratio", "rolling", "rolling_friction",
                              "rolling_viscosity"}) {
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

}  // namespace sabo::scene::detail
