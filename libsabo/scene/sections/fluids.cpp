// [sph] and [[fluids]]: the schema of the section and its reader.

#include "libsabo/scene/detail/builder.hpp"
#include "libsabo/scene/detail/schema_tables.hpp"

namespace sabo::scene::schema::detail {

void Schema::build_sph() {
  sph.title = "[sph]";
  sph.anchor = "sph";
  sph.description =
      "Weakly compressible SPH (sph_solver): kernel, resolution, equation-of-state stiffness, numerical "
      "diffusion and the wall model. Required when the scene has `[[fluids]]`, an error otherwise.\n\n"
      "Walls: with `wall_model = \"boundary_particles\"` the coupler samples every structure surface as "
      "layers of wall particles (Adami, Hu & Adams 2012) that enter the fluid's density and pressure sums; "
      "with `\"penalty\"` the coupler pushes fluid particles out of structure faces by the penalty contact "
      "of paper eqs. 3-6 (`[contact.sph_fem]`).";
  sph.keys = {
      K("particle_spacing", Type::number).required("0.02").unit("m").gt(0).doc("Initial particle spacing dx."),
      K("smoothing_ratio", Type::number)
          .def(SphSettings{}.smoothing_ratio)
          .ge(0.5)
          .le(3)
          .doc("h / dx. The default 1.5 keeps a Wendland C2 lattice at rest (about 100 neighbours); at 1.3 it "
               "rearranges (docs/physics.md, \"The kernel at rest\"). With the cubic spline 1.3 holds and 1.5 "
               "does not."),
      K("kernel", Type::string).def(SphSettings{}.kernel).doc("Smoothing kernel; both have support 2h."),
      K("wall_model", Type::string).def(SphSettings{}.wall_model).doc("How structures act on the fluid (see above)."),
      K("wall_work", Type::string)
          .def(SphSettings{}.wall_work)
          .doc("Boundary-particle walls: what becomes of the work that the walls' extrapolated pressure does "
               "on the fluid (docs/physics.md, \"Energy\"). `\"unstored\"`: nothing stores it (Adami et al. "
               "2012 as published); a column released beside walls gains up to 5e-4 of its energy. "
               "`\"stored\"`: each wall particle's compression is credited to the fluid whose pressures its "
               "pressure averages, an exact energy balance; but fronts run faster over a floor (S1's fitted "
               "shift -0.29 instead of -0.16 T) and a Bingham slump spreads 31 % too thin (S8's deposit). "
               "`\"bounded\"`: the work the fluid loses to the walls is held back, as without storing, in an "
               "account per fluid particle, and what the walls give back is paid from it; only what the account "
               "cannot pay is credited. The energy never rises above its initial value, S1's front comes out "
               "as without storing (2.2 % RMS, shift -0.15 T) and the reduced S8 deposit too (9.9 %). The held "
               "energy is the SPH process's `dissipated` in energy.csv. Not applied against elastic-plastic "
               "fluid."),
      K("free_slip_walls", Type::string_list)
          .absent("none: every wall is no-slip")
          .example("[\"floor\"]")
          .allowed("`[[structures]]` names")
          .doc("Boundary-particle walls: the structures whose wall particles are free-slip (the fluid keeps its "
               "velocity along the wall: neither the viscous terms nor the artificial viscosity put shear on it; "
               "a smooth wall, or a symmetry plane); every other structure is no-slip (Adami et al. 2012). "
               "Pressure acts on both alike. Not with `wall_model = \"penalty\"`, whose walls slip by "
               "`[contact.sph_fem]` friction."),
      K("wall_spacing_ratio", Type::number)
          .def(SphSettings{}.wall_spacing_ratio)
          .ge(0.25)
          .le(1)
          .doc("Boundary-particle walls: the spacing of the structures' wall particles over dx (their layers fill "
               "the kernel support 2h at that spacing). At 1 a fluid lattice sliding along a wall at a tenth of the "
               "sound speed or more is pumped by the wall lattice's corrugation, which the same lattice of fluid "
               "particles meets in phase: the row beside a free-slip floor starts to bounce and falls through it "
               "(a layer at 2.5 m/s, c = 25 m/s: through within 0.3 s). 0.5 halves the wall lattice and the row "
               "stays put (to 5 m/s at c = 25 m/s), for about eight times the wall particles; 0.75 and 2/3 do not "
               "cure it (docs/physics.md, \"Walls\"). Fast flows over free-slip walls (B1 at Fr = 4) need 0.5."),
      K("lagged_boundary_particles", Type::boolean)
          .def(SphSettings{}.lagged_boundary_particles)
          .doc("Boundary particles (boundary-particle walls, or `[contact.sph_dem] model = \"boundary_particles\"`): "
               "the sph_solver computes its forces of step n while the coupler computes its contacts, with the "
               "wall particles of step n - 1 moved ahead one step by their velocity and acceleration (second "
               "order in the step; walls at rest do not move), instead of waiting for the wall particles of step "
               "n, which the coupler sends ahead of its other contacts (docs/protocol.md, \"Walls ahead\"). "
               "Faster where the fluid and the coupler have cores of their own and placing the wall particles "
               "takes long beside the fluid's step; the fluid's forces still balance the boulders' and the walls' "
               "exactly, step by step. The first step waits, as without it. Only with boundary particles."),
      K("sound_speed", Type::number)
          .required("30.0")
          .unit("m/s")
          .gt(0)
          .doc("Artificial sound speed c of every fluid: at least ten times the largest expected flow speed."),
      K("cfl", Type::number)
          .def(SphSettings{}.cfl)
          .gt(0)
          .le(1)
          .doc("The stable dt sent to the coupler: cfl * min(h / (c + h max|div v|), sqrt(h / max|a|), "
               "rho h^2 / (8 eta)) (paper eq. 7's SPH term with its force and viscous conditions)."),
      K("artificial_viscosity", Type::number).def(SphSettings{}.artificial_viscosity).ge(0).doc("Monaghan's alpha."),
      K("density_diffusion", Type::string)
          .def(SphSettings{}.density_diffusion)
          .doc("delta-SPH term of the continuity equation: Molteni & Colagrossi 2009, or with the hydrostatic "
               "part taken out (Fourtakas et al. 2019)."),
      K("density_diffusion_delta", Type::number)
          .def(SphSettings{}.density_diffusion_delta)
          .ge(0)
          .le(1)
          .doc("delta of the density diffusion."),
      K("viscous_operator", Type::string)
          .def(SphSettings{}.viscous_operator)
          .doc("How the viscous stress 2 eta D of the fluids (`rheology` newtonian, bingham, herschel_bulkley, "
               "elastic_plastic's `viscosity`) enters the momentum (docs/physics.md, \"Viscosity\"). "
               "`\"strain_rate\"`: the divergence of the deviatoric 2 eta D' = eta (L + L^T) - 2/3 eta tr(L) I, "
               "L = grad v: Morris et al. 1997's pair term for eta L and the symmetric SPH divergence of each "
               "particle's eta (L^T - 2/3 tr(L) I), with the kernel-gradient-corrected L (exact for a linear velocity "
               "field up to a free surface), which the shear rate of the rheology takes too; action equals "
               "reaction per pair and a rigid rotation feels no force. A uniaxial extension carries Trouton's 3 eta "
               "eps_dot (S9: 1.2 % off) and a yield stress acts in compression as in shear. `\"morris\"`: Morris's "
               "pair term alone with the uncorrected L (the operator until 2026-12-01), 6-13 % cheaper per viscous "
               "particle-step: the same in simple shear (S5, "
               "S8's slope), but it drops eta L^T, half the normal stress of an extension, wherever the viscosity "
               "varies or a free surface is near (S9: 49 % short; a Bingham column slumps to 24-28 % below the slump "
               "analysis' height, against 9-12 % with `\"strain_rate\"`)."),
      K("domain_min", Type::vec3)
          .absent("no domain: particles are never taken out")
          .example("[-1.0, -1.0, -1.0]")
          .unit("m")
          .doc("Lower corner of the domain; a particle that leaves it is taken out of the simulation (counted "
               "and logged). Give both corners or neither."),
      K("domain_max", Type::vec3)
          .absent("no domain")
          .example("[10.0, 1.0, 5.0]")
          .unit("m")
          .doc("Upper corner of the domain, above `domain_min` on every axis."),
      K("density_ratio_limits", Type::number_pair)
          .def(SphSettings{}.density_ratio_limits)
          .doc("A fluid particle whose density over its rest density leaves `[min, max]` after a step is an "
               "instability: the run stops there (docs/physics.md, \"Instability detection\"). A weakly "
               "compressible flow stays within a few percent of 1."),
      K("periodic_x", Type::number_pair)
          .absent("not periodic along x")
          .example("[0.0, 0.3]")
          .unit("m")
          .doc("Periodic boundaries along x over `[min, max)`: a particle leaving at one end re-enters at the "
               "other, and particles near one end see those near the other as neighbours (an infinite layer, "
               "a channel). The period max - min is at least two kernel supports plus one spacing (4h + dx); "
               "every fluid body lies inside, and so do the wall particles (the structures end at the span; "
               "a floor of boundary particles covers it without overlap)."),
      K("periodic_y", Type::number_pair)
          .absent("not periodic along y")
          .example("[0.0, 0.3]")
          .unit("m")
          .doc("Periodic boundaries along y over `[min, max)`, like `periodic_x`."),
  };
  fluid.title = "[[fluids]]";
  fluid.anchor = "fluids";
  fluid.selector = "shape";
  fluid.description =
      "One body of fluid (slurry, water), simulated by the sph_solver and filled with particles on a cubic "
      "lattice of spacing `sph.particle_spacing`, centres dx/2 inside the shape's boundary.\n\n"
      "* `box`: the box `[min, max]`.\n"
      "* `extruded_polygon`: the polygon `profile` (points (s, z): s along `direction` from `origin`, z "
      "absolute height) in the vertical plane through `origin`, extruded `width` across, centred on that "
      "plane. The Wenjia scenes draw the gully's longitudinal profile this way.\n\n"
      "With `hydrostatic = true` each particle starts with the pressure of the fluid column above it (and "
      "the matching density), so that a body at rest stays at rest.";
  fluid.keys = {
      K("name", Type::string)
          .required("\"slurry\"")
          .allowed("letters, digits, `_`, `-`")
          .doc("Name of the body, unique among all bodies."),
      K("material", Type::string).required("\"slurry\"").allowed("a `[materials.NAME]`").doc("Material."),
      K("shape", Type::string).required("\"box\"").choices({"box", "extruded_polygon"}).doc("Kind of geometry."),
      K("min", Type::vec3).required("[0.0, 0.0, 0.0]").unit("m").only_for({"box"}).doc("Lower corner."),
      K("max", Type::vec3)
          .required("[1.0, 1.0, 1.0]")
          .unit("m")
          .only_for({"box"})
          .doc("Upper corner, above `min` on every axis."),
      K("profile", Type::pair_list)
          .required("[[0.0, 0.0], [10.0, 0.0], [0.0, 5.0]]")
          .unit("m")
          .only_for({"extruded_polygon"})
          .doc("Polygon vertices (s, z) in order, at least 3, not self-intersecting."),
      K("origin", Type::vec3)
          .def(FluidBody{}.profile_origin)
          .unit("m")
          .only_for({"extruded_polygon"})
          .doc("Where s = 0 (its z is ignored: profile heights are absolute)."),
      K("direction", Type::vec3)
          .def(FluidBody{}.direction)
          .only_for({"extruded_polygon"})
          .doc("Horizontal direction of s (z = 0), not zero."),
      K("width", Type::number)
          .required("7.0")
          .unit("m")
          .gt(0)
          .only_for({"extruded_polygon"})
          .doc("Extrusion width across `direction`."),
      K("velocity", Type::vec3).def(FluidBody{}.velocity).unit("m/s").doc("Initial velocity."),
      K("hydrostatic", Type::boolean)
          .def(FluidBody{}.hydrostatic)
          .doc("Start with the hydrostatic pressure of the column above each particle."),
      K("settle_time", Type::number)
          .def(FluidBody{}.settle_time)
          .unit("s")
          .ge(0)
          .doc(fmt::format(
              "Length of a damped settling phase from t = 0 (0: none). Until then the body's velocities are "
              "relaxed every step, `v <- v exp(-dt / tau)`, with `tau` growing linearly from `h / c` "
              "(critical damping of the particle-scale pressure waves) at t = 0 to {:g} `h / c` at the end, and "
              "at its end they are set to zero: the body then starts from the discrete equilibrium of its "
              "particles and walls instead of the continuum's hydrostatic state, whose small imbalance at the "
              "free surface otherwise starts a transient of 1.4e-3 to 1.8e-3 sqrt(g H) (S4). For a body at rest "
              "in a container or behind a structure; the body must start at rest (`velocity` zero). The "
              "simulated time it takes is part of the run: 4 sqrt(H / g) (H the body's depth) brings the "
              "S4 tank below 1e-3 sqrt(g H) from t = 0.",
              kSettleDampingGrowth)),
  };
}

}  // namespace sabo::scene::schema::detail

