// Every file of tests/scenes/bad is refused with a message that names the
// file, the line, the key and the value (and the suggestion where one
// applies), both by load_scene and by `sabo_scene check` (exit status 2).
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/scene/loader.hpp"
#include "scene_test_support.hpp"

namespace sabo::scene {
namespace {

struct BadScene {
  std::string file;               // in tests/scenes/bad
  int line;                       // of the first message
  std::string key;                // as printed: key 'KEY'
  std::string value;              // as printed after " = " (empty: no value)
  std::vector<std::string> also;  // further text the message must hold
};

std::filesystem::path bad_folder() {
  return testing::source_dir() / "tests/scenes/bad";
}

const std::vector<BadScene>& bad_scenes() {
  static const std::vector<BadScene> scenes{
      {"syntax_error.toml", 5, "end_time", "2.0.0", {":5:15:", "TOML syntax error", "expected decimal digit"}},
      {"unknown_key.toml", 7, "run.hang_timout", "5.0", {"unknown key. Did you mean 'hang_timeout'?"}},
      {"unknown_table.toml",
       18,
       "lava_flows",
       "[{ name = \"slurry\" }]",
       {"unknown key", "keys allowed at the top level"}},
      {"wrong_type.toml", 9, "materials.granite.density", "\"3000\"", {"must be a number (kg/m^3), not a string"}},
      {"negative_radius.toml", 18, "particles[0].spheres[1].radius", "-0.5", {"must be > 0 (m)", "positive radius"}},
      {"friction_out_of_range.toml", 32, "contact.dem_fem.friction", "-0.3", {"must be >= 0"}},
      {"damping_out_of_range.toml", 19, "contact.dem_dem.normal_damping_ratio", "1.2", {"must be in [0, 1)"}},
      {"poisson_out_of_range.toml", 11, "materials.granite.poisson_ratio", "0.5", {"must be in [0, 0.5)"}},
      {"missing_mesh.toml",
       27,
       "structures[0].file",
       "\"meshes/no_such_dam.stl\"",
       {"file not found", "tests/scenes/bad/meshes/no_such_dam.stl", "relative to the scene file's folder"}},
      {"unknown_material.toml", 15, "particles[0].material", "\"granit\"", {"Did you mean 'granite'?"}},
      {"overlapping_spheres.toml",
       21,
       "particles[1].spheres[0]",
       "{ center = [0.6, 0.0, 3.0], radius = 0.5 }",
       {"overlaps particles[0].spheres[0] (line 16) by 0.4 m"}},
      {"negative_end_time.toml", 5, "run.end_time", "-1.0", {"must be > 0 (s)"}},
      {"missing_solver_command.toml",
       19,
       "solvers.dem.command",
       "[\"/nonexistent/sabo/my_dem\", \"--fast\"]",
       {"does not exist or is not executable", "remove 'command' to run the built dem_solver"}},
      {"unneeded_solver.toml", 18, "solvers.fem", "", {"no bodies need the fem_solver", "add [[structures]]"}},
      {"no_bodies.toml",
       1,
       "",
       "",
       {"the scene has no bodies", "add at least one [[fluids]], [[particles]] or [[structures]]"}},
      {"duplicate_name.toml", 24, "structures[0].name", "\"boulders\"", {"already used by particles[0] (line 19)"}},
      {"interaction_unknown_body.toml",
       32,
       "interactions[0].pair",
       "[\"bouldrs\", \"ground\"]",
       {"no fluid, particle set or structure is named \"bouldrs\"", "Did you mean 'boulders'?"}},
      {"interaction_same_kind.toml",
       42,
       "interactions[0].pair",
       "[\"ground\", \"wall\"]",
       {"both structures are rigid: they never move, so they never come into contact",
        "pair a deformable structure (rigid = false) with another structure"}},
      {"fill_inverted_region.toml",
       16,
       "particles[0].fill.max",
       "[5.0, 5.0, 1.0]",
       {"empty or inverted", "min = [0.0, 0.0, 5.0]"}},
      {"fill_zero_count.toml", 16, "particles[0].fill.count", "0", {"must be >= 1"}},
      {"deformable_not_box.toml",
       16,
       "structures[0].rigid",
       "false",
       {"not shape = \"plane\" without a thickness", "give the plane a thickness"}},
      {"deformable_mesh_not_msh.toml",
       18,
       "structures[0].file",
       "\"../../../configs/tests/meshes/basin.stl\"",
       {"must be a Gmsh file ending in .msh", "export the mesh from Gmsh as msh 4.1 ASCII"}},
      {"slit_too_wide.toml", 22, "structures[0].slit_width", "3.5", {"leaving no piers", "give slit_width below"}},
      {"slit_too_deep.toml", 23, "structures[0].slit_depth", "5.0", {"deeper than the box is high", "slit_depth <="}},
      {"slit_without_width.toml",
       21,
       "structures[0].slit_width",
       "",
       {"slit_count = 2 needs the width of the slits", "give slit_width > 0"}},
      {"enhanced_strain_shells.toml",
       22,
       "structures[0].element_formulation",
       "\"enhanced_strain\"",
       {"enhanced-strain elements exist for solids (hexahedra) only", "remove the thickness"}},
      {"slit_on_rigid_box.toml",
       21,
       "structures[0].slit_count",
       "2",
       {"belongs to deformable structures, but this one is rigid"}},
      {"plasticity_without_yield.toml",
       12,
       "materials.concrete.tangent_modulus",
       "100000000.0",
       {"a plasticity parameter without yield_stress", "add yield_stress"}},
      {"fluid_without_sph.toml", 13, "sph", "", {"missing; the scene has [[fluids]]", "add an [sph] table"}},
      {"periodic_too_short.toml",
       12,
       "sph.periodic_x",
       "[0.0, 0.05]",
       {"shorter than two kernel supports plus one spacing, 4h + dx = 0.07 m", "widen the span to at least 0.07 m"}},
      {"fluid_outside_periodic.toml",
       18,
       "fluids[0]",
       "",
       {"the body spans y = [0.0, 0.15] m, outside the periodic span sph.periodic_y = [0.0, 0.1] (line 11)",
        "move the body into the span or widen sph.periodic_y"}},
      {"settling_body_moving.toml",
       24,
       "fluids[0].settle_time",
       "0.5",
       {"a settling body starts at rest, but its velocity is [1.0, 0.0, 0.0]",
        "remove settle_time, or set velocity = [0.0, 0.0, 0.0]"}},
      {"settle_time_negative.toml", 23, "fluids[0].settle_time", "-0.5", {"must be >= 0 (s)"}},
      {"fluid_interaction_hertz.toml",
       40,
       "interactions[0].model",
       "\"hertz_mindlin\"",
       {"through the penalty law only", "remove the key from this fluid's interaction"}},
      {"sph_dem_without_particles.toml",
       29,
       "contact.sph_dem",
       "",
       {"fluid-sphere contact needs both fluids and particles", "add the missing [[fluids]] or [[particles]]"}},
      {"sph_dem_boulder_too_small.toml",
       29,
       "particles[0].spheres",
       "",
       {"spans 1.5 SPH spacings", "at least 0.02 m", "model = \"penalty\""}},
      {"sph_dem_stiffness_unstable.toml",
       36,
       "contact.sph_dem.normal_stiffness",
       "1000000000.0",
       {"below the SPH step", "normal_stiffness <= 1.12e+04 N/m"}},
      {"sph_dem_settled_fill_in_fluid.toml",
       29,
       "particles[0].fill",
       "",
       {"reaches into fluid body 'water'", "settle_time", "move the fill region out of the fluid body"}},
      {"sph_dem_two_laws_for_one_set.toml",
       41,
       "interactions[0]",
       "",
       {"meets fluid 'water' as boundary particles but fluid 'slurry' otherwise", "same contact model"}},
      {"interaction_fluid_set_hertz.toml",
       36,
       "interactions[0].model",
       "\"hertz_mindlin\"",
       {"\"boundary_particles\" or \"penalty\""}},
      {"bingham_without_yield_stress.toml",
       12,
       "materials.mud.yield_stress",
       "",
       {"needs a positive yield stress (used by fluid 'slurry')"}},
      {"herschel_bulkley_without_consistency.toml",
       12,
       "materials.mud.consistency_index",
       "",
       {"needs its consistency index K", "(used by fluid 'slurry')", "give consistency_index > 0"}},
      {"flow_index_not_herschel_bulkley.toml",
       19,
       "materials.mud.flow_index",
       "0.4",
       {"read only by rheology = \"herschel_bulkley\" (used by fluid 'slurry')", "remove flow_index"}},
      {"artificial_stress_not_elastic_plastic.toml",
       12,
       "materials.mud.artificial_stress",
       "0.3",
       {"elastic_plastic fluid only (used by fluid 'slurry')", "use rheology = \"elastic_plastic\""}},
      {"fill_diameter_inverted.toml",
       16,
       "particles[0].fill.diameter",
       "[2.0, 1.0]",
       {"inverted", "write diameter = [1.0, 2.0]"}},
      {"fill_too_dense.toml", 16, "particles[0].fill.count", "100", {"42 % of the region's volume", "at most 30 %"}},
      // Issue 17, item 5: under the 30 % rule, but a 45-degree strip 0.18 m across cannot hold spheres of 0.2 m.
      {"fill_narrow_region.toml",
       16,
       "particles[0].fill.count",
       "40",
       {"only 0 of 40 spheres could be placed without overlap", "wider than the largest diameter everywhere"}},
      {"fill_polygon_not_simple.toml",
       16,
       "particles[0].fill.polygon_xz",
       "[[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]]",
       {"the polygon is not simple: edge 0 (vertices 0 and 1) meets edge 2"}},
      {"fluid_profile_crossing.toml",
       24,
       "fluids[0].profile",
       "[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]",
       {"edge 0-1 crosses edge 2-3", "without crossings"}},
      {"fill_sieve_not_increasing.toml",
       16,
       "particles[0].fill.sieve",
       "[[1.0, 0.0], [2.0, 0.5], [1.5, 1.0]]",
       {"row 2: the diameter 1.5 m does not exceed the previous row's", "fraction finer"}},
      {"fill_box_and_polygon.toml",
       16,
       "particles[0].fill.polygon_xz",
       "[[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]]",
       {"a box (min, max) or a polygon (polygon_xz, y_range), not both"}},
      {"fill_normal_mean_outside.toml",
       16,
       "particles[0].fill.mean_diameter",
       "2.5",
       {"outside the clip range diameter = [1.0, 2.0]"}},
      {"dem_pair_unknown_material.toml",
       22,
       "contact.dem_dem.pairs[0].materials",
       "[\"granite\", \"granit\"]",
       {"no material is named \"granit\"", "Did you mean 'granite'?"}},
      {"restitution_without_hertz.toml",
       20,
       "contact.dem_dem.restitution",
       "0.3",
       {"restitution applies to model = \"hertz_mindlin\"", "set model = \"hertz_mindlin\""}},
      {"dem_fem_restitution_without_hertz.toml",
       34,
       "contact.dem_fem.restitution",
       "0.5",
       {"this contact uses the penalty law", "set model = \"hertz_mindlin\" in [contact.dem_fem]"}},
      {"interaction_restitution_without_hertz.toml",
       34,
       "interactions[0].restitution",
       "0.5",
       {"this contact uses the penalty law", "in this interaction or in [contact.dem_fem]"}},
      {"bad_format_version.toml", 2, "format_version", "2", {"reads format_version 1 only"}},
      {"bad_endpoint.toml",
       7,
       "run.endpoint",
       "\"udp://127.0.0.1:5555\"",
       {"must be \"ipc\", \"tcp\" or \"tcp://HOST:PORT\""}},
      {"bad_endpoint_host.toml",
       7,
       "run.endpoint",
       "\"tcp://999.1.1.1:5555\"",
       {"the host 999.1.1.1 is not an IPv4 address: 999 is not a number from 0 to 255", "tcp://127.0.0.1:5555"}},
      {"unknown_recording_field.toml",
       19,
       "recording.fields",
       "[\"velocity\", \"positon\"]",
       {"\"positon\" is not one of", "Did you mean \"position\"?"}},
      {"recording_step_range.toml", 20, "recording.last_step", "10", {"before first_step = 100"}},
      {"missing_required_key.toml",
       4,
       "run.output_interval",
       "",
       {"missing; it is required (s)", "add output_interval"}},
      {"unknown_shape.toml", 26, "structures[0].shape", "\"plain\"", {"Did you mean \"plane\"?"}},
      {"key_of_other_shape.toml",
       30,
       "structures[0].slope_deg",
       "20.0",
       {"belongs to shape = \"chute\", not to shape = \"plane\""}},
      // Issue 18: every mesh file is read by the check, through the solvers' readers.
      {"mesh_stl_garbage.toml",
       22,
       "structures[0].file",
       "\"meshes/garbage.stl\"",
       {"the mesh cannot be read:", "not an STL file: 105 bytes of text that does not start with 'solid'",
        "export the mesh as STL"}},
      {"mesh_stl_empty.toml",
       22,
       "structures[0].file",
       "\"meshes/empty.stl\"",
       {"the mesh cannot be read:", "not an STL file: 0 bytes"}},
      {"mesh_stl_truncated_binary.toml",
       22,
       "structures[0].file",
       "\"meshes/truncated_binary.stl\"",
       {"binary STL declares 12 triangles but the file holds 5.34: truncated file?", "export the mesh again"}},
      {"mesh_stl_huge_count.toml",
       22,
       "structures[0].file",
       "\"meshes/huge_count.stl\"",
       {"binary STL declares 4000000000 triangles but the file holds 1"}},
      {"mesh_stl_truncated_ascii.toml",
       22,
       "structures[0].file",
       "\"meshes/truncated_ascii.stl\"",
       {"truncated_ascii.stl:12: ASCII STL: expected 'vertex'", "but found the end of the file",
        "the file is truncated"}},
      {"mesh_stl_nan_vertex.toml",
       22,
       "structures[0].file",
       "\"meshes/nan_vertex.stl\"",
       {"nan_vertex.stl:12: a vertex coordinate is 'nan', not a finite number"}},
      {"mesh_stl_degenerate.toml",
       22,
       "structures[0].file",
       "\"meshes/degenerate.stl\"",
       {"all 2 triangles have zero area"}},
      {"mesh_msh_garbage.toml",
       18,
       "structures[0].file",
       "\"meshes/garbage.msh\"",
       {"garbage.msh:2: missing $MeshFormat, $Nodes or $Elements"}},
      {"mesh_msh_empty.toml",
       18,
       "structures[0].file",
       "\"meshes/empty.msh\"",
       {"empty.msh: not a Gmsh mesh: the file is empty (0 bytes)", "export the mesh from Gmsh as msh 4.1 ASCII"}},
      {"mesh_msh_truncated.toml",
       18,
       "structures[0].file",
       "\"meshes/truncated.msh\"",
       {"truncated.msh:26: the file ends where node coordinates was expected", "the file is truncated"}},
      {"mesh_msh_huge_count.toml",
       18,
       "structures[0].file",
       "\"meshes/huge_count.msh\"",
       {"huge_count.msh:9: the header declares 4000000000 nodes, more than a file of 325 bytes can hold"}},
      {"mesh_msh_nan_node.toml",
       18,
       "structures[0].file",
       "\"meshes/nan_node.msh\"",
       {"nan_node.msh:27: node coordinates x y z: 'nan 1 0' is not a finite number"}},
      {"mesh_msh_inverted_hex.toml",
       18,
       "structures[0].file",
       "\"meshes/inverted_hex.msh\"",
       {"inverted_hex.msh:41: hexahedron 2 is inverted or flat (volume -1 m^3)", "fix the element's node order"}},
      {"mesh_msh_degenerate_quad.toml",
       19,
       "structures[0].file",
       "\"meshes/degenerate_quad.msh\"",
       {"degenerate_quad.msh:24: quadrangle 2 has zero area"}},
      // Issue 18: what the scene would cost, against this machine and the bounds of a run.
      {"sph_spacing_too_fine.toml",
       15,
       "sph.particle_spacing",
       "0.0001",
       {"GiB of memory (1e+12 fluid particles of ", "more than this machine's", "raise sph.particle_spacing"}},
      {"element_size_too_fine.toml",
       21,
       "structures[0].element_size",
       "0.0001",
       {"GiB of memory (8e+12 elements in structures[0])", "raise element_size"}},
      {"output_interval_too_small.toml",
       6,
       "run.output_interval",
       "1e-300",
       {"end_time = 4.0 s holds 4e+300 output times", "at most 1e+06",
        "give output_interval >= end_time / 1e+06 = "
        "4e-06 s"}},
      {"youngs_modulus_huge.toml",
       11,
       "materials.concrete.youngs_modulus",
       "1e+300",
       {"the run would take about 4.3e+148 steps, more than the 1e+10 that can be run",
        "the fem_solver's step L / c of structure 'dam'", "check the modulus"}},
      {"not_utf8_nul.toml",
       5,
       "",
       "",
       {"the file is not UTF-8 text: at byte offset 135 there is a NUL byte (0x00)", "remove the NUL byte"}},
      {"not_utf8_utf16.toml",
       1,
       "",
       "",
       {"the file is not UTF-8 text: at byte offset 0 there is the UTF-16 byte-order mark FF FE",
        "iconv -f UTF-16 -t UTF-8"}},
      {"constraint_unknown_tag.toml",
       20,
       "structures[0].constraints[0].tag",
       "\"impcat\"",
       {"taylor_bar_4x15.msh has no physical group of that name. Did you mean 'impact'?",
        "use one of the file's groups: bar, impact, top, side"}},
      {"constraint_box_misses_structure.toml",
       22,
       "structures[0].constraints[0].box",
       "{ max = [3.0, 1.0, 0.0], min = [2.0, 0.0, 0.0] }",
       {"the box misses the structure, which spans [0.0, 0.0, 0.0] to [1.0, 1.0, 0.5]", "move or grow the box"}},
      {"constraint_rotation_on_solid.toml",
       22,
       "structures[0].constraints[0].dofs",
       "[\"z\", \"rx\"]",
       {"rotations belong to shells", "hold \"x\", \"y\" or \"z\""}},
      {"fem_fem_structure_with_itself.toml",
       33,
       "interactions[0].pair",
       "[\"block\", \"block\"]",
       {"names one structure twice", "pair two different structures"}},
      {"fem_fem_contact_one_structure.toml",
       24,
       "contact.fem_fem",
       "",
       {"structure-structure contact needs two structures, one of them deformable", "remove [contact.fem_fem]"}},
      {"many_errors.toml",
       5,
       "run.end_time",
       "0.0",
       {":9: key 'materials.granite.density' = -3000.0: must be > 0 (kg/m^3)",
        ":16: key 'particles[0].spheres[0].colour' = \"red\": unknown key"}},
      {"gauge_outside_domain.toml",
       44,
       "gauges[0].end",
       "[0.05, 0.05, 0.5]",
       {"outside the SPH domain", "(sph.domain_min/domain_max, line 21)", "move the gauge into the domain"}},
      {"sensor_empty_box.toml",
       43,
       "sensors[0].min",
       "[0.02, 0.02, 0.01]",
       {"meets none of the surface of 'floor', which spans [0.0, 0.0, 0.0] to [0.1, 0.1, 0.0]",
        "move the box onto the part's face"}},
      {"sensor_unknown_part.toml", 42, "sensors[0].part", "\"flor\"", {"Did you mean 'floor'?"}},
  };
  return scenes;
}

// The message's first line.
std::string first_line(const std::string& message) {
  return message.substr(0, message.find('\n'));
}

void expect_names_everything(const BadScene& bad, const std::string& message, const std::string& file) {
  const std::string head = first_line(message);
  EXPECT_EQ(head.rfind(file + ":" + std::to_string(bad.line) + ":", 0), 0u) << head;
  if (!bad.key.empty()) {
    EXPECT_NE(head.find("key '" + bad.key + "'"), std::string::npos) << head;
  }
  if (!bad.value.empty()) {
    EXPECT_NE(head.find("' = " + bad.value + ":"), std::string::npos) << head;
  }
  for (const auto& text : bad.also) EXPECT_NE(message.find(text), std::string::npos) << text << "\n" << message;
  // Every line says how to fix it.
  std::size_t start = 0;
  while (start < message.size()) {
    const std::size_t end = std::min(message.find('\n', start), message.size());
    EXPECT_NE(message.substr(start, end - start).find(" Fix: "), std::string::npos) << message;
    start = end + 1;
  }
}

TEST(BadScenes, EveryFileIsCovered) {
  std::set<std::string> on_disk, listed;
  for (const auto& entry : std::filesystem::directory_iterator(bad_folder())) {
    if (entry.path().extension() == ".toml") on_disk.insert(entry.path().filename().string());
  }
  for (const auto& bad : bad_scenes()) listed.insert(bad.file);
  EXPECT_EQ(on_disk, listed);
}

TEST(BadScenes, LoaderNamesFileLineKeyValue) {
  for (const auto& bad : bad_scenes()) {
    SCOPED_TRACE(bad.file);
    const std::string file = (bad_folder() / bad.file).string();
    try {
      (void)load_scene(file);
      ADD_FAILURE() << "loaded without error";
    } catch (const SceneError& error) {
      std::cout << error.what() << "\n";
      expect_names_everything(bad, error.what(), file);
    }
  }
}

TEST(BadScenes, ToolExitsWithTwoAndPrintsTheMessage) {
  for (const auto& bad : bad_scenes()) {
    SCOPED_TRACE(bad.file);
    const std::string file = (bad_folder() / bad.file).string();
    const auto result = testing::run_tool("check '" + file + "'");
    EXPECT_EQ(result.exit_code, 2) << result.err;
    EXPECT_TRUE(result.out.empty()) << result.out;
    expect_names_everything(bad, result.err, file);
  }
}

}  // namespace
}  // namespace sabo::scene
