// [[inflows]]: the schema of the section and its reader. An inflow is a fluid body (FluidBody::Shape::inflow,
// after the [[fluids]] in Scene::fluids) whose particles enter through a cross-section during the run.

#include "libsabo/scene/detail/builder.hpp"
#include "libsabo/scene/detail/schema_tables.hpp"

namespace sabo::scene::schema::detail {

void Schema::build_inflows() {
  inflow.title = "[[inflows]]";
  inflow.anchor = "inflows";
  inflow.description =
      "A fluid body that enters the scene through a rectangular cross-section at the rate of a discharge "
      "hydrograph Q(t), the way a design event is given (docs/physics.md, \"Inflows\"). The section stands at "
      "`position` (the middle of its bottom edge), normal to the flow `direction`; it is `width` wide "
      "(horizontally, across the flow) and `depth` deep (perpendicular to the flow and the width, upwards).\n\n"
      "Behind the section the sph_solver keeps a buffer of ceil(2h / dx) + 1 layers of particles on the "
      "lattice of spacing dx, moving along `direction` at the section's mean velocity U(t) = Q(t) / A with "
      "A = n_w n_d dx^2 (n_w = round(width / dx), n_d = round(depth / dx) particles across and up), with the "
      "hydrostatic density of their depth (or the rest density); a layer that crosses the section is "
      "released into the flow, and a new one is added at the back each time the buffer has advanced dx. The "
      "released volume follows the integral of Q to within half a layer (summary.json: "
      "`results.sph_solver.inflows`; its history in `inflows.csv`: time, body (the inflow's name), discharge, "
      "hydrograph_volume, released_volume, buffer_speed at the output times). The buffer pushes the fluid ahead of "
      "it like a piston, and takes the flow's pressure back; the work it does and the energy of the fluid it "
      "brings is the `inflow` column of energy.csv. When the hydrograph ends (Q = 0 after its last point) the "
      "buffer's particles are taken out. The particles the run will need are counted from the hydrograph up "
      "to `run.end_time` and belong to the body from the start (`active` 0 in sph/*.vtp until they enter, "
      "2 while in the buffer, 1 once released). The body is named like a fluid in `[[interactions]]`, "
      "`[[fronts]]` and the contact sections.";
  inflow.keys = {
      K("name", Type::string)
          .required("\"upstream\"")
          .allowed("letters, digits, `_`, `-`")
          .doc("Name of the body, unique among all bodies."),
      K("material", Type::string)
          .required("\"slurry\"")
          .allowed("a `[materials.NAME]` of a fluid rheology but `elastic_plastic`")
          .doc("Material of the fluid that enters."),
      K("position", Type::vec3).required("[0.0, 0.0, 10.0]").unit("m").doc("Middle of the section's bottom edge."),
      K("direction", Type::vec3)
          .def(InflowSection{}.direction)
          .doc("Direction of the flow through the section, its normal; not vertical (a sloping bed: the bed's "
               "direction)."),
      K("width", Type::number).required("7.0").unit("m").gt(0).doc("Width of the section, at least dx."),
      K("depth", Type::number).required("2.0").unit("m").gt(0).doc("Flow depth at the section, at least dx."),
      K("hydrograph", Type::pair_list)
          .absent("use `hydrograph_file`")
          .example("[[0.0, 0.0], [10.0, 1530.0], [60.0, 0.0]]")
          .unit("s, m^3/s")
          .doc("The discharge: points (t, Q), at least 2, t strictly increasing from t >= 0, Q >= 0 and not all "
               "0; linear between them, 0 before the first and after the last. Exactly one of `hydrograph` and "
               "`hydrograph_file`."),
      K("hydrograph_file", Type::string)
          .absent("use `hydrograph`")
          .example("\"hydrograph.csv\"")
          .doc("A CSV file of the points (t, Q), one `time,discharge` per line (s, m^3/s), relative to the scene "
               "file's folder; `#` comments and a header line are skipped."),
      K("hydrostatic", Type::boolean)
          .def(FluidBody{}.hydrostatic)
          .doc("The buffer's particles carry the hydrostatic pressure of their depth below the section's top "
               "(and the matching density); false: the rest density."),
  };
}

}  // namespace sabo::scene::schema::detail