namespace sabo::scene::detail {

void Builder::read_fluid_material(Reader& r, Material& material) {
  if (auto v = r.string("eos")) material.eos = value_named<Material::Eos>(*v);
  if (auto v = r.number("tait_exponent")) material.tait_exponent = *v;
  if (auto v = r.number("eos_c0")) material.eos_c0 = *v;
  if (auto v = r.number("eos_c1")) material.eos_c1 = *v;
  if (auto v = r.number("eos_c2")) material.eos_c2 = *v;
  if (auto v = r.number("eos_c3")) material.eos_c3 = *v;
  if (auto v = r.string("rheology")) material.rheology = value_named<Material::Rheology>(*v);
  if (auto v = r.number("viscosity")) material.viscosity = *v;
  if (auto v = r.number("yield_shear_rate")) material.yield_shear_rate = *v;
  if (auto v = r.number("consistency_index")) material.consistency_index = *v;
  if (auto v = r.number("flow_index")) material.flow_index = *v;
  if (auto v = r.number("fluid_shear_modulus")) material.fluid_shear_modulus = *v;
  material.artificial_stress = r.number("artificial_stress");
  const auto line_if = [&](const char* key) { return r.has(key) ? r.line(key) : 0; };
  fluid_material_keys_[material.name] = {r.line(), r.has("eos_c1"), line_if("consistency_index"), line_if("flow_index"),
                                         line_if("viscosity")};
}

void Builder::read_sph(Reader& root) {
  const toml::table* table = root.table("sph");
  if (table == nullptr) {
    if (has_fluids_) {
      const char* bodies = root.has("fluids") ? "fluids" : "inflows";
      diag_.add(root.line(bodies), "sph", std::nullopt, fmt::format("missing; the scene has [[{}]]", bodies),
                "add an [sph] table with at least particle_spacing and sound_speed, e.g. [sph] particle_spacing = "
                "0.02, sound_speed = 30.0");
    }
    return;
  }
  if (!has_fluids_) {
    diag_.add(line_of(*table), "sph", std::nullopt, "there are no fluids, so no SPH settings",
              "remove [sph] or add [[fluids]]");
    return;
  }
  Reader r(diag_, spec("sph"), *table, "sph");
  SphSettings& sph = scene_.sph;
  if (auto v = r.number("particle_spacing")) sph.particle_spacing = *v;
  if (auto v = r.number("smoothing_ratio")) sph.smoothing_ratio = *v;
  if (auto v = r.string("kernel")) sph.kernel = value_named<SphSettings::Kernel>(*v);
  if (auto v = r.string("wall_model")) sph.wall_model = value_named<SphSettings::WallModel>(*v);
  if (auto v = r.string("wall_work")) sph.wall_work = value_named<SphSettings::WallWork>(*v);
  if (auto v = r.number("wall_spacing_ratio")) {
    sph.wall_spacing_ratio = *v;
    if (sph.wall_model != SphSettings::WallModel::boundary_particles && *v != 1.0) {
      diag_.add(r.line("wall_spacing_ratio"), r.key_path("wall_spacing_ratio"), fmt::format("{}", *v),
                "the wall particles' spacing is for boundary-particle walls, but wall_model = \"penalty\" here: "
                "penalty walls have no particles",
                "remove wall_spacing_ratio, or use wall_model = \"boundary_particles\"");
    }
  }
  if (auto v = r.boolean("lagged_boundary_particles")) sph.lagged_boundary_particles = *v;
  if (auto v = r.strings("free_slip_walls")) {
    sph.free_slip_walls = *v;
    free_slip_where_ = {r.line("free_slip_walls"), r.key_path("free_slip_walls")};
  }
  if (auto v = r.number("sound_speed")) sph.sound_speed = *v;
  if (auto v = r.number("cfl")) sph.cfl = *v;
  if (auto v = r.number("artificial_viscosity")) sph.artificial_viscosity = *v;
  if (auto v = r.string("density_diffusion")) sph.density_diffusion = value_named<SphSettings::DensityDiffusion>(*v);
  if (auto v = r.number("density_diffusion_delta")) sph.density_diffusion_delta = *v;
  if (auto v = r.string("viscous_operator")) sph.viscous_operator = value_named<SphSettings::ViscousOperator>(*v);
  const auto min = r.vec3("domain_min"), max = r.vec3("domain_max");
  if (r.has("domain_min") != r.has("domain_max")) {
    const char* given = r.has("domain_min") ? "domain_min" : "domain_max";
    diag_.add(r.line(given), r.key_path(given), value_text(*r.node(given)),
              "the domain needs both corners, domain_min and domain_max", "give both corners, or neither");
  } else if (min && max) {
    if (((*max).array() <= (*min).array()).any()) {
      diag_.add(r.line("domain_max"), r.key_path("domain_max"), value_text(*r.node("domain_max")),
                fmt::format("the domain is empty or inverted: domain_max must exceed domain_min = {} on every axis",
                            value_text(*r.node("domain_min"))),
                "swap the values where domain_max <= domain_min");
    } else {
      sph.domain = Aabb{*min, *max};
      domain_line_ = r.line("domain_max");
    }
  }
  if (auto limits = r.pair("density_ratio_limits")) {
    if (!((*limits)[0] > 0 && (*limits)[0] < 1 && (*limits)[1] > 1)) {
      diag_.add(r.line("density_ratio_limits"), r.key_path("density_ratio_limits"),
                value_text(*r.node("density_ratio_limits")), "must be [min, max] with 0 < min < 1 < max",
                "give e.g. density_ratio_limits = [0.5, 2.0]");
    } else {
      sph.density_ratio_limits = *limits;
    }
  }
  read_periodic(r, "periodic_x", sph.periodic_x, periodic_line_[0]);
  read_periodic(r, "periodic_y", sph.periodic_y, periodic_line_[1]);
}

void Builder::check_lagged_boundary_particles() {
  if (!scene_.sph.lagged_boundary_particles || scene_.sph_receives_boundary_particles()) return;
  const std::string key = "sph.lagged_boundary_particles";
  diag_.add(line_of_key(key), key, "true",
            "the sph_solver receives no boundary particles here (wall_model = \"penalty\" and no particle set meets "
            "the fluid through [contact.sph_dem] model = \"boundary_particles\"), so there is nothing to lag",
            "remove lagged_boundary_particles (penalty contacts already overlap the fluid's step with the "
            "coupler's), or use boundary particles");
}

void Builder::check_free_slip_walls() {
  const auto& walls = scene_.sph.free_slip_walls;
  if (walls.empty()) return;
  const Where& where = free_slip_where_;
  const std::string value = value_of_key(where.key).value_or(join(walls));
  if (scene_.sph.wall_model != SphSettings::WallModel::boundary_particles) {
    diag_.add(where.line, where.key, value,
              "free-slip walls are boundary-particle walls, but wall_model = \"penalty\" here: penalty walls slip "
              "by their friction",
              "remove free_slip_walls, and set friction = 0.0 in [contact.sph_fem] (or in the structure's "
              "[[interactions]] with the fluid) for a wall without friction; or use wall_model = "
              "\"boundary_particles\"");
    return;
  }
  std::vector<std::string> structure_names;
  for (const Structure& structure : scene_.structures) structure_names.push_back(structure.name);
  std::vector<std::string> seen;
  for (const std::string& name : walls) {
    if (std::find(seen.begin(), seen.end(), name) != seen.end()) {
      diag_.add(where.line, where.key, value, fmt::format("names {} twice", quote_text(name)),
                "name each structure once");
      continue;
    }
    seen.push_back(name);
    if (std::find(structure_names.begin(), structure_names.end(), name) != structure_names.end()) continue;
    const auto suggestion = closest_match(name, structure_names);
    diag_.add(where.line, where.key, value,
              fmt::format("no structure is named {}{}", quote_text(name),
                          suggestion ? fmt::format(". Did you mean '{}'?", *suggestion) : std::string()),
              structure_names.empty() ? std::string("add the [[structures]] whose walls slip, or remove the key")
                                      : fmt::format("use the names of [[structures]]: {}", join(structure_names)));
  }
}

// [min, max) of a periodic axis: a period of at least two kernel supports plus one spacing,
// so that no particle sees another and its image at once (docs/physics.md).
void Builder::read_periodic(Reader& r, const char* key, std::optional<std::array<double, 2>>& out, int& line) {
  const auto span = r.pair(key);
  if (!span) return;
  const SphSettings& sph = scene_.sph;
  const double period = (*span)[1] - (*span)[0];
  const double least = 2.0 * sph.kernel_support() + sph.particle_spacing;
  if (period <= 0) {
    diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
              "the periodic span is empty or inverted: max must exceed min", "give [min, max] with min < max");
  } else if (sph.particle_spacing > 0 && period < least) {
    diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
              fmt::format("the period {} m is shorter than two kernel supports plus one spacing, 4h + dx = {} m "
                          "(h = smoothing_ratio * particle_spacing): a particle would see another and its image",
                          number_literal(period), fmt::format("{:.6g}", least)),
              fmt::format("widen the span to at least {:.6g} m or lower sph.particle_spacing", least));
  } else {
    out = *span;
    line = r.line(key);
  }
}

