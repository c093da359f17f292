// [[gauges]], [[fronts]] and [[sensors]]: the schemas of the sections and their readers.

#include "libsabo/scene/detail/builder.hpp"
#include "libsabo/scene/detail/schema_tables.hpp"

namespace sabo::scene::schema::detail {

void Schema::build_gauges() {
  gauge.title = "[[gauges]]";
  gauge.anchor = "gauges";
  gauge.selector = "kind";
  gauge.description =
      "A pressure gauge in the fluid, read by the sph_solver into `gauges.csv` (time, gauge, point, x, y, z, "
      "kernel_sum, pressure, velocity_x, velocity_y, velocity_z, depth), one row per point and sample. Needs "
      "`[[fluids]]`.\n\n"
      "* `point`: one point, `position`.\n"
      "* `line`: `points` equally spaced points from `start` to `end`; `depth` is the distance from `start` along "
      "the line to the free surface (a vertical line from the bed: the flow depth).\n\n"
      "A value at a point x is the first-order (moving least squares) fit of the particles within the kernel "
      "support 2h of x, weighted by V_j W(x - x_j) (V_j = m_j / rho_j): exact for a linear field, and the "
      "Shepard-normalised mean sum V_j W f_j / sum V_j W where the neighbours do not span three dimensions. "
      "`kernel_sum` is sum V_j W(x - x_j): about 1 inside the fluid, 1/2 at a free surface or a wall, 0 in the "
      "air. A point with `kernel_sum` below 0.1 is dry and reads 0 (pressure and velocity). The free surface "
      "along a line is where `kernel_sum` falls through 1/2, found on a sub-sampling of spacing dx / 4. "
      "Samples are taken at t_n of the step at which the gauge's sample time is reached (positions and "
      "pressures at t_n, velocities at t_{n-1/2}).";
  gauge.keys = {
      K("name", Type::string)
          .required("\"wall_gauge\"")
          .allowed("letters, digits, `_`, `-`")
          .doc("Name of the gauge, unique among the gauges."),
      K("kind", Type::string).required("\"point\"").choices({"point", "line"}).doc("One point or a line of points."),
      K("position", Type::vec3).required("[1.0, 0.0, 0.2]").unit("m").only_for({"point"}).doc("The point."),
      K("start", Type::vec3).required("[1.0, 0.0, 0.0]").unit("m").only_for({"line"}).doc("First point of the line."),
      K("end", Type::vec3)
          .required("[1.0, 0.0, 1.0]")
          .unit("m")
          .only_for({"line"})
          .doc("Last point of the line, not `start`."),
      K("points", Type::integer)
          .def(Gauge::kLinePoints)
          .ge(2)
          .le(10000)
          .only_for({"line"})
          .doc("Points along the line."),
      K("interval", Type::number)
          .absent("`run.output_interval`")
          .example("0.001")
          .unit("s")
          .gt(0)
          .doc("Simulated time between two samples."),
  };
}

void Schema::build_fronts() {
  front.title = "[[fronts]]";
  front.anchor = "fronts";
  front.selector = "kind";
  front.description =
      "A front tracker of the sph_solver: where the flow's leading edge is along a path, how fast it "
      "moves, when it passes named stations and how deep the flow stands there. Needs `[[fluids]]`. At every "
      "sample it appends to `fronts.csv` (time, front, position, speed, flow_speed, x, y, z) and, for each "
      "station, to `front_stations.csv` (time, front, station, at, depth); `summary.json` carries the history, "
      "the fastest speed and, per station, the arrival time and the largest and final depths "
      "(`results.sph_solver.fronts.NAME`).\n\n"
      "* `axis`: the distance of a point x is s = (x - `start`) . `direction` (unit), a station's depth is "
      "measured vertically up from `start` + s `direction` (an axis along a floor: the depth above the floor).\n"
      "* `channel`: the path is the centre line of a `[[structures]]` of shape `channel`: s is the distance of "
      "its profile, a station's depth is measured vertically up from the bed.\n"
      "* `terrain`: the path is the centre line of the `strip` of a `[[structures]]` of shape `terrain`, a "
      "polyline that may bend: s is the horizontal distance along it from its first point (a point's s is that of "
      "the nearest point of the line seen from above), a station's depth is measured vertically up from the "
      "ground (the raster's elevation on the line, sampled at the terrain's `element_size`), and `flow_speed` is "
      "along the line where the front is.\n\n"
      "The front is the largest s of the fluid particles in the domain, leaving out the `ahead` most advanced ones "
      "(spray, a splash over a wall); `x, y, z` is that particle's position. `speed` is the front's advance since "
      "the previous sample divided by the time between them (0 at the first); `flow_speed` is the mean velocity "
      "along the path of the particles within one kernel support (2 h) behind the front. A station's depth is the "
      "height above its path point where the kernel sum falls through 1/2 (the free surface, as a line gauge's "
      "depth), 0 where the flow has not come.";
  front.keys = {
      K("name", Type::string)
          .required("\"slurry_front\"")
          .allowed("letters, digits, `_`, `-`")
          .doc("Name of the front, unique among the fronts."),
      K("kind", Type::string)
          .required("\"axis\"")
          .choices({"axis", "channel", "terrain"})
          .doc("A straight axis, a channel, or a terrain's strip."),
      K("start", Type::vec3).required("[0.0, 0.0, 0.0]").unit("m").only_for({"axis"}).doc("Where s = 0."),
      K("direction", Type::vec3)
          .required("[1.0, 0.0, 0.0]")
          .only_for({"axis"})
          .doc("The direction of increasing s, not zero (normalised by the loader)."),
      K("channel", Type::string)
          .required("\"gully\"")
          .only_for({"channel"})
          .allowed("a `[[structures]]` name of shape `channel`")
          .doc("The channel whose centre line is the path."),
      K("terrain", Type::string)
          .required("\"gully\"")
          .only_for({"terrain"})
          .allowed("a `[[structures]]` name of shape `terrain` with a `strip`")
          .doc("The terrain whose strip's centre line is the path."),
      K("ahead", Type::integer)
          .def(static_cast<std::int64_t>(Front{}.ahead))
          .ge(0)
          .doc("Fluid particles allowed ahead of the front: spray that left the flow."),
      K("interval", Type::number)
          .absent("`run.output_interval`")
          .example("0.5")
          .unit("s")
          .gt(0)
          .doc("Simulated time between two samples."),
      K("depth_height", Type::number)
          .absent("to `sph.domain_max`'s z, else 50 m")
          .example("30.0")
          .unit("m")
          .gt(0)
          .doc("Height of the vertical line above a station's path point along which its depth is found."),
      K("stations", Type::table_list)
          .inside(front_station)
          .absent("none")
          .example("[ { name = \"mouth\", at = 870.0 } ]")
          .doc("Named distances along the path (inline tables, see below)."),
  };
  front_station.title = "[[fronts]] stations = [ { ... } ]";
  front_station.anchor = "fronts-stations";
  front_station.description =
      "A station of a front: the time the front first passes it and the flow depth there at every sample "
      "(`front_stations.csv`), the largest and the final depth in `summary.json` (a deposit height at the end of a "
      "run that stops the flow).";
  front_station.keys = {
      K("name", Type::string)
          .required("\"mouth\"")
          .allowed("letters, digits, `_`, `-`")
          .doc("Name, unique among the front's stations."),
      K("at", Type::number)
          .required("870.0")
          .unit("m")
          .doc("Distance along the path; on a channel, within its profile."),
  };
}

void Schema::build_sensors() {
  sensor.title = "[[sensors]]";
  sensor.anchor = "sensors";
  sensor.description =
      "A force sensor on a structure, written by the coupler into `sensors.csv` (time, sensor, part, source, "
      "Fx, Fy, Fz, F, F_peak, area, pressure) at every output time, like `forces.csv`: the mean force over the "
      "output interval from each source (`fluid`, `particles`, ...), its magnitude and the largest instantaneous "
      "magnitude, the sensor's surface area and the mean normal pressure -F.n / area (n the area-weighted mean "
      "outward normal of the patch, N/m^2 = Pa). The sensor takes the contact forces whose point of contact on the "
      "surface lies in the box (for boundary-particle walls: the wall particles sampled there), so that a "
      "sensor smaller than the mesh's faces (a 10 mm transducer) works; its area is the part's surface clipped "
      "to the box. It should be at least one particle spacing `sph.particle_spacing` wide along the face (the scene "
      "check warns otherwise): a narrower one holds at most a row of wall particles and its reading jumps as the "
      "fluid particles pass. A sensor without a box is the whole part: its force is the part's row of "
      "`forces.csv`.";
  sensor.keys = {
      K("name", Type::string)
          .required("\"transducer_1\"")
          .allowed("letters, digits, `_`, `-`")
          .doc("Name of the sensor, unique among the sensors."),
      K("part", Type::string).required("\"dam\"").allowed("a `[[structures]]` name").doc("The structure."),
      K("min", Type::vec3)
          .absent("the whole part")
          .example("[4.99, -0.005, 0.095]")
          .unit("m")
          .doc("Lower corner of the box; give `min` and `max` together."),
      K("max", Type::vec3)
          .absent("the whole part")
          .example("[5.01, 0.005, 0.105]")
          .unit("m")
          .doc("Upper corner of the box, above `min` on every axis."),
  };
}

}  // namespace sabo::scene::schema::detail

