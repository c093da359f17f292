// [[particles]]: listed spheres and fills: the schema of the section and its reader.

#include "libsabo/scene/detail/builder.hpp"
#include "libsabo/scene/detail/schema_tables.hpp"

namespace sabo::scene::schema::detail {

void Schema::build_particles() {
  particles.title = "[[particles]]";
  particles.anchor = "particles";
  particles.description =
      "A set of DEM spheres (boulders), simulated by the dem_solver. Give exactly one of `spheres` (an "
      "explicit list) or `fill` (a box filled with random non-overlapping spheres).";
  particles.keys = {
      K("name", Type::string)
          .required("\"boulders\"")
          .allowed("letters, digits, `_`, `-`")
          .doc("Name of the set, unique among particle sets and structures."),
      K("material", Type::string).required("\"granite\"").allowed("a `[materials.NAME]`").doc("Material."),
      K("spheres", Type::table_list)
          .inside(sphere)
          .absent("use `fill`")
          .example("[ { center = [0.0, 0.0, 5.0], radius = 0.5 } ]")
          .doc("Explicit list of spheres (inline tables, see below)."),
      K("fill", Type::table)
          .inside(fill)
          .absent("use `spheres`")
          .example("{ min = [0.0, 0.0, 0.0], max = [4.0, 4.0, 4.0], count = 10, diameter = [0.5, 1.0] }")
          .doc("Random filling of a box (inline table, see below)."),
      K("fixed", Type::boolean)
          .def(ParticleSet{}.fixed)
          .doc("The set's spheres never move (a glued bed of beads, a rough bed): they take any force, and "
               "their contacts with other spheres, structures and the fluid are computed as for the others."),
  };
  sphere.title = "[[particles]] spheres = [ { ... } ]";
  sphere.anchor = "particles-spheres";
  sphere.description = "One sphere of an explicit list. Spheres of all lists must not overlap (touching is allowed).";
  sphere.keys = {
      K("center", Type::vec3).required("[0.0, 0.0, 5.0]").unit("m").doc("Centre."),
      K("radius", Type::number).required("0.5").unit("m").gt(0).doc("Radius."),
      K("velocity", Type::vec3).def(Sphere{}.velocity).unit("m/s").doc("Initial velocity."),
      K("angular_velocity", Type::vec3).def(Sphere{}.angular_velocity).unit("rad/s").doc("Initial angular velocity."),
  };
  fill.title = "[[particles]] fill = { ... }";
  fill.anchor = "particles-fill";
  fill.selector = "distribution";
  fill.description =
      "A region filled with `count` spheres that lie entirely inside it and do not overlap. The region is "
      "the box `[min, max]`, or a polygon in the vertical x-z plane (`polygon_xz`, e.g. a longitudinal "
      "profile) extruded along y over `y_range`. Diameters follow `distribution`:\n\n"
      "* `uniform`: uniform in `diameter = [min, max]`.\n"
      "* `normal`: normal with `mean_diameter` and `std_diameter`, redrawn until inside `diameter = [min, "
      "max]` (the clip range).\n"
      "* `sieve`: a grading curve, rows `[diameter, fraction finer]` as a sieve analysis gives them: "
      "diameters strictly increasing, fractions non-decreasing from 0 (first row) to 1 (last row). The "
      "share between two rows is a class whose diameters are uniform between them; `sieve_basis` says "
      "whether the fractions are of the mass (`\"mass\"`, the usual grading curve) or of the count.\n\n"
      "Positions (and diameters) come from a random generator seeded with `seed`, so the same scene gives "
      "the same spheres; the largest spheres are placed first. Random filling jams when dense: the "
      "expected solid volume (count times the mean sphere volume) must not exceed 30 % of the region. "
      "With `settle_time` > 0 the dem_solver lets the set fall under gravity inside its region (the region's "
      "faces act as frictional walls, the set's own contact law; listed spheres and earlier sets are fixed "
      "obstacles) for that long before step 0, at half the set's stable step; the settled positions, with "
      "velocities set to `velocity` and no spin, start the run "
      "(deterministic: the same bits on any number of threads).";
  const std::vector<std::string> ranged{"uniform", "normal"};
  fill.keys = {
      K("min", Type::vec3).absent("use `polygon_xz`").example("[0.0, 0.0, 0.0]").unit("m").doc("Box: lower corner."),
      K("max", Type::vec3).absent("use `polygon_xz`").example("[10.0, 6.0, 8.0]").unit("m").doc("Box: upper corner."),
      K("polygon_xz", Type::pair_list)
          .absent("use `min` and `max`")
          .example("[[0.0, 0.0], [20.0, 0.0], [20.0, 4.0], [0.0, 9.0]]")
          .unit("m")
          .doc("Polygon region: vertices `[x, z]` in order (either orientation), at least 3, a simple polygon "
               "(no edge crosses another) with positive area."),
      K("y_range", Type::number_pair)
          .absent("required with `polygon_xz`")
          .example("[-3.5, 3.5]")
          .unit("m")
          .doc("Polygon region: extent along y `[min, max]`, min < max."),
      K("count", Type::integer).required("200").ge(1).doc("Number of spheres."),
      K("distribution", Type::string).def(ParticleSet{}.distribution).doc("How diameters are drawn (see above)."),
      K("diameter", Type::number_pair)
          .required("[1.0, 2.0]")
          .unit("m")
          .gt(0)
          .only_for(ranged)
          .doc("Uniform: smallest and largest diameter `[min, max]`. Normal: the clip range."),
      K("mean_diameter", Type::number)
          .required("1.5")
          .unit("m")
          .gt(0)
          .only_for({"normal"})
          .doc("Mean of the normal distribution."),
      K("std_diameter", Type::number)
          .required("0.25")
          .unit("m")
          .ge(0)
          .only_for({"normal"})
          .doc("Standard deviation of the normal distribution."),
      K("sieve", Type::pair_list)
          .required("[[1.0, 0.0], [1.5, 0.4], [2.0, 1.0]]")
          .only_for({"sieve"})
          .doc("Grading curve, rows `[diameter (m), fraction finer]`, at least 2 rows."),
      K("sieve_basis", Type::string)
          .def(ParticleSet{}.sieve_by_mass ? "mass" : "count")
          .choices({"mass", "count"})
          .only_for({"sieve"})
          .doc("The sieve fractions are of the mass or of the count."),
      K("seed", Type::integer).def(ParticleSet{}.seed).ge(0).doc("Seed of the random generator."),
      K("velocity", Type::vec3).def(ParticleSet{}.velocity).unit("m/s").doc("Initial velocity of every sphere."),
      K("settle_time", Type::number)
          .def(ParticleSet{}.settle_time)
          .unit("s")
          .ge(0)
          .doc("Simulated time the set settles under gravity inside its region before step 0 (0: no "
               "settling; the spheres start where they were placed)."),
  };
}

}  // namespace sabo::scene::schema::detail