namespace sabo::scene::detail {

namespace {

// The hydrograph's rules (points, times, discharges), as a problem and its fix; nullopt when it keeps them.
std::optional<std::pair<std::string, std::string>> hydrograph_problem(const std::vector<std::array<double, 2>>& q) {
  if (q.size() < 2) {
    return std::pair{fmt::format("a hydrograph needs at least 2 points, not {}", q.size()),
                     std::string("list the points (t, Q) in order of time, e.g. [[0.0, 0.0], [10.0, 100.0], [60.0, "
                                 "0.0]]")};
  }
  if (q.front()[0] < 0) {
    return std::pair{fmt::format("starts at t = {} s, before the run", q.front()[0]),
                     std::string("start the hydrograph at t >= 0")};
  }
  for (std::size_t k = 0; k < q.size(); ++k) {
    if (k > 0 && !(q[k][0] > q[k - 1][0])) {
      return std::pair{fmt::format("point {} has t = {} s after t = {} s at point {}: time must increase", k, q[k][0],
                                   q[k - 1][0], k - 1),
                       std::string("sort the points by time and drop repeated ones")};
    }
    if (!(q[k][1] >= 0)) {
      return std::pair{
          fmt::format("point {} has the discharge {} m^3/s: an inflow's discharge is at least 0", k, q[k][1]),
          std::string("give discharges >= 0 (a section where fluid leaves is the domain's edge, "
                      "sph.domain_min/domain_max)")};
    }
  }
  if (std::all_of(q.begin(), q.end(), [](const std::array<double, 2>& p) { return p[1] == 0; })) {
    return std::pair{std::string("every discharge is 0: nothing would enter"),
                     std::string("give the discharges of the event (m^3/s), or remove the inflow")};
  }
  return std::nullopt;
}

}  // namespace

void Builder::read_inflow(const toml::table& table, std::size_t index) {
  const std::string path = fmt::format("inflows[{}]", index);
  Reader r(diag_, spec("inflows"), table, path);
  FluidBody body;
  body.shape = FluidBody::Shape::inflow;
  body.origin = origin(r.line(), path);
  InflowSection& section = body.inflow;
  if (auto v = r.string("name")) {
    body.name = *v;
    register_body(r, body.name, false, true);
  }
  if (auto v = r.string("material")) {
    body.material = *v;
    check_material(r, body.material);
    const auto material =
        std::find_if(scene_.materials.begin(), scene_.materials.end(), [&](const Material& m) { return m.name == *v; });
    if (material != scene_.materials.end() && material->rheology == Material::Rheology::elastic_plastic) {
      diag_.add(r.line("material"), r.key_path("material"), quote_text(*v),
                "an elastic_plastic material cannot enter through an inflow: the stress it carries in is unknown",
                "use a fluid rheology (bingham, herschel_bulkley, newtonian, inviscid) for the inflowing material");
    }
  }
  if (auto v = r.boolean("hydrostatic")) body.hydrostatic = *v;
  if (auto v = r.vec3("position")) section.position = *v;
  if (auto v = r.vec3("direction")) {
    const double horizontal = std::hypot(v->x(), v->y());
    if (!(horizontal > 1e-3 * v->norm())) {
      diag_.add(r.line("direction"), r.key_path("direction"), value_text(*r.node("direction")),
                "must not be zero or vertical: the section's width lies across it horizontally",
                "give the flow's direction, e.g. direction = [1.0, 0.0, -0.2] down a sloping bed");
    } else {
      section.direction = v->normalized();
    }
  }
  const double dx = scene_.sph.particle_spacing;
  for (const char* key : {"width", "depth"}) {
    const auto v = r.number(key);
    if (!v) continue;
    (std::string_view(key) == "width" ? section.width : section.depth) = *v;
    if (dx > 0 && *v < dx) {
      diag_.add(
          r.line(key), r.key_path(key), number_literal(*v),
          fmt::format("smaller than the particle spacing {} m: the section holds no particle", number_literal(dx)),
          fmt::format("give a {} of at least {} m, or lower sph.particle_spacing", key, number_literal(dx)));
    }
  }
  const bool inline_table = r.has("hydrograph"), file_table = r.has("hydrograph_file");
  if (inline_table == file_table) {
    diag_.add(r.line(), r.key_path(inline_table ? "hydrograph" : "hydrograph_file"),
              inline_table ? std::optional(value_text(*r.node("hydrograph"))) : std::nullopt,
              inline_table ? "gives both hydrograph and hydrograph_file: an inflow has one hydrograph"
                           : "an inflow needs its hydrograph",
              inline_table ? "keep one of hydrograph and hydrograph_file"
                           : "add hydrograph = [[0.0, 0.0], [10.0, 100.0], [60.0, 0.0]] (t in s, Q in m^3/s) or "
                             "hydrograph_file = \"hydrograph.csv\"");
  } else if (inline_table) {
    if (auto v = r.pairs("hydrograph")) {
      if (const auto problem = hydrograph_problem(*v)) {
        diag_.add(r.line("hydrograph"), r.key_path("hydrograph"), value_text(*r.node("hydrograph")), problem->first,
                  problem->second);
      } else {
        section.hydrograph = *v;
      }
    }
  } else if (auto file = r.string("hydrograph_file")) {
    try {
      std::vector<std::array<double, 2>> points;
      for (const io::CsvPair& point : io::read_pairs_csv(scene_relative(*file), io::kHydrographColumns)) {
        points.push_back({point.first, point.second});
      }
      if (const auto problem = hydrograph_problem(points)) {
        diag_.add(r.line("hydrograph_file"), r.key_path("hydrograph_file"), quote_text(*file),
                  fmt::format("the hydrograph of {}: {}", scene_relative(*file).string(), problem->first),
                  problem->second);
      } else {
        section.hydrograph = std::move(points);
      }
    } catch (const FileError& error) {
      add_file_error(r, "hydrograph_file", quote_text(*file), "the hydrograph cannot be read", error,
                     "correct the path; it is relative to the scene file's folder");
    }
  }
  // The box of the section and its buffer behind it.
  const bool placed = dx > 0 && section.width > 0 && section.depth > 0 && r.has("position");
  const double behind = static_cast<double>(scene_.sph.inflow_buffer_layers()) * dx;
  Aabb buffer = body.bounds();
  buffer.extend(buffer.min - behind * section.direction);
  buffer.extend(buffer.max - behind * section.direction);
  // The buffer lies in the domain: a particle outside it would be taken out.
  if (scene_.sph.domain && placed) {
    if (!(scene_.sph.domain->contains(buffer.min) && scene_.sph.domain->contains(buffer.max))) {
      diag_.add(r.line("position"), r.key_path("position"), value_text(*r.node("position")),
                fmt::format("the section and its buffer ({} layers, {} m behind it) reach outside the SPH domain "
                            "(sph.domain_min/domain_max, line {}): they span {} to {}",
                            scene_.sph.inflow_buffer_layers(), number_literal(behind), domain_line_,
                            vec_text(buffer.min), vec_text(buffer.max)),
                "move the section into the domain, or enlarge the domain to hold the buffer behind it");
    }
  }
  // A periodic axis wraps particles back into its span: a seam through the buffer would cut it.
  if (placed) {
    check_inside_periodic_spans(buffer, r.line("position"), r.key_path("position"), value_text(*r.node("position")),
                                "the section with its buffer",
                                "move the section into the span (across a periodic width: the span's width, centred "
                                "in it)");
  }
  // The buffer's speed stays well below the sound speed (weakly compressible flow).
  if (dx > 0 && scene_.sph.sound_speed > 0 && !section.hydrograph.empty() && section.width >= dx &&
      section.depth >= dx) {
    const double area = section.lattice(scene_.sph, scene_.run.end_time).area;
    const double speed = section.peak_discharge() / area;
    if (speed >= scene_.sph.sound_speed) {
      diag_.add(r.line(), path, std::nullopt,
                fmt::format("the peak discharge {} m^3/s through the section's {} m^2 is a speed of {} m/s, at or "
                            "above sph.sound_speed = {} m/s",
                            number_literal(section.peak_discharge()), fmt::format("{:.6g}", area),
                            fmt::format("{:.6g}", speed), number_literal(scene_.sph.sound_speed)),
                fmt::format("raise sph.sound_speed to at least {:.3g} m/s (ten times the flow), or widen or "
                            "deepen the section",
                            10.0 * speed));
    }
  }
  scene_.fluids.push_back(std::move(body));
}

}  // namespace sabo::scene::detail
