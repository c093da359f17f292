#include "libsabo/scene/schema.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "libsabo/scene/scene.hpp"

namespace sabo::scene::schema {
namespace {

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

  Schema() {
    build_root();
    build_run();
    build_solvers();
    build_materials();
    build_particles();
    build_structures();
    build_sph();
    build_contact();
    build_sph_fem();
    build_sph_dem();
    build_fem_fem();
    build_interactions();
    build_recording();
    build_gauges();
    build_sensors();
  }

  [[nodiscard]] std::vector<const Table*> ordered() const {
    return {&root,        &run,       &solvers,   &solver,     &materials,      &material, &particles,
            &sphere,      &fill,      &structure, &constraint, &constraint_box, &sph,      &fluid,
            &contact,     &dem_dem,   &dem_pair,  &dem_fem,    &sph_fem,        &sph_dem,  &fem_fem,
            &interaction, &recording, &gauge,     &sensor};
  }

 private:
  void build_root() {
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
        K("sensors", Type::table_list)
            .inside(sensor)
            .absent("no sensors")
            .doc("Patches of structures whose force and mean pressure the coupler writes (`sensors.csv`)."),
    };
  }

  void build_run() {
    run.title = "[run]";
    run.anchor = "run";
    run.description = "Run control: how long, how often to write output, how the processes talk.";
    run.keys = {
        K("end_time", Type::number).required("10.0").unit("s").gt(0).doc("Simulated time at which the run ends."),
        K("output_interval", Type::number)
            .required("0.1")
            .unit("s")
            .gt(0)
            .doc("Simulated time between two output frames (VTK, forces.csv)."),
        K("endpoint", Type::string)
            .def("\"ipc\"")
            .allowed("`\"ipc\"` or `\"tcp://HOST:PORT\"`")
            .doc("Where the coupler listens: `ipc` is a socket in the run folder; `tcp://HOST:PORT` lets solvers "
                 "run on other hosts (port 1-65535)."),
        K("gravity", Type::vec3).def("[0.0, 0.0, -9.81]").unit("m/s^2").doc("Gravitational acceleration (z is up)."),
        K("hang_timeout", Type::number)
            .def("10.0")
            .unit("s")
            .gt(0)
            .doc("Wall time after which a silent process is declared hung and the run is stopped."),
        K("max_dt", Type::number)
            .absent("no limit")
            .example("1e-3")
            .unit("s")
            .gt(0)
            .doc("Upper bound on the coupled time step."),
        K("checkpoint_interval", Type::number)
            .absent("a tenth of `end_time`")
            .example("0.5")
            .unit("s")
            .ge(0)
            .doc("Simulated time between two checkpoints: every process writes its whole state at the same step "
                 "into `RUN_DIR/checkpoints/<role>_<step>.h5`, from which one process is restarted while the others "
                 "wait (docs/restart.md). `0`: no checkpoints."),
        K("checkpoints_kept", Type::integer)
            .def("2")
            .ge(1)
            .doc("How many checkpoints of each process are kept (the newest; older ones are removed)."),
        K("restart", Type::string)
            .def("\"auto\"")
            .allowed("`\"auto\"` or `\"off\"`")
            .doc("`\"auto\"`: a solver killed by a signal (a crash, kill -9, out of memory) is started again from its "
                 "newest "
                 "checkpoint while the others wait; the coupler feeds it the StepForces it was sent since then and "
                 "checks that it sends the same states to the bit before it rejoins (docs/restart.md). `\"off\"`: "
                 "the run stops."),
        K("max_restarts", Type::integer)
            .def("3")
            .ge(0)
            .doc("Restarts allowed per solver process in one run; one more death stops the run."),
    };
  }

  void build_solvers() {
    solvers.title = "[solvers]";
    solvers.anchor = "solvers";
    solvers.description =
        "One table per solver role: `[solvers.sph]`, `[solvers.dem]`, `[solvers.fem]`. A role runs only when "
        "the scene's bodies need it (`[[fluids]]` need the sph_solver, `[[particles]]` the dem_solver, "
        "`[[structures]]` the fem_solver). A table for a role that no body needs is an error. A needed role without a "
        "table uses the built executable and `beta = 1.0`.";
    const std::string role_doc = "Settings of this role (see below).";
    solvers.keys = {
        K("sph", Type::table).inside(solver).absent("defaults").doc(role_doc),
        K("dem", Type::table).inside(solver).absent("defaults").doc(role_doc),
        K("fem", Type::table).inside(solver).absent("defaults").doc(role_doc),
    };
    solver.title = "[solvers.ROLE]";
    solver.anchor = "solvers-role";
    solver.description =
        "Settings of one solver process. Any program that speaks the protocol can replace the built solver.";
    solver.keys = {
        K("command", Type::string_list)
            .absent("the built executable (`sph_solver`, `dem_solver`, `fem_solver`)")
            .example("[\"/opt/my_dem/bin/dem\", \"--fast\"]")
            .doc("Program and fixed arguments that replace the built solver; the supervisor appends "
                 "`--scene`, `--coupler` and `--out`. The program is an absolute path, a path relative to the "
                 "scene file's folder (when it contains a `/`), or a name found on `PATH`."),
        K("beta", Type::number)
            .def("1.0")
            .gt(0)
            .le(1)
            .doc("Safety factor on this solver's stable time step (paper eq. 7): the coupled step is "
                 "`min(beta_i * stable_dt_i)`."),
    };
  }