namespace sabo::scene::detail {

// A gauge or sensor name: valid and unique among its kind (`names`).
void Builder::register_instrument(Reader& r, const std::string& name, std::map<std::string, int>& names,
                                  const char* kind) {
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

void Builder::read_gauges(Reader& root) {
  const toml::array* gauges = root.table_list("gauges");
  if (gauges == nullptr || gauges->empty()) return;
  if (!has_fluids_) {
    diag_.add(root.line("gauges"), "gauges", std::nullopt, "gauges measure the fluid, but the scene has no [[fluids]]",
              "remove the [[gauges]] or add a fluid");
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

void Builder::read_fronts(Reader& root) {
  const toml::array* fronts = root.table_list("fronts");
  if (fronts == nullptr || fronts->empty()) return;
  if (!has_fluids_) {
    diag_.add(root.line("fronts"), "fronts", std::nullopt, "fronts follow the fluid, but the scene has no [[fluids]]",
              "remove the [[fronts]] or add a fluid");
    return;
  }
  std::vector<std::string> channels;
  for (const Structure& structure : scene_.structures) {
    if (structure.shape.type == Shape::Type::channel) channels.push_back(structure.name);
  }
  std::map<std::string, int> names;
  for (std::size_t k = 0; k < fronts->size(); ++k) {
    const std::string path = fmt::format("fronts[{}]", k);
    Reader r(diag_, spec("fronts"), *fronts->get(k)->as_table(), path);
    Front front;
    front.origin = origin(r.line(), path);
    if (auto v = r.string("name")) {
      front.name = *v;
      register_instrument(r, front.name, names, "front");
    }
    if (auto v = r.integer("ahead")) front.ahead = static_cast<std::size_t>(*v);
    if (auto v = r.number("interval")) front.interval = *v;
    front.depth_height = scene_.sph.domain ? 0.0 : Front::kDepthHeight;
    if (auto v = r.number("depth_height")) front.depth_height = *v;
    const auto kind = r.string("kind");
    if (!kind) continue;
    r.select(*kind);
    bool have_path = false;
    if (*kind == "axis") {
      front.kind = Front::Kind::axis;
      const auto start = r.vec3("start"), direction = r.vec3("direction");
      if (start) front.start = *start;
      if (direction && direction->norm() == 0.0) {
        diag_.add(r.line("direction"), r.key_path("direction"), value_text(*r.node("direction")),
                  "the direction is zero", "give the direction the front moves in, e.g. [1.0, 0.0, 0.0]");
      } else if (direction) {
        front.direction = direction->normalized();
        have_path = start.has_value();
      }
    } else if (*kind == "terrain") {
      front.kind = Front::Kind::terrain;
      have_path = read_terrain_front(r, front);
    } else if (auto name = r.string("channel")) {
      front.kind = Front::Kind::channel;
      front.channel = *name;
      const auto structure = std::find_if(scene_.structures.begin(), scene_.structures.end(),
                                          [&](const Structure& s) { return s.name == *name; });
      if (structure == scene_.structures.end() || structure->shape.type != Shape::Type::channel) {
        const auto suggestion = closest_match(*name, channels);
        std::string problem =
            structure == scene_.structures.end() ? "no structure of that name" : "that structure is not a channel";
        if (suggestion) problem += fmt::format(". Did you mean '{}'?", *suggestion);
        diag_.add(r.line("channel"), r.key_path("channel"), quote_text(*name), problem,
                  channels.empty() ? std::string("add a [[structures]] of shape = \"channel\", or use kind = \"axis\"")
                                   : fmt::format("use one of: {}", join(channels)));
      } else if (!structure->shape.profile.empty()) {
        front.start = structure->shape.origin;
        front.direction = structure->shape.direction;
        front.bed = structure->shape.profile;
        have_path = true;
      }
    }
    if (const toml::array* stations = r.table_list("stations")) read_front_stations(r, *stations, front);
    if (have_path && scene_.sph.domain && !r.has("depth_height")) {
      double lowest = std::numeric_limits<double>::infinity();
      for (const Front::Station& station : front.stations) lowest = std::min(lowest, front.path_point(station.at).z());
      front.depth_height = std::isfinite(lowest) ? std::max(scene_.sph.domain->max.z() - lowest, 0.0) : 0.0;
      if (!front.stations.empty() && !(front.depth_height > 0)) {
        diag_.add(r.line("stations"), r.key_path("stations"), value_text(*r.node("stations")),
                  fmt::format("a station's path point lies above the SPH domain's top z = {}",
                              number_literal(scene_.sph.domain->max.z())),
                  "move the station or raise sph.domain_max");
      }
    }
    scene_.fronts.push_back(std::move(front));
  }
}

// A terrain front's path: the strip's centre line on the ground; false when the key is wrong.
bool Builder::read_terrain_front(Reader& r, Front& front) {
  const auto name = r.string("terrain");
  if (!name) return false;
  front.structure = *name;
  std::vector<std::string> strips;
  for (const Structure& s : scene_.structures) {
    if (s.shape.type == Shape::Type::terrain && !s.shape.strip.empty()) strips.push_back(s.name);
  }
  const auto structure = std::find_if(scene_.structures.begin(), scene_.structures.end(),
                                      [&](const Structure& s) { return s.name == *name; });
  if (structure == scene_.structures.end() || structure->shape.type != Shape::Type::terrain ||
      structure->shape.strip.empty()) {
    std::string problem = structure == scene_.structures.end()            ? "no structure of that name"
                          : structure->shape.type != Shape::Type::terrain ? "that structure is not a terrain"
                                                                          : "that terrain keeps no strip";
    if (const auto suggestion = closest_match(*name, strips))
      problem += fmt::format(". Did you mean '{}'?", *suggestion);
    diag_.add(r.line("terrain"), r.key_path("terrain"), quote_text(*name), problem,
              strips.empty() ? std::string("add a [[structures]] of shape = \"terrain\" with a strip, or use kind = "
                                           "\"axis\"")
                             : fmt::format("use one of: {}", join(strips)));
    return false;
  }
  if (structure->shape.file.empty() || structure->shape.raster.empty()) return false;  // its own error is out
  try {
    front.path = geometry::terrain_centre_line(structure->shape, structure->name);
  } catch (const Error& error) {
    add_file_error(r, "terrain", quote_text(*name), "the terrain's centre line cannot be followed", error,
                   "keep the strip inside the raster");
    return false;
  }
  front.path_s.assign(1, 0.0);
  for (std::size_t k = 1; k < front.path.size(); ++k) {
    front.path_s.push_back(front.path_s.back() + (front.path[k] - front.path[k - 1]).head<2>().norm());
  }
  return front.path.size() >= 2;
}

void Builder::read_front_stations(Reader& front_reader, const toml::array& list, Front& front) {
  std::map<std::string, int> names;
  for (std::size_t k = 0; k < list.size(); ++k) {
    const std::string path = front_reader.key_path(fmt::format("stations[{}]", k));
    Reader r(diag_, spec("fronts-stations"), *list.get(k)->as_table(), path);
    Front::Station station;
    if (auto v = r.string("name")) {
      station.name = *v;
      register_instrument(r, station.name, names, "station");
    }
    if (auto v = r.number("at")) {
      station.at = *v;
      if (!front.path_s.empty() && (*v < 0 || *v > front.path_s.back())) {
        diag_.add(r.line("at"), r.key_path("at"), value_text(*r.node("at")),
                  fmt::format("outside the centre line of terrain '{}', which runs from 0 to {} m", front.structure,
                              number_literal(front.path_s.back())),
                  "give a distance along the strip's centre line");
      }
      if (!front.bed.empty() && (*v < front.bed.front()[0] || *v > front.bed.back()[0])) {
        diag_.add(r.line("at"), r.key_path("at"), value_text(*r.node("at")),
                  fmt::format("outside the profile of channel '{}', which runs from {} to {} m", front.channel,
                              number_literal(front.bed.front()[0]), number_literal(front.bed.back()[0])),
                  "give a distance within the profile");
      }
    }
    front.stations.push_back(std::move(station));
  }
}

void Builder::read_sensors(Reader& root) {
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
void Builder::check_sensor_box(Reader& r, const Sensor& sensor) {
  const auto patch = sensor_patch(scene_.structures, sensor);
  if (!patch || patch->area > 0) return;
  diag_.add(r.line("min"), r.key_path("min"), value_text(*r.node("min")),
            fmt::format("the box [{}, {}] meets none of the surface of '{}', which spans {} to {}",
                        vec_text(sensor.box->min), vec_text(sensor.box->max), sensor.part,
                        vec_text(patch->part_bounds.min), vec_text(patch->part_bounds.max)),
            "move the box onto the part's face (a box a few mm thick across the face)");
}

}  // namespace sabo::scene::detail