namespace sabo::scene::detail {

void Builder::read_particle_set(const toml::table& table, std::size_t index) {
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

void Builder::read_fill(const toml::table& table, const std::string& path, ParticleSet& set) {
  Reader f(diag_, spec("particles-fill"), table, path);
  const std::size_t errors_before = diag_.count();
  if (const auto distribution = f.string("distribution")) {
    f.select(*distribution);
    set.distribution = value_named<SizeDistribution>(*distribution);
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

void Builder::read_fill_region(Reader& f, ParticleSet& set) {
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
    diag_.add(line, f.key_path("polygon_xz"), value,
              fmt::format("the polygon is not simple: edge {} (vertices {} and {}) meets edge {} (vertices {} and {})",
                          i, i, (i + 1) % n, j, j, (j + 1) % n),
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

void Builder::read_fill_sizes(Reader& f, ParticleSet& set) {
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
              fmt::format("the mean lies outside the clip range diameter = [{}, {}]", number_literal(set.diameter_min),
                          number_literal(set.diameter_max)),
              "give a mean inside the clip range, or widen diameter");
  }
}

// The fills placed as the dem_solver places them (the same function, the same seed): the 30 % rule is a quick
// estimate, and a region narrower than its spheres somewhere (a slanted strip whose bounding box is wide
// enough) passes it and still cannot be filled.
void Builder::check_fills() {
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

}  // namespace sabo::scene::detail
