// [contact]: the DEM-DEM, DEM-FEM, SPH-FEM, SPH-DEM and FEM-FEM laws: the schema of the section and its reader.

#include "libsabo/scene/detail/builder.hpp"
#include "libsabo/scene/detail/schema_tables.hpp"

namespace sabo::scene::schema::detail {

void Schema::build_sph_fem() {
  sph_fem.title = "[contact.sph_fem]";
  sph_fem.anchor = "contact-sph_fem";
  sph_fem.description =
      "Penalty contact of fluid particles against structure surfaces, computed by the coupler (paper eqs. "
      "3-6, the particle's contact radius is dx/2: the wall stands where the fluid body ends), used when "
      "`sph.wall_model = \"penalty\"`. Defaults of "
      "every fluid/structure pair; `[[interactions]]` override them per pair.";
  sph_fem.keys = {
      K("friction", Type::number).def(Scene{}.sph_fem_default.friction).ge(0).doc("Coulomb friction coefficient."),
      K("penalty_scale", Type::number).def(Scene{}.sph_fem_default.penalty_scale).gt(0).doc("k1 of eq. 6."),
      K("normal_stiffness", Type::number)
          .absent("eq. 6")
          .example("1e8")
          .unit("N/m")
          .gt(0)
          .doc("Normal stiffness replacing eq. 6."),
      K("normal_damping_ratio", Type::number)
          .def(Scene{}.sph_fem_default.normal_damping_ratio)
          .ge(0)
          .lt(1)
          .doc("Normal damping: c_n = 2 ratio sqrt(k_n m)."),
      K("tangential_damping_ratio", Type::number)
          .def(Scene{}.sph_fem_default.tangential_damping_ratio)
          .ge(0)
          .lt(1)
          .doc("Tangential damping ratio."),
  };
}

void Schema::build_sph_dem() {
  sph_dem.title = "[contact.sph_dem]";
  sph_dem.anchor = "contact-sph_dem";
  sph_dem.description =
      "Contact of fluid particles with the DEM spheres (boulders carried by the slurry), computed by the "
      "coupler. Defaults of every fluid/particle-set pair; `[[interactions]]` override them per pair. "
      "`model` picks the law (docs/physics.md, \"SPH-DEM\"):\n\n"
      "* `boundary_particles`: each sphere's surface is sampled as SPH wall particles (the layers of the "
      "structure walls) that move with it, v + w x r. The fluid's pressure and viscous stress act on them, "
      "and their sum is the force and torque on the sphere: buoyancy and drag come out of the fluid's "
      "physics. A sphere's diameter is at least 2 `particle_spacing`.\n"
      "* `penalty`: the paper's node-to-node law (eqs. 1-2): overlap delta = h_i + r_j - d, with h_i the "
      "fluid particle's contact radius dx/2; force K delta + eta v_rel,n along the line of centres, "
      "optional Coulomb `friction`. It carries no fluid pressure: a sphere feels the fluid only where "
      "particles touch it, so buoyancy comes only through contacts and is not Archimedes'.";
  sph_dem.keys = {
      K("model", Type::string)
          .def(SphDemContact{}.model)
          .doc("Contact law: boulder surfaces as wall particles, or the paper's penalty."),
      K("normal_stiffness", Type::number)
          .absent("rho0 c^2 dx, lowered so that 0.2 pi sqrt(rho0 dx^3 / K) >= cfl h / c")
          .example("2e6")
          .unit("N/m")
          .gt(0)
          .doc("Penalty stiffness K (penalty only); its pair step 0.2 pi sqrt(rho0 dx^3 / K) may not be below "
               "the SPH step cfl h / c."),
      K("normal_damping_ratio", Type::number)
          .def(SphDemContact{}.normal_damping_ratio)
          .ge(0)
          .lt(1)
          .doc("Normal damping of the penalty law: eta = 2 ratio sqrt(K m*), m* the reduced mass (penalty only)."),
      K("friction", Type::number)
          .def(SphDemContact{}.friction)
          .ge(0)
          .doc("Coulomb friction of the penalty law, tangential spring k_t = K (penalty only)."),
  };
}

void Schema::build_contact() {
  contact.title = "[contact]";
  contact.anchor = "contact";
  contact.description =
      "Contact laws between kinds of bodies. `[contact.dem_dem]` needs particles; `[contact.dem_fem]` needs "
      "particles and structures; `[contact.sph_fem]` needs fluids and structures; `[contact.sph_dem]` needs "
      "fluids and particles; `[contact.fem_fem]` needs two structures, one of them deformable.";
  contact.keys = {
      K("dem_dem", Type::table).inside(dem_dem).absent("defaults").doc("Sphere-sphere contact (dem_solver)."),
      K("dem_fem", Type::table)
          .inside(dem_fem)
          .absent("defaults")
          .doc("Sphere-structure contact (coupler), default of every pair."),
      K("sph_fem", Type::table)
          .inside(sph_fem)
          .absent("defaults")
          .doc("Fluid-structure penalty contact (coupler), default of every pair."),
      K("sph_dem", Type::table)
          .inside(sph_dem)
          .absent("defaults")
          .doc("Fluid-sphere contact (coupler), default of every pair."),
      K("fem_fem", Type::table)
          .inside(fem_fem)
          .absent("defaults (off)")
          .doc("Structure-structure contact (fem_solver), default of every pair of structures."),
  };
  dem_dem.title = "[contact.dem_dem]";
  dem_dem.anchor = "contact-dem_dem";
  dem_dem.description =
      "Sphere-sphere contact in the dem_solver, the default of every pair of materials (`pairs` override it "
      "per pair). `model` picks the law:\n\n"
      "* `linear`: the reference paper's spring-dashpot: normal stiffness from `normal_stiffness` or "
      "`normal_stiffness_scale`, dashpots from the damping ratios, tangential spring `tangential_stiffness_ratio` "
      "times k_n.\n"
      "* `hertz_mindlin`: Hertz normal spring and Mindlin no-slip tangential spring from the materials' E and "
      "nu, dashpots from the coefficient of `restitution` (as in LIGGGHTS and EDEM).\n\n"
      "Both: tangential spring capped by Coulomb `friction`. Rolling resistance (`rolling`): `constant`, the "
      "torque `rolling_friction` r_eff F_n against the relative rotation (an elastic-plastic rolling spring "
      "capped at that torque, so that a pile at rest holds), or `viscous`, the torque `rolling_viscosity` "
      "r_eff F_n (r_eff w) that grows with the rolling speed. A scene that asks for no rolling resistance "
      "(`rolling_friction = 0`) pays nothing for it. The defaults are the reference paper's boulders. Give "
      "`normal_stiffness` or `normal_stiffness_scale`, not both.";
  const std::string damping_doc = "damping as a fraction of critical damping (linear).";
  dem_dem.keys = {
      K("model", Type::string).def(DemContact{}.model).doc("Contact law."),
      K("normal_damping_ratio", Type::number)
          .def(DemContact{}.normal_damping_ratio)
          .ge(0)
          .lt(1)
          .doc("Normal " + damping_doc),
      K("tangential_damping_ratio", Type::number)
          .def(DemContact{}.tangential_damping_ratio)
          .ge(0)
          .lt(1)
          .doc("Tangential " + damping_doc + " Also the rolling spring's dashpot."),
      K("restitution", Type::number)
          .def(DemContact{}.restitution)
          .gt(0)
          .le(1)
          .doc("Coefficient of restitution of the normal impact (hertz_mindlin); 1: no damping."),
      K("friction", Type::number).def(DemContact{}.friction).ge(0).doc("Sliding friction coefficient."),
      K("rolling", Type::string).def(DemContact{}.rolling).doc("Rolling resistance model."),
      K("rolling_friction", Type::number)
          .def(DemContact{}.rolling_friction)
          .ge(0)
          .doc("Constant rolling resistance: torque = rolling_friction * r_eff * |F_n| (0: none)."),
      K("rolling_viscosity", Type::number)
          .def(DemContact{}.rolling_viscosity)
          .unit("s/m")
          .ge(0)
          .doc("Viscous rolling resistance: torque = rolling_viscosity * r_eff * |F_n| * r_eff |w_rel|."),
      K("normal_stiffness", Type::number)
          .absent("use `normal_stiffness_scale`")
          .example("1e7")
          .unit("N/m")
          .gt(0)
          .doc("Linear normal contact stiffness, the same for every pair."),
      K("normal_stiffness_scale", Type::number)
          .def(DemContact{}.normal_stiffness_scale)
          .gt(0)
          .doc("LS-DYNA's NormK: k_n = scale * K1 r1 K2 r2 / (K1 r1 + K2 r2), K the bulk modulus, r the radius."),
      K("tangential_stiffness_ratio", Type::number)
          .def(DemContact{}.tangential_stiffness_ratio)
          .gt(0)
          .doc("k_t / k_n of the linear law (2/7 keeps normal and tangential oscillations in step)."),
      K("pairs", Type::table_list)
          .inside(dem_pair)
          .absent("every pair uses the keys above")
          .example("[ { materials = [\"granite\", \"sandstone\"], model = \"hertz_mindlin\" } ]")
          .doc("Per-pair-of-materials overrides."),
  };
  dem_pair.title = "[[contact.dem_dem.pairs]]";
  dem_pair.anchor = "contact-dem_dem-pairs";
  dem_pair.description =
      "The contact law of one pair of materials (a material with itself: the same name twice), each pair at "
      "most once. Keys left out take their value from `[contact.dem_dem]`; the stiffness keys of the linear "
      "law are shared by all pairs.";
  const std::string from_dem = "as in `[contact.dem_dem]`";
  dem_pair.keys = {
      K("materials", Type::string_list)
          .required("[\"granite\", \"sandstone\"]")
          .allowed("two `[materials.NAME]`")
          .doc("The two materials."),
      K("model", Type::string).absent(from_dem).example("\"hertz_mindlin\"").choices_of<DemLaw>().doc("Contact law."),
      K("normal_damping_ratio", Type::number).absent(from_dem).example("0.7").ge(0).lt(1).doc("Normal " + damping_doc),
      K("tangential_damping_ratio", Type::number)
          .absent(from_dem)
          .example("0.4")
          .ge(0)
          .lt(1)
          .doc("Tangential " + damping_doc),
      K("restitution", Type::number)
          .absent(from_dem)
          .example("0.3")
          .gt(0)
          .le(1)
          .doc("Coefficient of restitution (hertz_mindlin; particle sets only)."),
      K("friction", Type::number).absent(from_dem).example("0.5").ge(0).doc("Sliding friction coefficient."),
      K("rolling", Type::string)
          .absent(from_dem)
          .example("\"viscous\"")
          .choices_of<RollingModel>()
          .doc("Rolling resistance model."),
      K("rolling_friction", Type::number)
          .absent(from_dem)
          .example("0.1")
          .ge(0)
          .doc("Constant rolling resistance coefficient."),
      K("rolling_viscosity", Type::number)
          .absent(from_dem)
          .example("0.05")
          .unit("s/m")
          .ge(0)
          .doc("Viscous rolling resistance coefficient."),
  };
  dem_fem.title = "[contact.dem_fem]";
  dem_fem.anchor = "contact-dem_fem";
  dem_fem.description =
      "Penalty contact of spheres against structure surfaces, computed by the coupler (paper eqs. 3-6). "
      "These are the settings of every particle-set/structure pair; `[[interactions]]` override them per "
      "pair. `model = \"hertz_mindlin\"` replaces the penalty spring by the Hertz-Mindlin (no-slip) law of a "
      "sphere against a flat face, from the E and nu of the sphere's and the structure's materials, with "
      "dashpots from `restitution`; the penalty and damping-ratio keys then do not apply. Rolling resistance "
      "(`rolling`, `rolling_friction`, `rolling_viscosity`: the models of `[contact.dem_dem]` with r_eff the "
      "sphere's radius) is off by default here.";
  dem_fem.keys = {
      K("model", Type::string)
          .def(SurfaceContact{}.model)
          .doc("Contact law: the paper's penalty (eqs. 3-6) or Hertz-Mindlin."),
      K("restitution", Type::number)
          .def(SurfaceContact{}.restitution)
          .gt(0)
          .le(1)
          .doc("Coefficient of restitution (hertz_mindlin only; refused with the penalty law); 1: no damping."),
      K("friction", Type::number).def(SurfaceContact{}.friction).ge(0).doc("Coulomb friction coefficient."),
      K("penalty_scale", Type::number)
          .def(SurfaceContact{}.penalty_scale)
          .gt(0)
          .doc("k1 of eq. 6: k_n = k1 K s^2 / V (solid face) or k1 K s / max_diagonal (shell)."),
      K("normal_stiffness", Type::number)
          .absent("eq. 6")
          .example("1e8")
          .unit("N/m")
          .gt(0)
          .doc("Normal stiffness replacing eq. 6."),
      K("normal_damping_ratio", Type::number)
          .def(SurfaceContact{}.normal_damping_ratio)
          .ge(0)
          .lt(1)
          .doc("Normal damping: c_n = 2 ratio sqrt(k_n m)."),
      K("tangential_damping_ratio", Type::number)
          .def(SurfaceContact{}.tangential_damping_ratio)
          .ge(0)
          .lt(1)
          .doc("Tangential damping ratio (and the rolling spring's dashpot)."),
      K("rolling", Type::string)
          .def(SurfaceContact{}.rolling)
          .doc("Rolling resistance model against the structure (as `[contact.dem_dem]`, r_eff = the sphere's "
               "radius)."),
      K("rolling_friction", Type::number)
          .def(SurfaceContact{}.rolling_friction)
          .ge(0)
          .doc("Constant rolling resistance against the structure: an elastic-plastic rolling spring capped at "
               "rolling_friction * r * |F_n| (0: none)."),
      K("rolling_viscosity", Type::number)
          .def(SurfaceContact{}.rolling_viscosity)
          .unit("s/m")
          .ge(0)
          .doc("Viscous rolling resistance against the structure: torque = rolling_viscosity * r * |F_n| * r |w|."),
  };
}

void Schema::build_fem_fem() {
  fem_fem.title = "[contact.fem_fem]";
  fem_fem.anchor = "contact-fem_fem";
  fem_fem.description =
      "Contact between structures, computed by the fem_solver, which holds both sides (docs/physics.md, "
      "\"Structure against structure\"): node-to-segment penalty contact with the law of `[contact.dem_fem]` "
      "(paper eqs. 3-6): every surface node of one structure is a point against the faces of the other, both "
      "ways, with the face's eq. 6 stiffness (solid face: k1 K s^2 / V; shell or rigid face: k1 K s / L), "
      "a tangential spring with Coulomb `friction`, and dashpots from the damping ratios with the reduced mass "
      "of the node and the face. Faces of eroded elements leave the contact, exposed ones join. A structure "
      "never meets its own faces, two rigid structures never meet. Off unless `enabled = true` (every pair "
      "of structures, at least one deformable) or a pair's `[[interactions]]` table names two structures "
      "(those pairs only, with these settings as their defaults). The spring energy and the dissipated work "
      "are the fem_solver's (energy.csv: `solver_elastic`, `dissipated`); the contact's stable step 0.2 pi "
      "sqrt(m / k_n) is part of the fem_solver's.";
  fem_fem.keys = {
      K("enabled", Type::boolean)
          .def(Scene{}.fem_fem_default.enabled)
          .doc("`true`: every pair of structures (at least one deformable) is in contact."),
      K("friction", Type::number).def(Scene{}.fem_fem_default.friction).ge(0).doc("Coulomb friction coefficient."),
      K("penalty_scale", Type::number)
          .def(Scene{}.fem_fem_default.penalty_scale)
          .gt(0)
          .doc("k1 of eq. 6: k_n = k1 K s^2 / V (solid face) or k1 K s / max_diagonal (shell or rigid face)."),
      K("normal_stiffness", Type::number)
          .absent("eq. 6")
          .example("1e8")
          .unit("N/m")
          .gt(0)
          .doc("Normal stiffness replacing eq. 6."),
      K("normal_damping_ratio", Type::number)
          .def(Scene{}.fem_fem_default.normal_damping_ratio)
          .ge(0)
          .lt(1)
          .doc("Normal damping: c_n = 2 ratio sqrt(k_n m), m the reduced mass of the node and the face's "
               "lightest node (a rigid side is infinitely heavy)."),
      K("tangential_damping_ratio", Type::number)
          .def(Scene{}.fem_fem_default.tangential_damping_ratio)
          .ge(0)
          .lt(1)
          .doc("Tangential damping ratio."),
  };
}

}  // namespace sabo::scene::schema::detail