void Builder::read_fluid(const toml::table& table, std::size_t index) {
  const std::string path = fmt::format("fluids[{}]", index);
  Reader r(diag_, spec("fluids"), table, path);
  FluidBody body;
  body.origin = origin(r.line(), path);
  if (auto v = r.string("name")) {
    body.name = *v;
    register_body(r, body.name, false, true);
  }
  if (auto v = r.string("material")) {
    body.material = *v;
    check_material(r, body.material);
  }
  if (auto v = r.vec3("velocity")) body.velocity = *v;
  if (auto v = r.boolean("hydrostatic")) body.hydrostatic = *v;
  if (auto v = r.number("settle_time")) {
    body.settle_time = *v;
    if (*v > 0 && !body.velocity.isZero(0.0)) {
      diag_.add(r.line("settle_time"), r.key_path("settle_time"), value_text(*r.node("settle_time")),
                fmt::format("a settling body starts at rest, but its velocity is {}: the settling phase would "
                            "damp that velocity away",
                            value_text(*r.node("velocity"))),
                "remove settle_time, or set velocity = [0.0, 0.0, 0.0]");
    }
  }
  const auto shape = r.string("shape");
  if (!shape) {
    scene_.fluids.push_back(std::move(body));
    return;
  }
  r.select(*shape);
  const double dx = scene_.sph.particle_spacing;
  Aabb bounds;
  if (*shape == "box") {
    body.shape = FluidBody::Shape::box;
    const auto min = r.vec3("min"), max = r.vec3("max");
    if (min && max) {
      body.box = Aabb{*min, *max};
      bounds = body.box;
      if (((*max - *min).array() < dx).any()) {
        diag_.add(r.line("max"), r.key_path("max"), value_text(*r.node("max")),
                  fmt::format("the box must exceed min = {} by at least the particle spacing {} m on every axis, "
                              "or it holds no particle",
                              value_text(*r.node("min")), number_literal(dx)),
                  "enlarge the box or lower sph.particle_spacing");
      }
    }
  } else {
    body.shape = FluidBody::Shape::extruded_polygon;
    if (auto v = r.vec3("origin")) body.profile_origin = *v;
    if (auto v = r.number("width")) {
      body.width = *v;
      if (body.width < dx) {
        diag_.add(
            r.line("width"), r.key_path("width"), number_literal(body.width),
            fmt::format("narrower than the particle spacing {} m: the body holds no particle", number_literal(dx)),
            "widen the body or lower sph.particle_spacing");
      }
    }
    if (auto v = r.vec3("direction")) {
      if (std::abs(v->z()) > 1e-12 || v->norm() == 0) {
        diag_.add(r.line("direction"), r.key_path("direction"), value_text(*r.node("direction")),
                  "must be horizontal (z = 0) and not zero", "give e.g. direction = [1.0, 0.0, 0.0]");
      } else {
        body.direction = v->normalized();
      }
    }
    if (auto v = r.pairs("profile")) {
      body.profile = *v;
      check_profile(r, body.profile);
      const Vec3 across(-body.direction.y(), body.direction.x(), 0.0);  // z x direction
      for (const auto& [s, z] : body.profile) {
        const Vec3 base = body.profile_origin + s * body.direction;
        bounds.extend(Vec3(base.x(), base.y(), z) + 0.5 * body.width * across);
        bounds.extend(Vec3(base.x(), base.y(), z) - 0.5 * body.width * across);
      }
    }
  }
  if (scene_.sph.domain && !bounds.empty() &&
      !(scene_.sph.domain->contains(bounds.min) && scene_.sph.domain->contains(bounds.max))) {
    diag_.add(r.line(), path, std::nullopt,
              fmt::format("the body reaches outside the SPH domain (sph.domain_min/domain_max, line {})", domain_line_),
              "enlarge the domain or move the body into it");
  }
  if (!bounds.empty()) {
    check_inside_periodic_spans(bounds, r.line(), path, std::nullopt, "the body", "move the body into the span");
  }
  scene_.fluids.push_back(std::move(body));
}