  void build_materials() {
    materials.title = "[materials]";
    materials.anchor = "materials";
    materials.description =
        "Named materials, one table each: `[materials.granite]`. Names are letters, digits, `_` and `-`. "
        "Material ids in the protocol are the indices of the names in sorted order.";
    material.title = "[materials.NAME]";
    material.anchor = "materials-name";
    material.description =
        "Linear elastic constants of one material. A material used by a fluid body also has an equation of "
        "state and a rheology (the keys from `eos` on; the SPH solver reads them only for fluids); its "
        "`density` is the rest density rho0.\n\n"
        "* `eos = \"tait\"`: p = B ((rho/rho0)^gamma - 1), B = rho0 c^2 / gamma, c = `sph.sound_speed`.\n"
        "* `eos = \"polynomial\"` (LS-DYNA's linear polynomial, the paper's slurry): p = C0 + s (C1 mu + C2 mu^2 "
        "+ C3 mu^3), mu = rho/rho0 - 1, s = rho0 c^2 / C1: the artificial sound speed sets the stiffness, "
        "the coefficients the shape.\n"
        "* `rheology`: `inviscid` (artificial viscosity only); `newtonian` (dynamic `viscosity`); `bingham` "
        "(Papanastasiou-regularised, eta = `viscosity` + `yield_stress` (1 - exp(-gamma_dot / "
        "`yield_shear_rate`)) / gamma_dot); `herschel_bulkley` (tau = tau_y + K gamma_dot^n, eta = "
        "`consistency_index` max(gamma_dot, `yield_shear_rate`)^(`flow_index` - 1) + `yield_stress` (1 - "
        "exp(-gamma_dot / `yield_shear_rate`)) / gamma_dot: the yield term regularised as bingham's "
        "(Papanastasiou), the power law held at its value at `yield_shear_rate` below that rate so that a "
        "shear-thinning fluid's viscosity stays bounded; `yield_stress` absent: a power-law fluid); "
        "`elastic_plastic` (the paper's MAT_ELASTIC_PLASTIC_HYDRO: deviatoric stress by the Jaumann rate with "
        "shear modulus `fluid_shear_modulus`, von Mises yield `yield_stress`, radial return; `viscosity` "
        "optional). gamma_dot = sqrt(2 D':D'), so that the yield stresses act as von Mises yield in shear; the "
        "viscous stress 2 eta D enters the momentum by `sph.viscous_operator`.";
    material.keys = {
        K("density", Type::number).required("3000.0").unit("kg/m^3").gt(0).doc("Mass density."),
        K("youngs_modulus", Type::number).required("30e9").unit("Pa").gt(0).doc("Young's modulus E."),
        K("poisson_ratio", Type::number).required("0.3").ge(0).lt(0.5).doc("Poisson's ratio nu."),
        K("eos", Type::string).def("\"tait\"").choices({"tait", "polynomial"}).doc("Fluids: equation of state."),
        K("tait_exponent", Type::number).def("7.0").ge(1).doc("Fluids, Tait: exponent gamma."),
        K("eos_c0", Type::number).def("0.0").unit("Pa").doc("Fluids, polynomial: C0."),
        K("eos_c1", Type::number)
            .absent("required with eos = \"polynomial\"")
            .example("20e9")
            .unit("Pa")
            .gt(0)
            .doc("Fluids, polynomial: C1."),
        K("eos_c2", Type::number).def("0.0").unit("Pa").doc("Fluids, polynomial: C2."),
        K("eos_c3", Type::number).def("0.0").unit("Pa").doc("Fluids, polynomial: C3."),
        K("rheology", Type::string)
            .def("\"inviscid\"")
            .choices({"inviscid", "newtonian", "bingham", "herschel_bulkley", "elastic_plastic"})
            .doc("Fluids: constitutive model of the deviatoric stress."),
        K("viscosity", Type::number)
            .def("0.0")
            .unit("Pa s")
            .ge(0)
            .doc("Fluids: dynamic viscosity (newtonian, > 0), plastic viscosity (bingham, > 0), extra viscosity "
                 "(elastic_plastic)."),
        K("yield_shear_rate", Type::number)
            .def("1.0")
            .unit("1/s")
            .gt(0)
            .doc("Fluids, bingham and herschel_bulkley: shear rate below which the regularised law turns viscous "
                 "(largest viscosity `viscosity` + `yield_stress` / `yield_shear_rate`; herschel_bulkley with "
                 "`flow_index` <= 1: `consistency_index` `yield_shear_rate`^(`flow_index` - 1) + `yield_stress` / "
                 "`yield_shear_rate`). Below it a regularised fluid creeps (at about `yield_shear_rate` times "
                 "stress / `yield_stress`); the explicit viscous step falls in proportion to it."),
        K("consistency_index", Type::number)
            .absent("required with rheology = \"herschel_bulkley\"")
            .example("5.0")
            .unit("Pa s^n")
            .gt(0)
            .doc("Fluids, herschel_bulkley: consistency index K of tau = tau_y + K gamma_dot^n."),
        K("flow_index", Type::number)
            .def("1.0")
            .gt(0)
            .le(2)
            .doc("Fluids, herschel_bulkley: flow index n of tau = tau_y + K gamma_dot^n (< 1 shear-thinning, 1 "
                 "bingham, > 1 shear-thickening)."),
        K("fluid_shear_modulus", Type::number)
            .absent("E / (2 (1 + nu)) of this material")
            .example("1.68e6")
            .unit("Pa")
            .gt(0)
            .doc("Fluids, elastic_plastic: shear modulus G."),
        K("artificial_stress", Type::number)
            .absent("0: off (elastic_plastic columns at rest measured the same with 0.3, docs/physics.md)")
            .example("0.3")
            .ge(0)
            .le(1)
            .doc("Fluids, elastic_plastic: epsilon of Monaghan's artificial stress against the tensile "
                 "instability (docs/physics.md): each particle adds R = -epsilon sigma'/rho^2 for its tensile "
                 "principal stresses sigma' > 0, pair term m_j (R_i + R_j) (W(r)/W(dx))^4 grad W; 0 switches it "
                 "off; Gray, Monaghan & Swift 2001 use 0.3. Only elastic_plastic fluids accept it."),
    };
    add_plasticity_keys();
  }

