// [materials.NAME] (and the plasticity keys structures share): the schema of the section and its reader.

#include "libsabo/scene/detail/builder.hpp"
#include "libsabo/scene/detail/schema_tables.hpp"

namespace sabo::scene::schema::detail {

void Schema::build_materials() {
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
      K("eos", Type::string).def(Material{}.eos).doc("Fluids: equation of state."),
      K("tait_exponent", Type::number).def(Material{}.tait_exponent).ge(1).doc("Fluids, Tait: exponent gamma."),
      K("eos_c0", Type::number).def(Material{}.eos_c0).unit("Pa").doc("Fluids, polynomial: C0."),
      K("eos_c1", Type::number)
          .absent("required with eos = \"polynomial\"")
          .example("20e9")
          .unit("Pa")
          .gt(0)
          .doc("Fluids, polynomial: C1."),
      K("eos_c2", Type::number).def(Material{}.eos_c2).unit("Pa").doc("Fluids, polynomial: C2."),
      K("eos_c3", Type::number).def(Material{}.eos_c3).unit("Pa").doc("Fluids, polynomial: C3."),
      K("rheology", Type::string).def(Material{}.rheology).doc("Fluids: constitutive model of the deviatoric stress."),
      K("viscosity", Type::number)
          .def(Material{}.viscosity)
          .unit("Pa s")
          .ge(0)
          .doc("Fluids: dynamic viscosity (newtonian, > 0), plastic viscosity (bingham, > 0), extra viscosity "
               "(elastic_plastic)."),
      K("yield_shear_rate", Type::number)
          .def(Material{}.yield_shear_rate)
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
          .def(Material{}.flow_index)
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
void Schema::add_plasticity_keys() {
  material.description +=
      " Deformable structures may add plasticity and failure (LS-DYNA MAT_PLASTIC_KINEMATIC): bilinear "
      "von Mises plasticity from `yield_stress` with `tangent_modulus`, hardening mixed between kinematic "
      "(`hardening` = 0) and isotropic (1), an optional Cowper-Symonds rate factor 1 + (rate / C)^(1/p), "
      "and erosion of elements whose maximum principal strain (or, with `failure_measure` = "
      "\"plastic_strain\", effective plastic strain: MAT_PLASTIC_KINEMATIC's own FS) reaches `failure_strain`.";
  material.keys.push_back(
      K("yield_stress", Type::number)
          .absent("elastic (structures); required by bingham and elastic_plastic fluids; 0 for herschel_bulkley")
          .unit("Pa")
          .gt(0)
          .doc("Structures: initial yield stress sigma_0 of the plastic kinematic law. Fluids: the Bingham yield "
               "stress tau_y (bingham, herschel_bulkley), or the von Mises yield stress sigma_y "
               "(elastic_plastic)."));
  material.keys.push_back(K("tangent_modulus", Type::number)
                              .def(Material{}.tangent_modulus)
                              .unit("Pa")
                              .ge(0)
                              .allowed(">= 0 and < youngs_modulus")
                              .doc("Slope of the stress-strain curve after yield (needs `yield_stress`)."));
  material.keys.push_back(K("hardening", Type::number)
                              .def(Material{}.hardening)
                              .ge(0)
                              .le(1)
                              .doc("beta: 0 kinematic, 1 isotropic hardening (needs `yield_stress`)."));
  material.keys.push_back(K("cowper_symonds_c", Type::number)
                              .absent("no strain-rate effect")
                              .unit("1/s")
                              .gt(0)
                              .doc("Cowper-Symonds C (needs `yield_stress`)."));
  material.keys.push_back(K("cowper_symonds_p", Type::number)
                              .def(Material{}.cowper_symonds_p)
                              .gt(0)
                              .doc("Cowper-Symonds exponent p (with C)."));
  material.keys.push_back(K("failure_strain", Type::number)
                              .absent("no failure")
                              .gt(0)
                              .doc("Strain at which an element erodes (deformable structures), measured as "
                                   "`failure_measure` says."));
  material.keys.push_back(
      K("failure_measure", Type::string)
          .def(Material{}.failure_measure)
          .doc("What `failure_strain` bounds: `principal_strain`, the largest principal total strain (elastic "
               "and plastic); `plastic_strain`, the effective plastic strain (LS-DYNA MAT_PLASTIC_KINEMATIC's "
               "FS, \"effective plastic strain for eroding elements\"; needs `yield_stress`)."));
}

}  // namespace sabo::scene::schema::detail

namespace sabo::scene::detail {

void Builder::read_materials(Reader& root) {
  for (const auto& [name, table] : root.named_tables("materials")) {
    const std::string path = "materials." + name;
    material_names_.push_back(name);
    if (!valid_name(name)) {
      diag_.add(line_of(*table), path, std::nullopt, "the name must be made of letters, digits, '_' and '-'",
                "rename the material");
    }
    Reader r(diag_, spec("materials-name"), *table, path);
    Material material;
    material.name = name;
    material.origin = origin(r.line(), path);
    if (auto v = r.number("density")) material.density = *v;
    if (auto v = r.number("youngs_modulus")) material.youngs_modulus = *v;
    if (auto v = r.number("poisson_ratio")) material.poisson_ratio = *v;
    read_plasticity(r, material);
    read_fluid_material(r, material);
    scene_.materials.push_back(std::move(material));
  }
}

// Checks `name` (validity, uniqueness among bodies) and records it.
// Plastic kinematic keys of a material (deformable structures).
void Builder::read_plasticity(Reader& r, Material& material) {
  material.yield_stress = r.number("yield_stress");
  if (auto v = r.number("tangent_modulus")) material.tangent_modulus = *v;
  if (auto v = r.number("hardening")) material.hardening = *v;
  material.cowper_symonds_c = r.number("cowper_symonds_c");
  if (auto v = r.number("cowper_symonds_p")) material.cowper_symonds_p = *v;
  material.failure_strain = r.number("failure_strain");
  if (auto v = r.string("failure_measure")) material.failure_measure = value_named<Material::FailureMeasure>(*v);
  if (r.has("failure_measure") && !material.failure_strain) {
    diag_.add(r.line("failure_measure"), r.key_path("failure_measure"), value_text(*r.node("failure_measure")),
              "a failure measure without failure_strain (the material never fails)",
              "add failure_strain, or remove the key");
  } else if (material.failure_measure == Material::FailureMeasure::plastic_strain && !material.yield_stress &&
             material.failure_strain) {
    diag_.add(r.line("failure_measure"), r.key_path("failure_measure"), value_text(*r.node("failure_measure")),
              "an elastic material (no yield_stress) never strains plastically, so it would never fail",
              "add yield_stress, or failure_measure = \"principal_strain\"");
  }
  if (!material.yield_stress) {
    for (const char* key : {"tangent_modulus", "hardening", "cowper_symonds_c", "cowper_symonds_p"}) {
      if (r.has(key)) {
        diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                  "a plasticity parameter without yield_stress (the material is elastic)",
                  "add yield_stress, or remove the key");
      }
    }
  }
  if (material.youngs_modulus > 0 && material.tangent_modulus >= material.youngs_modulus) {
    diag_.add(
        r.line("tangent_modulus"), r.key_path("tangent_modulus"), value_text(*r.node("tangent_modulus")),
        fmt::format("the tangent modulus must be below youngs_modulus = {}", number_literal(material.youngs_modulus)),
        "give the slope after yield, a fraction of youngs_modulus");
  }
}

}  // namespace sabo::scene::detail
