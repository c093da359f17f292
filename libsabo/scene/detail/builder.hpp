#pragma once
// The scene loader's Builder: reads a parsed scene file section by section into a Scene,
// collecting every problem. Its members are defined beside the schema of their section:
// sections/run.cpp ([run], [solvers], [recording]), materials.cpp, fluids.cpp ([sph],
// [[fluids]]), inflows.cpp, particles.cpp, structures.cpp, contact.cpp ([contact]), interactions.cpp,
// instruments.cpp ([[gauges]], [[sensors]]), checks.cpp (what spans sections: names,
// overlaps, cost and memory), and loader.cpp (the order of the sections).
#include <fmt/format.h>
#include <toml++/toml.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cassert>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/hexahedron.hpp"
#include "libsabo/geometry/polygon.hpp"
#include "libsabo/geometry/primitives.hpp"
#include "libsabo/geometry/sphere_fill.hpp"
#include "libsabo/io/gmsh.hpp"
#include "libsabo/io/gmsh_groups.hpp"
#include "libsabo/io/pairs_csv.hpp"
#include "libsabo/io/raster.hpp"
#include "libsabo/io/stl.hpp"
#include "libsabo/physics/stable_step.hpp"
#include "libsabo/scene/detail/reader.hpp"
#include "libsabo/scene/estimate.hpp"
#include "libsabo/scene/scene.hpp"
#include "libsabo/scene/schema.hpp"
#include "libsabo/scene/sensor_patch.hpp"
#include "libsabo/scene/suggest.hpp"

namespace sabo::scene::detail {

// Random filling jams well before dense packing; past this expected solid
// fraction of the box a fill would likely not fit (docs/scene.md says so).
constexpr double kMaxFillSolidFraction = 0.3;
// Overlap reports beyond this many are summarised in one line.
constexpr std::size_t kMaxOverlapReports = 20;

class Builder {
 public:
  Builder(const fs::path& file, const toml::table& document);
  Scene build();

 private:
  struct BodyName {
    bool is_particle_set;
    std::string path;
    int line;
    bool is_fluid = false;
  };
  // The fluid keys of a material, for the checks that need the fluids that use it.
  struct FluidMaterialKeys {
    int line = 0;
    bool has_eos_c1 = false;
    // Lines of the Herschel-Bulkley keys (0: absent) and of viscosity.
    int consistency_index_line = 0, flow_index_line = 0, viscosity_line = 0;
  };
  // A sphere of a list, with where it was written, for the overlap check.
  struct ListedSphere {
    Vec3 center;
    double radius;
    std::string path;
    int line;
  };

  [[nodiscard]] Origin origin(int line, std::string key) const { return {scene_.file, line, std::move(key)}; }
  void read_run(const toml::table& table);
  void read_materials(Reader& root);
  void read_fluid_material(Reader& r, Material& material);
  void read_sph(Reader& root);
  void read_periodic(Reader& r, const char* key, std::optional<std::array<double, 2>>& out, int& line);
  void read_fluid(const toml::table& table, std::size_t index);
  void read_inflow(const toml::table& table, std::size_t index);
  void check_inside_periodic_spans(const Aabb& bounds, int line, const std::string& key,
                                   const std::optional<std::string>& value, const std::string& what,
                                   const std::string& fix);
  void check_profile(Reader& r, const std::vector<std::array<double, 2>>& profile);
  void check_fluid_materials();
  void read_plasticity(Reader& r, Material& material);
  void read_deformable(Reader& r, Structure& structure, const std::optional<std::string>& shape);

  static constexpr std::array<const char*, 4> kSlitKeys{"slit_count", "slit_width", "slit_depth", "slit_axis"};

  // Where a constraint's keys were written, for the checks that need the structure's shape (read later).
  struct ConstraintKeys {
    int line = 0, box_line = 0, tag_line = 0;
    std::string path, box_value;
  };
  void read_constraints(Reader& structure_reader, const toml::array& list, Structure& structure);
  void check_constraints(const Structure& structure, const std::optional<std::string>& shape);