  // Plastic kinematic material and failure (deformable structures, fem_solver).
  void add_plasticity_keys() {
    material.description +=
        " Deformable structures may add plasticity and failure (LS-DYNA MAT_PLASTIC_KINEMATIC): bilinear "
        "von Mises plasticity from `yield_stress` with `tangent_modulus`, hardening mixed between kinematic "
        "(`hardening` = 0) and isotropic (1), an optional Cowper-Symonds rate factor 1 + (rate / C)^(1/p), "
        "and erosion of elements whose maximum principal strain reaches `failure_strain`.";
    material.keys.push_back(
        K("yield_stress", Type::number)
            .absent("elastic (structures); required by bingham and elastic_plastic fluids; 0 for herschel_bulkley")
            .unit("Pa")
            .gt(0)
            .doc("Structures: initial yield stress sigma_0 of the plastic kinematic law. Fluids: the Bingham yield "
                 "stress tau_y (bingham, herschel_bulkley), or the von Mises yield stress sigma_y "
                 "(elastic_plastic)."));
    material.keys.push_back(K("tangent_modulus", Type::number)
                                .def("0.0")
                                .unit("Pa")
                                .ge(0)
                                .allowed(">= 0 and < youngs_modulus")
                                .doc("Slope of the stress-strain curve after yield (needs `yield_stress`)."));
    material.keys.push_back(K("hardening", Type::number)
                                .def("0.0")
                                .ge(0)
                                .le(1)
                                .doc("beta: 0 kinematic, 1 isotropic hardening (needs `yield_stress`)."));
    material.keys.push_back(K("cowper_symonds_c", Type::number)
                                .absent("no strain-rate effect")
                                .unit("1/s")
                                .gt(0)
                                .doc("Cowper-Symonds C (needs `yield_stress`)."));
    material.keys.push_back(
        K("cowper_symonds_p", Type::number).def("1.0").gt(0).doc("Cowper-Symonds exponent p (with C)."));
    material.keys.push_back(K("failure_strain", Type::number)
                                .absent("no failure")
                                .gt(0)
                                .doc("Maximum principal strain at which an element erodes (deformable structures)."));
  }