// `bounds` (a fluid body's, an inflow's buffer's) lies inside every periodic span: particles are wrapped back
// into it, so a seam through a body would move part of it.
void Builder::check_inside_periodic_spans(const Aabb& bounds, int line, const std::string& key,
                                          const std::optional<std::string>& value, const std::string& what,
                                          const std::string& fix) {
  const std::optional<std::array<double, 2>>* periodic[2] = {&scene_.sph.periodic_x, &scene_.sph.periodic_y};
  for (int axis = 0; axis < 2; ++axis) {
    const auto& span = *periodic[axis];
    if (!span) continue;
    const double tolerance = 1e-9 * std::max(1.0, (*span)[1] - (*span)[0]);
    if (bounds.min[axis] < (*span)[0] - tolerance || bounds.max[axis] > (*span)[1] + tolerance) {
      const char* name = axis == 0 ? "periodic_x" : "periodic_y";
      diag_.add(line, key, value,
                fmt::format("{} spans {} = [{}, {}] m, outside the periodic span sph.{} = [{}, {}] (line {})", what,
                            axis == 0 ? "x" : "y", number_literal(bounds.min[axis]), number_literal(bounds.max[axis]),
                            name, number_literal((*span)[0]), number_literal((*span)[1]), periodic_line_[axis]),
                fmt::format("{} or widen sph.{}", fix, name));
    }
  }
}