  static std::string vec_text(const Vec3& v) {
    return fmt::format("[{}, {}, {}]", number_literal(v.x()), number_literal(v.y()), number_literal(v.z()));
  }
  static Aabb structure_extent(const Structure& structure);
  void check_slits(Reader& r, const Structure& structure);
  void register_body(Reader& r, const std::string& name, bool is_particle_set, bool is_fluid = false);
  void check_material(Reader& r, const std::string& material, const char* key = "material");
  void read_particle_set(const toml::table& table, std::size_t index);
  void read_fill(const toml::table& table, const std::string& path, ParticleSet& set);
  void read_fill_region(Reader& f, ParticleSet& set);
  void read_fill_sizes(Reader& f, ParticleSet& set);
  void read_structure(const toml::table& table, std::size_t index);
  // A file named in the scene: absolute, or relative to the scene file's folder.
  [[nodiscard]] fs::path scene_relative(const std::string& file) const {
    const fs::path given(file);
    return (given.is_absolute() ? given : scene_dir_ / given).lexically_normal();
  }
  fs::path resolve_mesh(Reader& r, const std::string& file, bool rigid = true);
  void read_mesh(Reader& r, const std::string& file, Structure& structure);
  void read_channel_profile(Reader& r, Shape& shape);
  void read_terrain(Reader& r, Structure& structure);
  bool read_terrain_front(Reader& r, Front& front);
  // A file reader's error ("FILE[:LINE]: problem. Fix: fix") as a problem of key `key`, its problem after
  // `what`, its fix (or `fallback_fix` where it names none) as the fix.
  void add_file_error(Reader& r, const std::string& key, const std::string& value, const std::string& what,
                      const Error& error, const std::string& fallback_fix);
  void read_solvers(Reader& root);
  void check_command(Reader& r, SolverSettings& solver);
  void read_surface_contact_law(Reader& r, SurfaceContact& contact, const char* model_fix);
  static void read_surface_contact(Reader& r, SurfaceContact& contact);
  void read_surface_rolling(Reader& r, SurfaceContact& contact);
  static void read_dem_law(Reader& r, DemContactLaw& law);
  void check_dem_law_keys(Reader& r, const DemContactLaw& law, bool any_hertz, bool any_viscous);
  void read_contact(Reader& root);
  static void read_sph_dem_contact(Reader& r, SphDemContact& contact);
  [[nodiscard]] bool deformable_pair_possible() const;
  [[nodiscard]] const Structure* structure_named(const std::string& name) const;
  void read_fem_fem_interaction(Reader& r, FemFemInteraction& interaction);
  void read_interactions(Reader& root);
  void read_recording(Reader& root);
  void register_instrument(Reader& r, const std::string& name, std::map<std::string, int>& names, const char* kind);
  void read_gauges(Reader& root);
  void read_fronts(Reader& root);
  void read_front_stations(Reader& front_reader, const toml::array& list, Front& front);
  void read_sensors(Reader& root);
  void check_sensor_box(Reader& r, const Sensor& sensor);
  void check_overlaps();

  // Where a fluid/particle-set contact's settings were written: the line and key of its
  // normal_stiffness, else of its table.
  struct Where {
    int line = 0;
    std::string key;
  };
  [[nodiscard]] Where sph_dem_where(const std::string& fluid, const std::string& set) const;
  void check_sph_dem();
  // [sph] free_slip_walls names structures, with boundary-particle walls (after the structures are read).
  void check_free_slip_walls();
  void check_lagged_boundary_particles();
  void check_fills();
  [[nodiscard]] int line_of_key(std::string path) const;
  [[nodiscard]] std::optional<std::string> value_of_key(const std::string& path) const;
  void check_costs();
  void report_memory(const SceneEstimate& e, double memory);

  static constexpr double kGiB = 1024.0 * 1024.0 * 1024.0;

  Diagnostics diag_;
  const toml::table& document_;
  fs::path scene_dir_;
  Scene scene_;
  bool has_particles_ = false, has_structures_ = false, has_fluids_ = false;
  std::map<std::string, FluidMaterialKeys> fluid_material_keys_;
  int domain_line_ = 0;
  Where free_slip_where_{0, "sph.free_slip_walls"};
  int periodic_line_[2] = {0, 0};
  std::vector<std::string> material_names_;
  std::map<std::string, BodyName> bodies_;
  std::vector<ConstraintKeys> constraint_keys_;  // of the structure being read
  std::vector<ListedSphere> listed_;
  Where sph_dem_default_where_{0, "contact.sph_dem"};
  std::map<std::pair<std::string, std::string>, Where> sph_dem_where_;  // (fluid, set) -> its interaction
};

}  // namespace sabo::scene::detail