  void build_particles() {
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
            .def("false")
            .doc("The set's spheres never move (a glued bed of beads, a rough bed): they take any force, and "
                 "their contacts with other spheres, structures and the fluid are computed as for the others."),
    };
    sphere.title = "[[particles]] spheres = [ { ... } ]";
    sphere.anchor = "particles-spheres";
    sphere.description = "One sphere of an explicit list. Spheres of all lists must not overlap (touching is allowed).";
    sphere.keys = {
        K("center", Type::vec3).required("[0.0, 0.0, 5.0]").unit("m").doc("Centre."),
        K("radius", Type::number).required("0.5").unit("m").gt(0).doc("Radius."),
        K("velocity", Type::vec3).def("[0.0, 0.0, 0.0]").unit("m/s").doc("Initial velocity."),
        K("angular_velocity", Type::vec3).def("[0.0, 0.0, 0.0]").unit("rad/s").doc("Initial angular velocity."),
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
        K("distribution", Type::string)
            .def("\"uniform\"")
            .choices({"uniform", "normal", "sieve"})
            .doc("How diameters are drawn (see above)."),
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
            .def("\"mass\"")
            .choices({"mass", "count"})
            .only_for({"sieve"})
            .doc("The sieve fractions are of the mass or of the count."),
        K("seed", Type::integer).def("1").ge(0).doc("Seed of the random generator."),
        K("velocity", Type::vec3).def("[0.0, 0.0, 0.0]").unit("m/s").doc("Initial velocity of every sphere."),
        K("settle_time", Type::number)
            .def("0.0")
            .unit("s")
            .ge(0)
            .doc("Simulated time the set settles under gravity inside its region before step 0 (0: no "
                 "settling; the spheres start where they were placed)."),
    };
  }

  void build_structures() {
    structure.title = "[[structures]]";
    structure.anchor = "structures";
    structure.selector = "shape";
    structure.description =
        "One FEM part, simulated by the fem_solver: rigid (fixed in space) or, with `rigid = false`, "
        "deformable (a solid box of hexahedra, a shell building or a shell panel). The "
        "`shape` picks the geometry; the keys marked with shapes belong only to those shapes.\n\n"
        "* `plane`: a rectangle centred at `origin` with unit normal `normal`, `length` along `direction` "
        "(projected onto the plane) and `width` across.\n"
        "* `box`: the closed surface of the box `[min, max]`, normals outward.\n"
        "* `chute`: a floor whose upper edge is centred at `origin`; it runs `length` (measured along the "
        "floor) in the horizontal `direction`, descending at `slope_deg`, `width` wide, with side walls "
        "`wall_height` high along both long edges and, when `end_wall_height` > 0, a wall closing the lower "
        "end.\n"
        "* `mesh`: a triangulated surface read from an STL file (ASCII or binary), scaled by `scale` and then "
        "translated by `translate`.\n\n"
        "The loader normalises `normal` and `direction` (the plane's `direction` is first projected onto the "
        "plane) and makes the mesh path absolute.";
    const std::vector<std::string> plane_chute{"plane", "chute"};
    structure.keys = {
        K("name", Type::string)
            .required("\"chute\"")
            .allowed("letters, digits, `_`, `-`")
            .doc("Name of the part, unique among particle sets and structures."),
        K("material", Type::string).required("\"concrete\"").allowed("a `[materials.NAME]`").doc("Material."),
        K("rigid", Type::boolean)
            .def("true")
            .doc("Rigid part, fixed in space. `false`: deformable (explicit FEM, docs/physics.md): a `box` "
                 "without thickness is a solid of hexahedra; a `box` with a `thickness` is a thin-walled "
                 "building of shells (four walls, `floors` slabs with the roof); a `plane` with a "
                 "`thickness` is a shell panel. Elements of about `element_size`."),
        K("fixed", Type::string_list)
            .def("[]")
            .choices({"x-", "x+", "y-", "y+", "z-", "z+"})
            .doc("Deformable: faces of the box around the structure's nodes whose nodes have every degree of "
                 "freedom fixed (a `box`: its own faces; a `mesh`: the faces of the box that bounds its nodes, "
                 "after `scale` and `translate`; a `plane`: the box around the panel). One direction, or a node "
                 "set of its own: `constraints`."),
        K("constraints", Type::table_list)
            .inside(constraint)
            .absent("none")
            .example("[ { box = { min = [-1.0, -1.0, -0.001], max = [1.0, 1.0, 0.001] }, dofs = [\"z\"] } ]")
            .doc("Deformable: degrees of freedom held on node sets, each selected by a box or a mesh's physical "
                 "group (a roller, a symmetry plane, a frictionless anvil; inline tables, see below)."),
        K("velocity", Type::vec3).def("[0.0, 0.0, 0.0]").unit("m/s").doc("Deformable: initial velocity."),
        K("element_formulation", Type::string)
            .def("\"one_point\"")
            .choices({"one_point", "fully_integrated", "enhanced_strain"})
            .only_for({"box", "mesh", "plane"})
            .doc("Deformable solid (hexahedra): `one_point`, one integration point with hourglass control "
                 "(cheapest, exact in bending with a few elements through the depth); `enhanced_strain`, 2 x 2 x 2 "
                 "points with nine condensed incompatible modes (no hourglass modes and accurate in bending: for "
                 "concentrated impacts that stay mostly elastic; too soft under large plastic strain: the F2 "
                 "Taylor bar ends outside the reference, docs/physics.md); `fully_integrated`, 2 x 2 x 2 points "
                 "with the volume change at the element mean (no hourglass modes, stiffer in bending: for "
                 "concentrated impacts with large plastic flow). Shells (a structure with a `thickness`): "
                 "`one_point`, Belytschko-Lin-Tsay with hourglass control; `fully_integrated`, 2 x 2 in-plane "
                 "points with MITC4 transverse shear (no hourglass modes, no shear locking: for concentrated "
                 "impact loads; about twice the cost per element); `enhanced_strain` is for solids only."),
        K("floors", Type::integer)
            .def("1")
            .ge(1)
            .only_for({"box"})
            .doc("Deformable building (box with a thickness): storeys; a slab tops each."),
        K("roof_thickness", Type::number)
            .def("0.0")
            .unit("m")
            .ge(0)
            .only_for({"box"})
            .doc("Deformable building: thickness of the floor and roof slabs (0: `thickness`)."),
        K("roof_material", Type::string)
            .absent("`material`")
            .allowed("a `[materials.NAME]`")
            .only_for({"box"})
            .doc("Deformable building: material of the floor and roof slabs."),
        K("slit_count", Type::integer)
            .def("0")
            .ge(0)
            .only_for({"box"})
            .doc("Deformable solid box (no `thickness`): a slit dam. Number of vertical slits, open at the top, "
                 "cut through the box along `slit_axis` and spaced evenly along the other horizontal axis (the "
                 "`slit_count + 1` piers between them are equally wide). 0: a plain box."),
        K("slit_width", Type::number)
            .def("0.0")
            .unit("m")
            .ge(0)
            .only_for({"box"})
            .doc("Slit dam: width of each slit; with `slit_count`, below the box's length across `slit_axis`."),
        K("slit_depth", Type::number)
            .def("0.0")
            .unit("m")
            .ge(0)
            .only_for({"box"})
            .doc("Slit dam: depth of the slits from the top of the box down; at most its height (`max.z - min.z`; "
                 "equal: the slits reach the ground)."),
        K("slit_axis", Type::string)
            .def("\"y\"")
            .choices({"x", "y"})
            .only_for({"box"})
            .doc("Slit dam: the horizontal axis the slits pass through (the flow direction, across the dam's "
                 "thickness)."),
        K("thickness", Type::number)
            .def("0.0")
            .unit("m")
            .ge(0)
            .doc("Shell thickness: contact acts at half of it from the surface (paper eq. 3); 0 for a solid face."),
        K("shape", Type::string)
            .required("\"plane\"")
            .choices({"plane", "box", "chute", "mesh"})
            .doc("Kind of geometry."),
        K("origin", Type::vec3)
            .required("[0.0, 0.0, 0.0]")
            .unit("m")
            .only_for(plane_chute)
            .doc("Plane: centre. Chute: centre of the floor's upper edge."),
        K("normal", Type::vec3).def("[0.0, 0.0, 1.0]").only_for({"plane"}).doc("Normal, not zero."),
        K("direction", Type::vec3)
            .def("[1.0, 0.0, 0.0]")
            .only_for(plane_chute)
            .doc("Plane: direction of `length`, not along the normal. Chute: horizontal downhill direction "
                 "(z = 0)."),
        K("length", Type::number)
            .required("20.0")
            .unit("m")
            .gt(0)
            .only_for(plane_chute)
            .doc("Plane: side along `direction`. Chute: floor length along the slope."),
        K("width", Type::number).required("8.0").unit("m").gt(0).only_for(plane_chute).doc("Side across."),
        K("slope_deg", Type::number)
            .required("20.0")
            .unit("degree")
            .ge(0)
            .lt(90)
            .only_for({"chute"})
            .doc("Inclination of the floor below the horizontal."),
        K("wall_height", Type::number)
            .def("0.0")
            .unit("m")
            .ge(0)
            .only_for({"chute"})
            .doc("Height of the side walls (0: none)."),
        K("end_wall_height", Type::number)
            .def("0.0")
            .unit("m")
            .ge(0)
            .only_for({"chute"})
            .doc("Height of the wall closing the lower end (0: open end)."),
        K("min", Type::vec3).required("[0.0, 0.0, 0.0]").unit("m").only_for({"box"}).doc("Lower corner."),
        K("max", Type::vec3)
            .required("[1.0, 1.0, 1.0]")
            .unit("m")
            .only_for({"box"})
            .doc("Upper corner, above `min` on every axis."),
        K("element_size", Type::number)
            .def("0.0")
            .unit("m")
            .ge(0)
            .only_for({"plane", "box", "chute"})
            .doc("Target edge length of the generated triangles (0: the coarsest mesh)."),
        K("file", Type::string)
            .required("\"meshes/dam.stl\"")
            .only_for({"mesh"})
            .allowed("an existing `.stl` file (rigid) or `.msh` file (deformable)")
            .doc("STL file, relative to the scene file's folder; for `rigid = false`, a Gmsh msh 4.1 ASCII file of "
                 "8-node hexahedra (solid) or 4-node quadrangles (shells of `thickness`)."),
        K("scale", Type::number).def("1.0").gt(0).only_for({"mesh"}).doc("Scale applied to the file's coordinates."),
        K("translate", Type::vec3)
            .def("[0.0, 0.0, 0.0]")
            .unit("m")
            .only_for({"mesh"})
            .doc("Translation applied after scaling."),
    };
    constraint.title = "[[structures]] constraints = [ { ... } ]";
    constraint.anchor = "structures-constraints";
    constraint.description =
        "One constraint of a deformable structure: the degrees of freedom `dofs` of the nodes it selects keep "
        "zero velocity from the start (the reactions are whatever holds them). It selects the nodes inside a "
        "`box` (its faces included: a box flat on one axis picks the nodes of a plane), in the structure's final "
        "coordinates (a mesh after `scale` and `translate`), or the nodes of the elements of a physical group "
        "`tag` of the structure's Gmsh mesh (`$PhysicalNames`; any dimension: a volume, a surface, a curve, a "
        "point). Give exactly one of `box` and `tag`. Examples: a roller or a frictionless anvil, `dofs = "
        "[\"z\"]` on the face that rests on it; a symmetry plane x = 0, `dofs = [\"x\"]` on its nodes (and, for "
        "shells, `\"ry\"`, `\"rz\"`); a clamped edge, `dofs = [\"all\"]`. Constraints add to `fixed` and to each "
        "other. A selection that holds no node is an error.";
    constraint.keys = {
        K("box", Type::table)
            .inside(constraint_box)
            .absent("use `tag`")
            .example("{ min = [-1.0, -1.0, -0.001], max = [1.0, 1.0, 0.001] }")
            .doc("The nodes inside this box (inline table, see below)."),
        K("tag", Type::string)
            .absent("use `box`")
            .example("\"base\"")
            .allowed("a physical group of the `.msh` file")
            .doc("The nodes of a physical group of the structure's Gmsh mesh (`shape = \"mesh\"` only)."),
        K("dofs", Type::string_list)
            .required("[\"z\"]")
            .choices({"x", "y", "z", "rx", "ry", "rz", "all"})
            .doc("Degrees of freedom held, at least one: translations along x, y, z; rotations about x, y, z "
                 "(shells only: a solid's nodes have none); `all`, every one the nodes have (3 on solids, 6 on "
                 "shells)."),
    };
    constraint_box.title = "[[structures]] constraints = [ { box = { ... } } ]";
    constraint_box.anchor = "structures-constraints-box";
    constraint_box.description = "The box of a constraint: `min` <= `max` on every axis (equal: flat on that axis).";
    constraint_box.keys = {
        K("min", Type::vec3).required("[-1.0, -1.0, -0.001]").unit("m").doc("Lower corner."),
        K("max", Type::vec3).required("[1.0, 1.0, 0.001]").unit("m").doc("Upper corner."),
    };
  }

  void build_sph() {
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
            .def("1.5")
            .ge(0.5)
            .le(3)
            .doc("h / dx. The default 1.5 keeps a Wendland C2 lattice at rest (about 100 neighbours); at 1.3 it "
                 "rearranges (docs/physics.md, \"The kernel at rest\"). With the cubic spline 1.3 holds and 1.5 "
                 "does not."),
        K("kernel", Type::string)
            .def("\"wendland_c2\"")
            .choices({"wendland_c2", "cubic_spline"})
            .doc("Smoothing kernel; both have support 2h."),
        K("wall_model", Type::string)
            .def("\"boundary_particles\"")
            .choices({"boundary_particles", "penalty"})
            .doc("How structures act on the fluid (see above)."),
        K("wall_work", Type::string)
            .def("\"bounded\"")
            .choices({"bounded", "stored", "unstored"})
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
        K("sound_speed", Type::number)
            .required("30.0")
            .unit("m/s")
            .gt(0)
            .doc("Artificial sound speed c of every fluid: at least ten times the largest expected flow speed."),
        K("cfl", Type::number)
            .def("0.25")
            .gt(0)
            .le(1)
            .doc("The stable dt sent to the coupler: cfl * min(h / (c + h max|div v|), sqrt(h / max|a|), "
                 "rho h^2 / (8 eta)) (paper eq. 7's SPH term with its force and viscous conditions)."),
        K("artificial_viscosity", Type::number).def("0.01").ge(0).doc("Monaghan's alpha."),
        K("density_diffusion", Type::string)
            .def("\"fourtakas\"")
            .choices({"none", "molteni", "fourtakas"})
            .doc("delta-SPH term of the continuity equation: Molteni & Colagrossi 2009, or with the hydrostatic "
                 "part taken out (Fourtakas et al. 2019)."),
        K("density_diffusion_delta", Type::number).def("0.1").ge(0).le(1).doc("delta of the density diffusion."),
        K("viscous_operator", Type::string)
            .def("\"strain_rate\"")
            .choices({"strain_rate", "morris"})
            .doc(
                "How the viscous stress 2 eta D of the fluids (`rheology` newtonian, bingham, herschel_bulkley, "
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
            .def("[0.0, 0.0, 0.0]")
            .unit("m")
            .only_for({"extruded_polygon"})
            .doc("Where s = 0 (its z is ignored: profile heights are absolute)."),
        K("direction", Type::vec3)
            .def("[1.0, 0.0, 0.0]")
            .only_for({"extruded_polygon"})
            .doc("Horizontal direction of s (z = 0), not zero."),
        K("width", Type::number)
            .required("7.0")
            .unit("m")
            .gt(0)
            .only_for({"extruded_polygon"})
            .doc("Extrusion width across `direction`."),
        K("velocity", Type::vec3).def("[0.0, 0.0, 0.0]").unit("m/s").doc("Initial velocity."),
        K("hydrostatic", Type::boolean)
            .def("true")
            .doc("Start with the hydrostatic pressure of the column above each particle."),
        K("settle_time", Type::number)
            .def("0.0")
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

  void build_sph_fem() {
    sph_fem.title = "[contact.sph_fem]";
    sph_fem.anchor = "contact-sph_fem";
    sph_fem.description =
        "Penalty contact of fluid particles against structure surfaces, computed by the coupler (paper eqs. "
        "3-6, the particle's contact radius is dx/2: the wall stands where the fluid body ends), used when "
        "`sph.wall_model = \"penalty\"`. Defaults of "
        "every fluid/structure pair; `[[interactions]]` override them per pair.";
    sph_fem.keys = {
        K("friction", Type::number).def("0.3").ge(0).doc("Coulomb friction coefficient."),
        K("penalty_scale", Type::number).def("0.1").gt(0).doc("k1 of eq. 6."),
        K("normal_stiffness", Type::number)
            .absent("eq. 6")
            .example("1e8")
            .unit("N/m")
            .gt(0)
            .doc("Normal stiffness replacing eq. 6."),
        K("normal_damping_ratio", Type::number)
            .def("0.0")
            .ge(0)
            .lt(1)
            .doc("Normal damping: c_n = 2 ratio sqrt(k_n m)."),
        K("tangential_damping_ratio", Type::number).def("0.0").ge(0).lt(1).doc("Tangential damping ratio."),
    };
  }

  void build_sph_dem() {
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
            .def("\"boundary_particles\"")
            .choices({"boundary_particles", "penalty"})
            .doc("Contact law: boulder surfaces as wall particles, or the paper's penalty."),
        K("normal_stiffness", Type::number)
            .absent("rho0 c^2 dx, lowered so that 0.2 pi sqrt(rho0 dx^3 / K) >= cfl h / c")
            .example("2e6")
            .unit("N/m")
            .gt(0)
            .doc("Penalty stiffness K (penalty only); its pair step 0.2 pi sqrt(rho0 dx^3 / K) may not be below "
                 "the SPH step cfl h / c."),
        K("normal_damping_ratio", Type::number)
            .def("0.0")
            .ge(0)
            .lt(1)
            .doc("Normal damping of the penalty law: eta = 2 ratio sqrt(K m*), m* the reduced mass (penalty only)."),
        K("friction", Type::number)
            .def("0.0")
            .ge(0)
            .doc("Coulomb friction of the penalty law, tangential spring k_t = K (penalty only)."),
    };
  }

  void build_contact() {
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
        K("model", Type::string).def("\"linear\"").choices({"linear", "hertz_mindlin"}).doc("Contact law."),
        K("normal_damping_ratio", Type::number).def("0.7").ge(0).lt(1).doc("Normal " + damping_doc),
        K("tangential_damping_ratio", Type::number)
            .def("0.4")
            .ge(0)
            .lt(1)
            .doc("Tangential " + damping_doc + " Also the rolling spring's dashpot."),
        K("restitution", Type::number)
            .def("0.5")
            .gt(0)
            .le(1)
            .doc("Coefficient of restitution of the normal impact (hertz_mindlin); 1: no damping."),
        K("friction", Type::number).def("1.0").ge(0).doc("Sliding friction coefficient."),
        K("rolling", Type::string)
            .def("\"constant\"")
            .choices({"constant", "viscous"})
            .doc("Rolling resistance model."),
        K("rolling_friction", Type::number)
            .def("0.1")
            .ge(0)
            .doc("Constant rolling resistance: torque = rolling_friction * r_eff * |F_n| (0: none)."),
        K("rolling_viscosity", Type::number)
            .def("0.0")
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
            .def("0.01")
            .gt(0)
            .doc("LS-DYNA's NormK: k_n = scale * K1 r1 K2 r2 / (K1 r1 + K2 r2), K the bulk modulus, r the radius."),
        K("tangential_stiffness_ratio", Type::number)
            .def("0.2857142857142857")
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
        K("model", Type::string)
            .absent(from_dem)
            .example("\"hertz_mindlin\"")
            .choices({"linear", "hertz_mindlin"})
            .doc("Contact law."),
        K("normal_damping_ratio", Type::number)
            .absent(from_dem)
            .example("0.7")
            .ge(0)
            .lt(1)
            .doc("Normal " + damping_doc),
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
            .choices({"constant", "viscous"})
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
            .def("\"penalty\"")
            .choices({"penalty", "hertz_mindlin"})
            .doc("Contact law: the paper's penalty (eqs. 3-6) or Hertz-Mindlin."),
        K("restitution", Type::number)
            .def("0.5")
            .gt(0)
            .le(1)
            .doc("Coefficient of restitution (hertz_mindlin only; refused with the penalty law); 1: no damping."),
        K("friction", Type::number).def("0.3").ge(0).doc("Coulomb friction coefficient."),
        K("penalty_scale", Type::number)
            .def("0.1")
            .gt(0)
            .doc("k1 of eq. 6: k_n = k1 K s^2 / V (solid face) or k1 K s / max_diagonal (shell)."),
        K("normal_stiffness", Type::number)
            .absent("eq. 6")
            .example("1e8")
            .unit("N/m")
            .gt(0)
            .doc("Normal stiffness replacing eq. 6."),
        K("normal_damping_ratio", Type::number)
            .def("0.0")
            .ge(0)
            .lt(1)
            .doc("Normal damping: c_n = 2 ratio sqrt(k_n m)."),
        K("tangential_damping_ratio", Type::number)
            .def("0.0")
            .ge(0)
            .lt(1)
            .doc("Tangential damping ratio (and the rolling spring's dashpot)."),
        K("rolling", Type::string)
            .def("\"constant\"")
            .choices({"constant", "viscous"})
            .doc("Rolling resistance model against the structure (as `[contact.dem_dem]`, r_eff = the sphere's "
                 "radius)."),
        K("rolling_friction", Type::number)
            .def("0.0")
            .ge(0)
            .doc("Constant rolling resistance against the structure: an elastic-plastic rolling spring capped at "
                 "rolling_friction * r * |F_n| (0: none)."),
        K("rolling_viscosity", Type::number)
            .def("0.0")
            .unit("s/m")
            .ge(0)
            .doc("Viscous rolling resistance against the structure: torque = rolling_viscosity * r * |F_n| * r |w|."),
    };
  }

  void build_fem_fem() {
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
            .def("false")
            .doc("`true`: every pair of structures (at least one deformable) is in contact."),
        K("friction", Type::number).def("0.3").ge(0).doc("Coulomb friction coefficient."),
        K("penalty_scale", Type::number)
            .def("0.1")
            .gt(0)
            .doc("k1 of eq. 6: k_n = k1 K s^2 / V (solid face) or k1 K s / max_diagonal (shell or rigid face)."),
        K("normal_stiffness", Type::number)
            .absent("eq. 6")
            .example("1e8")
            .unit("N/m")
            .gt(0)
            .doc("Normal stiffness replacing eq. 6."),
        K("normal_damping_ratio", Type::number)
            .def("0.0")
            .ge(0)
            .lt(1)
            .doc("Normal damping: c_n = 2 ratio sqrt(k_n m), m the reduced mass of the node and the face's "
                 "lightest node (a rigid side is infinitely heavy)."),
        K("tangential_damping_ratio", Type::number).def("0.0").ge(0).lt(1).doc("Tangential damping ratio."),
    };
  }

  void build_interactions() {
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
            .def("true")
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
            .choices({"constant", "viscous"})
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

  void build_recording() {
    recording.title = "[recording]";
    recording.anchor = "recording";
    recording.description = "What the coupler records into `traffic.h5`, the log that replay and restart read.";
    recording.keys = {
        K("enabled", Type::boolean).def("true").doc("Record at all."),
        K("fields", Type::string_list)
            .def("[]")
            .choices({"position", "velocity", "angular_velocity", "force", "torque", "node_position", "node_velocity",
                      "node_force", "energies", "boundary_particles", "boundary_force"})
            .doc("Fields to record; empty: all. `boundary_particles`: the SPH wall particles sent to the sph_solver "
                 "(position, velocity, normal, acceleration, volume); `boundary_force`: the fluid's forces on them "
                 "(with their `boundary_step`)."),
        K("every", Type::integer).def("1").ge(1).doc("Record every N-th step."),
        K("first_step", Type::integer).def("0").ge(0).doc("First recorded step."),
        K("last_step", Type::integer)
            .absent("to the end")
            .example("100000")
            .ge(0)
            .doc("Last recorded step, not before `first_step`."),
        K("flush_interval", Type::number)
            .def("0.2")
            .unit("s")
            .gt(0)
            .doc("Wall time between flushes to disk (the file stays readable after a crash)."),
    };
  }

  void build_gauges() {
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
        K("points", Type::integer).def("20").ge(2).le(10000).only_for({"line"}).doc("Points along the line."),
        K("interval", Type::number)
            .absent("`run.output_interval`")
            .example("0.001")
            .unit("s")
            .gt(0)
            .doc("Simulated time between two samples."),
    };
  }

  void build_sensors() {
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
};

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
      "Shapes: a plane's `normal` is not zero and its `direction` not along the normal; a chute's `direction` "
      "is horizontal and not zero; a box has `min` < `max` on every axis; a mesh `file` exists, is a regular "
      "file and ends in `.stl` (`.msh` for `rigid = false`), and it is read by the solvers' own readers "
      "(truncated, malformed, non-finite or degenerate meshes are refused with the mesh file's line). Keys of "
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
      "<!-- Generated by `sabo_scene schema-doc` from libsabo/scene/schema.cpp. Do not edit by hand: a test "
      "checks that this file equals the generated text. -->\n\n"
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