namespace sabo::scene::detail {

// The law of a sphere-structure pair: penalty (eqs. 3-6) or Hertz-Mindlin. `contact` holds the law this
// table starts from (the defaults, or [contact.dem_fem] for an interaction); restitution is refused where
// the resulting law is the penalty one, which has no use for it.
void Builder::read_surface_contact_law(Reader& r, SurfaceContact& contact, const char* model_fix) {
  if (auto v = r.string("model")) {
    contact.model = value_named<SurfaceContact::Model>(*v);
  }
  if (auto v = r.number("restitution")) contact.restitution = *v;
  if (r.has("restitution") && contact.model != SurfaceContact::Model::hertz_mindlin) {
    diag_.add(r.line("restitution"), r.key_path("restitution"), value_text(*r.node("restitution")),
              "restitution applies to model = \"hertz_mindlin\", and this contact uses the penalty law",
              fmt::format("remove restitution, or set model = \"hertz_mindlin\" {}", model_fix));
  }
}

// The penalty keys every particle-structure pair has.
void Builder::read_surface_contact(Reader& r, SurfaceContact& contact) {
  if (auto v = r.number("friction")) contact.friction = *v;
  if (auto v = r.number("penalty_scale")) contact.penalty_scale = *v;
  if (auto v = r.number("normal_stiffness")) contact.normal_stiffness = *v;
  if (auto v = r.number("normal_damping_ratio")) contact.normal_damping_ratio = *v;
  if (auto v = r.number("tangential_damping_ratio")) contact.tangential_damping_ratio = *v;
}

// A sphere's rolling resistance against a structure ([contact.dem_fem] or a set's interaction): the
// viscosity only with the viscous model, and a viscous model only with a viscosity.
void Builder::read_surface_rolling(Reader& r, SurfaceContact& contact) {
  if (auto v = r.string("rolling")) contact.rolling = value_named<RollingModel>(*v);
  if (auto v = r.number("rolling_friction")) contact.rolling_friction = *v;
  if (auto v = r.number("rolling_viscosity")) contact.rolling_viscosity = *v;
  if (r.has("rolling_viscosity") && contact.rolling != RollingModel::viscous) {
    diag_.add(r.line("rolling_viscosity"), r.key_path("rolling_viscosity"), value_text(*r.node("rolling_viscosity")),
              "rolling_viscosity applies to rolling = \"viscous\", and this contact uses the constant model",
              "remove rolling_viscosity, or set rolling = \"viscous\"");
  }
  if (r.has("rolling") && contact.rolling == RollingModel::viscous && !(contact.rolling_viscosity > 0)) {
    diag_.add(r.line("rolling"), r.key_path("rolling"), "\"viscous\"",
              "viscous rolling resistance needs rolling_viscosity > 0",
              "give rolling_viscosity (s/m), e.g. rolling_viscosity = 0.05");
  }
}

// The keys of one DEM-DEM contact law ([contact.dem_dem] or one of its pairs).
void Builder::read_dem_law(Reader& r, DemContactLaw& law) {
  if (auto v = r.string("model")) law.model = value_named<DemLaw>(*v);
  if (auto v = r.number("normal_damping_ratio")) law.normal_damping_ratio = *v;
  if (auto v = r.number("tangential_damping_ratio")) law.tangential_damping_ratio = *v;
  if (auto v = r.number("restitution")) law.restitution = *v;
  if (auto v = r.number("friction")) law.friction = *v;
  if (auto v = r.string("rolling")) law.rolling = value_named<RollingModel>(*v);
  if (auto v = r.number("rolling_friction")) law.rolling_friction = *v;
  if (auto v = r.number("rolling_viscosity")) law.rolling_viscosity = *v;
}

// Keys that the law of this table does not use are errors, not silently ignored.
void Builder::check_dem_law_keys(Reader& r, const DemContactLaw& law, bool any_hertz, bool any_viscous) {
  if (r.has("restitution") && !any_hertz) {
    diag_.add(r.line("restitution"), r.key_path("restitution"), value_text(*r.node("restitution")),
              "restitution applies to model = \"hertz_mindlin\", and no pair uses it",
              "remove restitution, or set model = \"hertz_mindlin\"");
  }
  if (r.has("rolling_viscosity") && !any_viscous) {
    diag_.add(r.line("rolling_viscosity"), r.key_path("rolling_viscosity"), value_text(*r.node("rolling_viscosity")),
              "rolling_viscosity applies to rolling = \"viscous\", and no pair uses it",
              "remove rolling_viscosity, or set rolling = \"viscous\"");
  }
  if (law.rolling == RollingModel::viscous && !(law.rolling_viscosity > 0) && (r.has("rolling"))) {
    diag_.add(r.line("rolling"), r.key_path("rolling"), "\"viscous\"",
              "viscous rolling resistance needs rolling_viscosity > 0",
              "give rolling_viscosity (s/m), e.g. rolling_viscosity = 0.05");
  }
}

void Builder::read_contact(Reader& root) {
  const toml::table* table = root.table("contact");
  Reader contact(diag_, spec("contact"), table != nullptr ? *table : empty_table(), "contact");

  const toml::table* dem_dem = contact.table("dem_dem");
  if (dem_dem != nullptr && !has_particles_) {
    diag_.add(line_of(*dem_dem), "contact.dem_dem", std::nullopt, "there are no particles, so no sphere-sphere contact",
              "remove [contact.dem_dem] or add [[particles]]");
  }
  Reader dd(diag_, spec("contact-dem_dem"), dem_dem != nullptr ? *dem_dem : empty_table(), "contact.dem_dem");
  DemContact& dem = scene_.dem_contact;
  read_dem_law(dd, dem);
  if (auto v = dd.number("normal_stiffness")) dem.normal_stiffness = *v;
  if (auto v = dd.number("normal_stiffness_scale")) dem.normal_stiffness_scale = *v;
  if (auto v = dd.number("tangential_stiffness_ratio")) dem.tangential_stiffness_ratio = *v;
  if (dd.has("normal_stiffness") && dd.has("normal_stiffness_scale")) {
    diag_.add(dd.line("normal_stiffness_scale"), dd.key_path("normal_stiffness_scale"),
              value_text(*dd.node("normal_stiffness_scale")),
              "give either normal_stiffness or normal_stiffness_scale, not both", "remove one of the two keys");
  }
  std::vector<Reader> pair_readers;
  std::vector<DemContactLaw> pair_laws;  // of every pair table, valid or not, for the key checks
  if (const toml::array* pairs = dd.table_list("pairs")) {
    std::map<std::pair<std::string, std::string>, int> seen;
    pair_readers.reserve(pairs->size());
    for (std::size_t k = 0; k < pairs->size(); ++k) {
      const std::string path = fmt::format("contact.dem_dem.pairs[{}]", k);
      Reader& r = pair_readers.emplace_back(diag_, spec("contact-dem_dem-pairs"), *pairs->get(k)->as_table(), path);
      DemPairLaw pair;
      pair.origin = origin(r.line(), path);
      pair.law = static_cast<const DemContactLaw&>(dem);
      read_dem_law(r, pair.law);
      pair_laws.push_back(pair.law);
      const auto materials = r.strings("materials");
      if (!materials) continue;
      const int line = r.line("materials");
      const std::string value = value_text(*r.node("materials"));
      if (materials->size() != 2) {
        diag_.add(line, r.key_path("materials"), value,
                  fmt::format("a pair names exactly two materials, not {}", materials->size()),
                  "write materials = [\"A\", \"B\"] (the same name twice for a material with itself)");
        continue;
      }
      bool known = true;
      for (const auto& name : *materials) {
        if (std::find(material_names_.begin(), material_names_.end(), name) != material_names_.end()) continue;
        known = false;
        const auto suggestion = closest_match(name, material_names_);
        diag_.add(line, r.key_path("materials"), value,
                  fmt::format("no material is named {}{}", quote_text(name),
                              suggestion ? fmt::format(". Did you mean '{}'?", *suggestion) : std::string()),
                  fmt::format("use the names of [materials.NAME]: {}", join(material_names_)));
      }
      if (!known) continue;
      pair.material_a = std::min((*materials)[0], (*materials)[1]);
      pair.material_b = std::max((*materials)[0], (*materials)[1]);
      auto [it, inserted] = seen.try_emplace({pair.material_a, pair.material_b}, line);
      if (!inserted) {
        diag_.add(line, r.key_path("materials"), value,
                  fmt::format("this pair of materials is already given at line {}", it->second),
                  "merge the two tables of this pair");
        continue;
      }
      dem.pairs.push_back(std::move(pair));
    }
  }
  bool any_hertz = dem.model == DemLaw::hertz_mindlin, any_viscous = dem.rolling == RollingModel::viscous;
  for (const auto& pair : dem.pairs) {
    any_hertz = any_hertz || pair.law.model == DemLaw::hertz_mindlin;
    any_viscous = any_viscous || pair.law.rolling == RollingModel::viscous;
  }
  check_dem_law_keys(dd, dem, any_hertz, any_viscous);
  for (std::size_t k = 0; k < pair_readers.size(); ++k) {
    const DemContactLaw& law = pair_laws[k];
    check_dem_law_keys(pair_readers[k], law, law.model == DemLaw::hertz_mindlin, law.rolling == RollingModel::viscous);
  }

  const toml::table* dem_fem = contact.table("dem_fem");
  if (dem_fem != nullptr && !(has_particles_ && has_structures_)) {
    diag_.add(line_of(*dem_fem), "contact.dem_fem", std::nullopt,
              "sphere-structure contact needs both particles and structures",
              "remove [contact.dem_fem] or add the missing [[particles]] or [[structures]]");
  }
  Reader df(diag_, spec("contact-dem_fem"), dem_fem != nullptr ? *dem_fem : empty_table(), "contact.dem_fem");
  read_surface_contact_law(df, scene_.dem_fem_default, "in [contact.dem_fem]");
  read_surface_contact(df, scene_.dem_fem_default);
  read_surface_rolling(df, scene_.dem_fem_default);

  const toml::table* sph_fem = contact.table("sph_fem");
  if (sph_fem != nullptr && !(has_fluids_ && has_structures_)) {
    diag_.add(line_of(*sph_fem), "contact.sph_fem", std::nullopt,
              "fluid-structure contact needs both fluids and structures",
              "remove [contact.sph_fem] or add the missing [[fluids]] or [[structures]]");
  }
  Reader sf(diag_, spec("contact-sph_fem"), sph_fem != nullptr ? *sph_fem : empty_table(), "contact.sph_fem");
  read_surface_contact(sf, scene_.sph_fem_default);

  const toml::table* sph_dem = contact.table("sph_dem");
  if (sph_dem != nullptr && !(has_fluids_ && has_particles_)) {
    diag_.add(line_of(*sph_dem), "contact.sph_dem", std::nullopt,
              "fluid-sphere contact needs both fluids and particles",
              "remove [contact.sph_dem] or add the missing [[fluids]] or [[particles]]");
  }
  const toml::table* fem_fem = contact.table("fem_fem");
  if (fem_fem != nullptr && !deformable_pair_possible()) {
    diag_.add(line_of(*fem_fem), "contact.fem_fem", std::nullopt,
              "structure-structure contact needs two structures, one of them deformable",
              "remove [contact.fem_fem], or add the structures (rigid = false for a deformable one)");
  }
  Reader ff(diag_, spec("contact-fem_fem"), fem_fem != nullptr ? *fem_fem : empty_table(), "contact.fem_fem");
  if (auto v = ff.boolean("enabled")) scene_.fem_fem_default.enabled = *v;
  read_surface_contact(ff, scene_.fem_fem_default);

  Reader sd(diag_, spec("contact-sph_dem"), sph_dem != nullptr ? *sph_dem : empty_table(), "contact.sph_dem");
  read_sph_dem_contact(sd, scene_.sph_dem_default);
  if (sph_dem != nullptr) {
    sph_dem_default_where_ = {sd.has("normal_stiffness") ? sd.line("normal_stiffness") : line_of(*sph_dem),
                              sd.has("normal_stiffness") ? "contact.sph_dem.normal_stiffness" : "contact.sph_dem"};
  }
}

// The keys of a fluid/particle-set contact ([contact.sph_dem] or an interaction of the two).
void Builder::read_sph_dem_contact(Reader& r, SphDemContact& contact) {
  if (auto v = r.string("model")) {
    contact.model = value_named<SphDemContact::Model>(*v);
  }
  if (auto v = r.number("normal_stiffness")) contact.normal_stiffness = *v;
  if (auto v = r.number("normal_damping_ratio")) contact.normal_damping_ratio = *v;
  if (auto v = r.number("friction")) contact.friction = *v;
}

// Whether two structures, one deformable, are in the scene (FEM-FEM contact can exist).
bool Builder::deformable_pair_possible() const {
  const bool deformable =
      std::any_of(scene_.structures.begin(), scene_.structures.end(), [](const Structure& s) { return !s.rigid; });
  return scene_.structures.size() >= 2 && deformable;
}

Builder::Where Builder::sph_dem_where(const std::string& fluid, const std::string& set) const {
  const auto it = sph_dem_where_.find({fluid, set});
  return it != sph_dem_where_.end() ? it->second : sph_dem_default_where_;
}

// Fluid/particle-set contacts (after every body, [sph] and the interactions are read): boulder sizes for
// boundary particles, one law per set against every fluid, a penalty stiffness the SPH step can carry,
// and spheres starting inside a fluid only where their places are known before the run.
void Builder::check_sph_dem() {
  if (!has_fluids_ || !has_particles_ || !(scene_.sph.particle_spacing > 0) || !(scene_.sph.sound_speed > 0)) return;
  if (std::any_of(scene_.fluids.begin(), scene_.fluids.end(), [&](const FluidBody& f) {
        return std::find(material_names_.begin(), material_names_.end(), f.material) == material_names_.end();
      })) {
    return;  // reported already; the stiffness needs the fluid's density
  }
  const double dx = scene_.sph.particle_spacing;
  const auto material_of = [&](const std::string& name) -> const Material& {
    return *std::find_if(scene_.materials.begin(), scene_.materials.end(),
                         [&](const Material& m) { return m.name == name; });
  };
  bool settled_before = false;
  for (const ParticleSet& set : scene_.particle_sets) {
    const bool position_unknown = set.kind == ParticleSet::Kind::fill && (settled_before || set.settle_time > 0);
    settled_before = settled_before || (set.kind == ParticleSet::Kind::fill && set.settle_time > 0);
    const std::string set_key = set.origin.key;
    bool any_boundary = false, any_other = false;
    std::string boundary_fluid, other_fluid;
    for (const FluidBody& fluid : scene_.fluids) {
      const SphDemContact contact = scene_.sph_dem_contact(fluid.name, set.name);
      const bool boundary = contact.enabled && contact.model == SphDemContact::Model::boundary_particles;
      (boundary ? any_boundary : any_other) = true;
      (boundary ? boundary_fluid : other_fluid) = fluid.name;
      if (contact.enabled && contact.model == SphDemContact::Model::penalty && contact.normal_stiffness &&
          material_names_.end() != std::find(material_names_.begin(), material_names_.end(), fluid.material)) {
        // The materials are not sorted yet: the pair step from the fluid's own density.
        const double rho0 = material_of(fluid.material).density;
        const double pair_dt = physics::spring_stable_dt(rho0 * dx * dx * dx, *contact.normal_stiffness);
        const double sph_dt = scene_.sph.cfl * scene_.sph.smoothing_length() / scene_.sph.sound_speed;
        if (pair_dt < sph_dt) {
          const double largest = physics::stiffness_for_stable_dt(rho0 * dx * dx * dx, sph_dt);
          const Where where = sph_dem_where(fluid.name, set.name);
          diag_.add(
              where.line, where.key, number_literal(*contact.normal_stiffness),
              fmt::format("the penalty spring of fluid '{}' against particle set '{}' has the stable step "
                          "0.2 pi sqrt(m / K) = {:.3g} s (m = rho0 dx^3 = {:.3g} kg), below the SPH step "
                          "cfl h / c = {:.3g} s: every step of the run would shrink to {:.2g} of the SPH's, "
                          "or the spring would be unstable at the SPH step",
                          fluid.name, set.name, pair_dt, rho0 * dx * dx * dx, sph_dt, pair_dt / sph_dt),
              fmt::format("give normal_stiffness <= {:.3g} N/m, or leave it out for the derived stiffness", largest));
        }
      }
      if (!contact.enabled) continue;
      if (!position_unknown || !set.region.overlaps(fluid.bounds())) continue;
      diag_.add(set.origin.line, set_key + ".fill", std::nullopt,
                fmt::format("the fill region of particle set '{}' reaches into fluid body '{}'{}: where its spheres "
                            "come to rest is only known once the dem_solver has settled them, so the sph_solver "
                            "cannot leave their places free of fluid",
                            set.name, fluid.name,
                            set.settle_time > 0 ? " and the set settles (settle_time)"
                                                : " and an earlier fill set settles, which moves its obstacles"),
                "move the fill region out of the fluid body (e.g. above it: the spheres fall in), list the "
                "spheres, or drop settle_time");
    }
    if (any_boundary && any_other) {
      const Where where = sph_dem_where(other_fluid, set.name);
      diag_.add(where.line, where.key, std::nullopt,
                fmt::format("particle set '{}' meets fluid '{}' as boundary particles but fluid '{}' otherwise; "
                            "the sph_solver sees a boulder's wall particles whatever fluid body is near it",
                            set.name, boundary_fluid, other_fluid),
                "give the set the same contact model (and enabled) against every fluid body");
    }
    if (!any_boundary) continue;
    double smallest = std::numeric_limits<double>::infinity();
    if (set.kind == ParticleSet::Kind::list) {
      for (const Sphere& sphere : set.spheres) smallest = std::min(smallest, 2 * sphere.radius);
    } else {
      smallest = set.diameter_min;
    }
    if (smallest < kMinBoundaryParticleDiameter * dx) {
      diag_.add(set.origin.line, set_key + (set.kind == ParticleSet::Kind::list ? ".spheres" : ".fill"), std::nullopt,
                fmt::format("a sphere of diameter {:g} m spans {:.2g} SPH spacings (dx = {:g} m); as boundary "
                            "particles a boulder needs at least {:g} spacings to have a surface the fluid can push",
                            smallest, smallest / dx, dx, kMinBoundaryParticleDiameter),
                fmt::format("use spheres of at least {:g} m, a finer sph.particle_spacing (<= {:g} m), or model = "
                            "\"penalty\" for this set (in [contact.sph_dem] or an interaction of '{}' with the fluid)",
                            kMinBoundaryParticleDiameter * dx, smallest / kMinBoundaryParticleDiameter, set.name));
    }
  }
}

}  // namespace sabo::scene::detail