void Builder::check_profile(Reader& r, const std::vector<std::array<double, 2>>& profile) {
  const int line = r.line("profile");
  const std::string key = r.key_path("profile");
  const std::string value = value_text(*r.node("profile"));
  const std::size_t n = profile.size();
  if (n < 3) {
    diag_.add(line, key, value, fmt::format("a polygon needs at least 3 points, not {}", n),
              "list the corners of the profile in order, e.g. [[0.0, 0.0], [10.0, 0.0], [0.0, 5.0]]");
    return;
  }
  const auto point = [&](std::size_t k) { return profile[k % n]; };
  for (std::size_t k = 0; k < n; ++k) {
    if (point(k) == point(k + 1)) {
      diag_.add(line, key, value, fmt::format("points {} and {} are the same: a zero-length edge", k, (k + 1) % n),
                "remove the repeated point");
      return;
    }
  }
  if (const auto edges = geometry::first_crossing_edges(profile, /*touching=*/false)) {
    const auto [a, b] = *edges;
    diag_.add(line, key, value, fmt::format("edge {}-{} crosses edge {}-{}", a, (a + 1) % n, b, (b + 1) % n),
              "list the points in order around the polygon, without crossings");
  }
}

// Requirements of the materials that fluids use.
void Builder::check_fluid_materials() {
  std::vector<std::string> checked;
  for (const FluidBody& body : scene_.fluids) {
    if (std::find(checked.begin(), checked.end(), body.material) != checked.end()) continue;
    checked.push_back(body.material);
    const auto material = std::find_if(scene_.materials.begin(), scene_.materials.end(),
                                       [&](const Material& m) { return m.name == body.material; });
    if (material == scene_.materials.end()) continue;
    const FluidMaterialKeys keys = fluid_material_keys_[material->name];
    const std::string path = "materials." + material->name;
    const std::string user = fmt::format(" (used by fluid '{}')", body.name);
    if (material->eos == Material::Eos::polynomial && !keys.has_eos_c1) {
      diag_.add(keys.line, path + ".eos_c1", std::nullopt, "missing; eos = \"polynomial\" needs C1" + user,
                "add eos_c1 = 20e9 (the bulk stiffness of the polynomial EOS), or use eos = \"tait\"");
    }
    using R = Material::Rheology;
    if ((material->rheology == R::newtonian || material->rheology == R::bingham) && material->viscosity <= 0) {
      diag_.add(keys.line, path + ".viscosity", number_literal(material->viscosity),
                "a newtonian or bingham fluid needs a positive viscosity" + user,
                "give viscosity > 0 (Pa s), or use rheology = \"inviscid\"");
    }
    if ((material->rheology == R::bingham || material->rheology == R::elastic_plastic) && !material->yield_stress) {
      diag_.add(keys.line, path + ".yield_stress", std::nullopt,
                "missing; a bingham or elastic_plastic fluid needs a positive yield stress" + user,
                "give yield_stress > 0 (Pa)");
    }
    if (material->rheology == R::herschel_bulkley) {
      if (keys.consistency_index_line == 0) {
        diag_.add(keys.line, path + ".consistency_index", std::nullopt,
                  "missing; a herschel_bulkley fluid needs its consistency index K (tau = tau_y + K "
                  "gamma_dot^n)" +
                      user,
                  "give consistency_index > 0 (Pa s^n), e.g. consistency_index = 5.0");
      }
      if (keys.viscosity_line != 0) {
        diag_.add(keys.viscosity_line, path + ".viscosity", number_literal(material->viscosity),
                  "herschel_bulkley does not read viscosity: its viscous part is consistency_index K and "
                  "flow_index n (K gamma_dot^n)" +
                      user,
                  "remove viscosity (flow_index = 1 with consistency_index = the plastic viscosity is bingham's "
                  "law)");
      }
    } else {
      const std::tuple<const char*, int, double> given[] = {
          {"consistency_index", keys.consistency_index_line, material->consistency_index},
          {"flow_index", keys.flow_index_line, material->flow_index}};
      for (const auto& [key, line, value] : given) {
        if (line == 0) continue;
        diag_.add(line, path + "." + key, number_literal(value),
                  std::string(key) + " is read only by rheology = \"herschel_bulkley\"" + user,
                  fmt::format("remove {}, or use rheology = \"herschel_bulkley\"", key));
      }
    }
    if (material->rheology != R::elastic_plastic && material->artificial_stress.value_or(0.0) > 0) {
      diag_.add(keys.line, path + ".artificial_stress", number_literal(*material->artificial_stress),
                "artificial stress acts on the stress tensor of an elastic_plastic fluid only" + user,
                "remove artificial_stress, or use rheology = \"elastic_plastic\"");
    }
  }
}

}  // namespace sabo::scene::detail
