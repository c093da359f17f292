#include "libsabo/scene/schema.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "libsabo/scene/detail/schema_tables.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::scene::schema::detail {

Schema::Schema() {
  build_root();
  build_run();
  build_solvers();
  build_materials();
  build_particles();
  build_structures();
  build_sph();
  build_inflows();
  build_contact();
  build_sph_fem();
  build_sph_dem();
  build_fem_fem();
  build_interactions();
  build_recording();
  build_gauges();
  build_fronts();
  build_sensors();
}

std::vector<const Table*> Schema::ordered() const {
  return {&root,    &run,         &solvers,   &solver,     &materials,      &material,      &particles,
          &sphere,  &fill,        &structure, &constraint, &constraint_box, &sph,           &fluid,
          &inflow,  &contact,     &dem_dem,   &dem_pair,   &dem_fem,        &sph_fem,       &sph_dem,
          &fem_fem, &interaction, &recording, &gauge,      &front,          &front_station, &sensor};
}

void Schema::build_root() {
  root.title = "Top level";
  root.anchor = "top-level";
  root.description =
      "The tables a scene file may hold. Only `format_version`, `[run]` and at least one body "
      "(`[[fluids]]`, `[[particles]]` or `[[structures]]`) are required; `[sph]` is required with fluids.";
  root.keys = {
      K("format_version", Type::integer)
          .required("1")
          .allowed("1")
          .doc("Version of this file format. This build reads version 1."),
      K("run", Type::table).required("{ end_time = 10.0, output_interval = 0.1 }").inside(run).doc("Run control."),
      K("solvers", Type::table)
          .absent("built executables, default settings")
          .inside(solvers)
          .doc("Per-role solver settings."),
      K("materials", Type::named_tables).inside(material).absent("no materials").doc("Named materials."),
      K("particles", Type::table_list).inside(particles).absent("no DEM bodies").doc("DEM sphere sets."),
      K("structures", Type::table_list).inside(structure).absent("no FEM bodies").doc("FEM parts."),
      K("sph", Type::table)
          .inside(sph)
          .absent("no fluids allowed")
          .doc("Settings of the SPH solver; required with `[[fluids]]`."),
      K("fluids", Type::table_list).inside(fluid).absent("no SPH bodies").doc("SPH bodies (debris slurry, water)."),
      K("inflows", Type::table_list)
          .inside(inflow)
          .absent("no inflows")
          .doc("Fluid bodies that enter through a cross-section at the rate of a discharge hydrograph."),
      K("contact", Type::table).inside(contact).absent("defaults").doc("Contact laws between kinds of bodies."),
      K("interactions", Type::table_list)
          .inside(interaction)
          .absent(
              "every pair uses `[contact.dem_fem]`, `[contact.sph_fem]`, `[contact.sph_dem]` or `[contact.fem_fem]`")
          .doc("Per-pair contact overrides."),
      K("recording", Type::table).inside(recording).absent("defaults").doc("What the coupler records."),
      K("gauges", Type::table_list)
          .inside(gauge)
          .absent("no gauges")
          .doc("Points and lines where the sph_solver measures pressure, velocity and flow depth (`gauges.csv`)."),
      K("fronts", Type::table_list)
          .inside(front)
          .absent("no fronts")
          .doc("Paths along which the sph_solver tracks the flow's front and the depth at stations "
               "(`fronts.csv`)."),
      K("sensors", Type::table_list)
          .inside(sensor)
          .absent("no sensors")
          .doc("Patches of structures whose force and mean pressure the coupler writes (`sensors.csv`)."),
  };
}

}  // namespace sabo::scene::schema::detail

namespace sabo::scene::schema {
namespace {

using detail::Schema;

const Schema& schema() {
  static const Schema instance;
  return instance;
}

std::string number_text(double v) {
  return fmt::format("{}", v);
}

std::string escape_cell(std::string text) {
  std::string out;
  for (char c : text) {
    if (c == '|')
      out += "\\|";
    else if (c == '\n')
      out += ' ';
    else
      out += c;
  }
  return out;
}

std::string allowed_cell(const Key& key) {
  if (!key.allowed.empty()) return key.allowed;
  if (!key.choices.empty()) {
    std::string text;
    for (const auto& choice : key.choices) {
      if (!text.empty()) text += ", ";
      text += "`\"" + choice + "\"`";
    }
    return key.type == Type::string_list ? "each of " + text : text;
  }
  if (!key.range.unbounded()) return key.range.text();
  return "";
}

// A table's title as markdown text (link text, heading).
std::string title_text(const Table& table) {
  return &table == &schema().root ? table.title : "`" + table.title + "`";
}

std::string default_cell(const Key& key) {
  if (key.required) {
    if (key.only_for.empty()) return "required";
    std::string shapes;
    for (const auto& value : key.only_for) shapes += (shapes.empty() ? "" : ", ") + value;
    return "required (" + shapes + ")";
  }
  if (!key.default_value.empty()) return "`" + key.default_value + "`";
  return key.when_absent.empty() ? "" : "absent: " + key.when_absent;
}

}  // namespace

std::string_view type_name(Type type) {
  switch (type) {
    case Type::boolean: return "boolean";
    case Type::integer: return "integer";
    case Type::number: return "number";
    case Type::string: return "string";
    case Type::vec3: return "[x, y, z]";
    case Type::number_pair: return "[min, max]";
    case Type::pair_list: return "array of [a, b]";
    case Type::string_list: return "array of strings";
    case Type::table: return "table";
    case Type::table_list: return "array of tables";
    case Type::named_tables: return "tables by name";
  }
  return "?";
}

bool Range::contains(double value) const {
  if (min && (min_exclusive ? !(value > *min) : !(value >= *min))) return false;
  if (max && (max_exclusive ? !(value < *max) : !(value <= *max))) return false;
  return true;
}

std::string Range::text() const {
  if (min && max) {
    return fmt::format("{}{}, {}{}", min_exclusive ? "(" : "[", number_text(*min), number_text(*max),
                       max_exclusive ? ")" : "]");
  }
  if (min) return fmt::format("{} {}", min_exclusive ? ">" : ">=", number_text(*min));
  if (max) return fmt::format("{} {}", max_exclusive ? "<" : "<=", number_text(*max));
  return "";
}

const Key* Table::find(std::string_view name) const {
  auto it = std::find_if(keys.begin(), keys.end(), [&](const Key& key) { return key.name == name; });
  return it == keys.end() ? nullptr : &*it;
}

std::vector<std::string> Table::key_names() const {
  std::vector<std::string> names;
  names.reserve(keys.size());
  for (const auto& key : keys) names.push_back(key.name);
  return names;
}

const Table& root() {
  return schema().root;
}

std::vector<const Table*> tables() {
  return schema().ordered();
}

const std::vector<std::string>& cross_checks() {
  static const std::vector<std::string> checks{
      "A scene has at least one body (`[[fluids]]`, `[[particles]]` or `[[structures]]`).",
      "Fluids, particle sets and structures share one namespace: every name is unique among them. Names are made of "
      "letters, digits, `_` and `-`; material names too.",
      "`material` names a `[materials.NAME]` table.",
      "A particle set gives exactly one of `spheres` and `fill`; a list has at least one sphere.",
      "Spheres of lists do not overlap, within a set or across sets (touching is allowed).",
      "A `fill` region is either a box (`min` and `max`, `min` < `max` on every axis) or a polygon (`polygon_xz` "
      "and `y_range`): at least 3 vertices, no two edges crossing, positive area, `y_range` min < max. Every "
      "side of the region's bounding box is at least the largest diameter; `diameter` is `[min, max]` with min "
      "<= max; a normal distribution's mean lies in the clip range; a sieve has at least 2 rows, positive "
      "strictly increasing diameters and fractions non-decreasing from 0 to 1. The expected solid volume is "
      "at most 30 % of the region. Fill regions may overlap each other and listed spheres: the dem_solver "
      "places filled spheres clear of the listed spheres and of earlier sets.",
      "`[[contact.dem_dem.pairs]]`: `materials` names two defined materials; no pair appears twice. "
      "`restitution` is given only where a pair uses `hertz_mindlin`, `rolling_viscosity` only where a pair uses "
      "`rolling = \"viscous\"`, and a viscous pair has `rolling_viscosity` > 0.",
      "`[solvers.ROLE]` appears only for a role that the bodies need (`sph` for fluids, `dem` for particles, "
      "`fem` for structures). `command`, when given, is not empty and its program exists: "
      "an executable file (absolute, or relative to the scene file's folder when it contains a `/`) or a name "
      "found on `PATH`.",
      "`[contact.dem_dem]` needs particles; `[contact.dem_fem]` and `[[interactions]]` need particles and "
      "structures. `[contact.dem_dem]` gives `normal_stiffness` or `normal_stiffness_scale`, not both.",
      "`[contact.sph_dem]` needs fluids and particles. With `boundary_particles` (its `model`, or a fluid and "
      "particle-set interaction's), every sphere of the set has a diameter of at least 2 `particle_spacing`, "
      "and a set that meets one fluid body as boundary particles meets every fluid body so (the sph_solver "
      "sees wall particles whatever body it is near). A penalty `normal_stiffness` gives a pair step 0.2 pi "
      "sqrt(rho0 dx^3 / K) no shorter than the SPH step cfl h / c. A sphere that starts inside a fluid body "
      "pushes the fluid aside (the sph_solver leaves out the particles within dx/2 of it), which needs its "
      "place known before the run: spheres of a fill set that settles (`settle_time`), or of a fill set "
      "after one, may not start inside a fluid body's bounds.",
      "An interaction's `pair` names one particle set or fluid body and one structure, or one fluid body and "
      "one particle set; no pair appears twice. "
      "`restitution` in `[contact.dem_fem]` or a particle set's interaction is given only where that contact uses "
      "`model = \"hertz_mindlin\"` (an interaction's model is its own or, when absent, `[contact.dem_fem]`'s).",
      "`[sph]` is given exactly when there are `[[fluids]]`; `[contact.sph_fem]` needs fluids and structures. "
      "`domain_min` and `domain_max` come together, min < max on every axis, and the domain holds every fluid. "
      "`periodic_x` and `periodic_y` have min < max, a period of at least 4h + dx (h = `smoothing_ratio` * "
      "`particle_spacing`), and hold every fluid body along their axis.",
      "A fluid material: `eos = \"polynomial\"` needs `eos_c1`; `newtonian` and `bingham` need `viscosity` > 0; "
      "`bingham` and `elastic_plastic` need `yield_stress` > 0; `herschel_bulkley` needs `consistency_index` and "
      "takes no `viscosity`; `consistency_index` and `flow_index` need `herschel_bulkley`; `artificial_stress` > 0 "
      "needs `elastic_plastic`. "
      "A fluid body holds at least one particle; a "
      "box has min < max on every axis; a profile has at least 3 points, no zero-length edge, no crossing "
      "edges; `direction` is horizontal and not zero.",
      "Shapes: a plane's `normal` is not zero and its `direction` not along the normal; a chute's and a channel's "
      "`direction` is horizontal and not zero; a channel has exactly one of `profile` and `profile_file`, at least "
      "two points, the distance strictly increasing (a CSV file's errors name its line); a box has `min` < `max` on "
      "every axis; a mesh `file` exists, is a regular "
      "file and ends in `.stl` (`.msh` for `rigid = false`), and it is read by the solvers' own readers "
      "(truncated, malformed, non-finite or degenerate meshes are refused with the mesh file's line). A terrain's "
      "`raster_file` opens in GDAL (its message quoted otherwise), is north-up and at least 2 x 2 cells; it keeps "
      "at most one of `strip` (at least two distinct points, with `strip_width`) and `clip_polygon` (at least "
      "three corners); every node of its surface lies within the raster's cell centres and off its no-data "
      "cells (the point named otherwise), and a polygon holds at least one element. Keys of "
      "other shapes are errors. `rigid = false` needs `shape = \"box\"`, "
      "`shape = \"mesh\"` with a `.msh` file, or `shape = \"plane\"` with a `thickness`; `fixed`, `constraints`, "
      "`velocity`, "
      "`floors`, `roof_thickness` and "
      "`roof_material` need `rigid = false` (the last three a box with a `thickness`). Plasticity keys other than "
      "`yield_stress` and "
      "`failure_strain` need `yield_stress`; `tangent_modulus` is below `youngs_modulus`.",
      "`constraints` (deformable structures only): each gives exactly one of `box` (`min` <= `max` on every "
      "axis) and `tag` (a `mesh` structure's physical group, present in its `.msh` file and not empty), and at "
      "least one of `dofs`; a box must hold a node of the structure (a mesh's nodes are checked here, a "
      "generated mesh's box against the structure's extent here and node by node when the fem_solver builds "
      "it); rotations (`rx`, `ry`, `rz`) only on shells.",
      "Two structures in `[[interactions]]`: not the same structure twice, not both rigid; the keys are those of "
      "`[contact.fem_fem]` (`model` only `\"penalty\"`; no `restitution`, no rolling resistance).",
      "`[recording]`: `first_step` <= `last_step`.",
      "`[[gauges]]` need `[[fluids]]`; gauge names are unique; a line's `end` differs from its `start`; every "
      "point of a gauge lies inside `sph.domain_min`/`domain_max` when a domain is given (without one the fluid "
      "may go anywhere, and a gauge anywhere reads 0 until fluid comes). `[[sensors]]`: names are unique, `part` "
      "names a structure, `min` and `max` come together with min < max on every axis, and the box meets the "
      "part's surface (an empty sensor is refused when the coupler starts, naming the sensor, its box and the "
      "part's extent).",
      "Every number is finite (no `nan`, no `inf`).",
      "The file is UTF-8 text: a NUL byte or a UTF-16 file is refused with its byte offset.",
      "What the scene costs (`libsabo/scene/estimate.hpp`, also in the launch plan's `estimate`): the "
      "particles, elements and surfaces it makes, at about the bytes per entity measured for a whole run, fit "
      "this machine's memory (else the key of the largest share is named, e.g. `sph.particle_spacing` or a "
      "structure's `element_size`); `end_time` over the smallest estimated stable step (SPH `cfl h / c`, DEM "
      "contact, FEM `L / c`, `max_dt`) is at most 1e10 steps; `end_time / output_interval` is at most 1e6 "
      "output times.",
      "Warnings (printed, the run still starts; `libsabo/scene/warnings.hpp`): a structure that nothing can touch "
      "(no particle set, fluid or other structure has contact with it enabled), when it is rigid or the scene has "
      "other bodies (a lone deformable structure under its weight is a valid scene).",
  };
  return checks;
}

std::string_view example_scene() {
  return R"(format_version = 1

[run]
end_time = 4.0
output_interval = 0.1
gravity = [0.0, 0.0, -9.81]

[solvers.dem]
beta = 0.8

[materials.granite]
density = 3000.0
youngs_modulus = 30e9
poisson_ratio = 0.3

[materials.concrete]
density = 3000.0
youngs_modulus = 30e9
poisson_ratio = 0.24

[[particles]]
name = "boulders"
material = "granite"
fill = { min = [1.0, -1.5, 0.5], max = [6.0, 1.5, 3.5], count = 20, diameter = [0.5, 1.0], seed = 7 }

[[particles]]
name = "marker"
material = "granite"
spheres = [ { center = [8.0, 0.0, 1.0], radius = 0.4, velocity = [1.0, 0.0, 0.0] } ]

[[structures]]
name = "chute"
material = "concrete"
shape = "chute"
origin = [0.0, 0.0, 0.0]
direction = [1.0, 0.0, 0.0]
length = 15.0
width = 4.0
slope_deg = 20.0
wall_height = 2.0
end_wall_height = 2.0
element_size = 1.0

[contact.dem_dem]
friction = 1.0
rolling_friction = 0.1

[contact.dem_fem]
friction = 0.3
normal_damping_ratio = 0.2

[[interactions]]
pair = ["marker", "chute"]
friction = 0.4

[recording]
fields = ["position", "force"]
every = 10
)";
}

std::string markdown() {
  std::string out;
  out +=
      "# Scene file reference\n\n"
      "<!-- Generated by `sabo_scene schema-doc` from the schema tables in libsabo/scene/sections/. Do not edit by "
      "hand: a test checks that this file equals the generated text. -->\n\n"
      "A scene is one TOML file (`configs/*.toml`) that says everything a run simulates: materials, bodies "
      "(fluids, particle sets, structures), how they touch, and what is recorded. What the scene does not mention is "
      "not simulated: a scene without `[[particles]]` starts no `dem_solver`. Units are SI (m, s, kg, Pa), "
      "angles in degrees, z points up.\n\n"
      "`sabo_scene check SCENE` validates a file and prints the launch plan (the processes to start, as JSON). "
      "Every value is checked when the scene is loaded. Each error names the file, the line, the key and the "
      "value, and says how to fix it; all errors of a file are reported together, and nothing starts. Keys "
      "are written as paths: `run.end_time`, `materials.granite.density`, `particles[0].spheres[3].radius` "
      "(arrays count from 0). Unknown keys are errors, with the nearest allowed key as a suggestion.\n\n"
      "Numbers may be written as integers or floats (`3000` or `3000.0`); integers must be integers.\n\n";

  out += "## Contents\n\n";
  for (const Table* table : tables()) {
    out += fmt::format("* [{}](#{})\n", title_text(*table), table->anchor);
  }
  out += "* [Checks across keys](#checks-across-keys)\n* [Example](#example)\n\n";

  for (const Table* table : tables()) {
    out += fmt::format("<a id=\"{}\"></a>\n\n## {}\n\n{}\n\n", table->anchor, title_text(*table), table->description);
    if (table->keys.empty()) continue;
    out += "| key | type | default | unit | allowed | description |\n";
    out += "|---|---|---|---|---|---|\n";
    for (const Key& key : table->keys) {
      std::string description = key.description;
      if (!key.only_for.empty() && !key.required) {
        std::string shapes;
        for (const auto& value : key.only_for) shapes += (shapes.empty() ? "" : ", ") + value;
        description = "(" + shapes + ") " + description;
      }
      if (key.table != nullptr)
        description += fmt::format(" See [{}](#{}).", title_text(*key.table), key.table->anchor);
      out += fmt::format("| `{}` | {} | {} | {} | {} | {} |\n", key.name, escape_cell(std::string(type_name(key.type))),
                         escape_cell(default_cell(key)), escape_cell(key.unit), escape_cell(allowed_cell(key)),
                         escape_cell(description));
    }
    out += "\n";
  }

  out += "<a id=\"checks-across-keys\"></a>\n\n## Checks across keys\n\n";
  for (const auto& check : cross_checks()) out += "* " + check + "\n";
  out += "\n<a id=\"example\"></a>\n\n## Example\n\n```toml\n";
  out += example_scene();
  out += "```\n";
  return out;
}

}  // namespace sabo::scene::schema
