// [[structures]]: shapes, meshes, deformable parts, constraints, slits: the schema of the section and its reader.

#include "libsabo/scene/detail/builder.hpp"
#include "libsabo/scene/detail/schema_tables.hpp"

namespace sabo::scene::schema::detail {

void Schema::build_structures() {
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
      "* `channel`: a floor `width` wide that follows a longitudinal profile, the points (s, z) of `profile` or "
      "of the CSV file `profile_file`: s the horizontal distance along `direction` from `origin` (its z is "
      "ignored), z the bed's absolute elevation, s strictly increasing. Vertical side walls stand `wall_height` "
      "above the bed; `start_wall_height` and `end_wall_height` > 0 close the first and the last end. Each "
      "straight piece of the profile is meshed on its own, so every point of the profile is a row of nodes. The "
      "Wenjia scenes draw the gully this way (docs/wenjia.md).\n"
      "* `mesh`: a triangulated surface read from an STL file (ASCII or binary), scaled by `scale` and then "
      "translated by `translate`.\n"
      "* `terrain`: the ground of an elevation raster `raster_file` (a GeoTIFF, an ESRI ASCII grid or any raster "
      "GDAL reads; band 1 the elevation in m, north-up), rigid: a `strip` `strip_width` wide along a polyline, "
      "the inside of `clip_polygon`, or the whole raster, meshed at `element_size` (the raster's cell without it) "
      "with each node at the raster's elevation there (bilinear between cell centres), then translated by "
      "`translate` (a projected raster's coordinates are large: move the region near the origin). Coordinates "
      "(x, y) of `strip` and `clip_polygon` are the raster's own. The fem_solver's log and summary.json "
      "(`active_effects`, `fem_terrain_from_raster`) name the raster and its "
      "coordinate system.\n\n"
      "The loader normalises `normal` and `direction` (the plane's `direction` is first projected onto the "
      "plane) and makes the mesh path absolute.";
  const std::vector<std::string> plane_chute{"plane", "chute"};
  const std::vector<std::string> plane_chute_channel{"plane", "chute", "channel"};
  const std::vector<std::string> chute_channel{"chute", "channel"};
  structure.keys = {
      K("name", Type::string)
          .required("\"chute\"")
          .allowed("letters, digits, `_`, `-`")
          .doc("Name of the part, unique among particle sets and structures."),
      K("material", Type::string).required("\"concrete\"").allowed("a `[materials.NAME]`").doc("Material."),
      K("rigid", Type::boolean)
          .def(Structure{}.rigid)
          .doc("Rigid part, fixed in space. `false`: deformable (explicit FEM, docs/physics.md): a `box` "
               "without thickness is a solid of hexahedra; a `box` with a `thickness` is a thin-walled "
               "building of shells (four walls, `floors` slabs with the roof); a `plane` with a "
               "`thickness` is a shell panel. Elements of about `element_size`."),
      K("fixed", Type::string_list)
          .def(Structure{}.fixed_faces)
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
      K("velocity", Type::vec3).def(Structure{}.velocity).unit("m/s").doc("Deformable: initial velocity."),
      K("element_formulation", Type::string)
          .def(Structure{}.element_formulation)
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
          .def(Structure{}.floors)
          .ge(1)
          .only_for({"box"})
          .doc("Deformable building (box with a thickness): storeys; a slab tops each."),
      K("roof_thickness", Type::number)
          .def(Structure{}.roof_thickness)
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
          .def(Structure{}.slit_count)
          .ge(0)
          .only_for({"box"})
          .doc("Deformable solid box (no `thickness`): a slit dam. Number of vertical slits, open at the top, "
               "cut through the box along `slit_axis` and spaced evenly along the other horizontal axis (the "
               "`slit_count + 1` piers between them are equally wide). 0: a plain box."),
      K("slit_width", Type::number)
          .def(Structure{}.slit_width)
          .unit("m")
          .ge(0)
          .only_for({"box"})
          .doc("Slit dam: width of each slit; with `slit_count`, below the box's length across `slit_axis`."),
      K("slit_depth", Type::number)
          .def(Structure{}.slit_depth)
          .unit("m")
          .ge(0)
          .only_for({"box"})
          .doc("Slit dam: depth of the slits from the top of the box down; at most its height (`max.z - min.z`; "
               "equal: the slits reach the ground)."),
      K("slit_axis", Type::string)
          .def(Structure{}.slit_axis == 0 ? "x" : "y")
          .choices({"x", "y"})
          .only_for({"box"})
          .doc("Slit dam: the horizontal axis the slits pass through (the flow direction, across the dam's "
               "thickness)."),
      K("thickness", Type::number)
          .def(Structure{}.thickness)
          .unit("m")
          .ge(0)
          .doc("Shell thickness: contact acts at half of it from the surface (paper eq. 3); 0 for a solid face."),
      K("shape", Type::string)
          .required("\"plane\"")
          .choices({"plane", "box", "chute", "channel", "mesh", "terrain"})
          .doc("Kind of geometry."),
      K("origin", Type::vec3)
          .required("[0.0, 0.0, 0.0]")
          .unit("m")
          .only_for(plane_chute_channel)
          .doc("Plane: centre. Chute: centre of the floor's upper edge. Channel: the point on the channel's "
               "centre line where s = 0 (its z is ignored: the profile's elevations are absolute)."),
      K("normal", Type::vec3).def(Shape{}.normal).only_for({"plane"}).doc("Normal, not zero."),
      K("direction", Type::vec3)
          .def(Shape{}.direction)
          .only_for(plane_chute_channel)
          .doc("Plane: direction of `length`, not along the normal. Chute: horizontal downhill direction "
               "(z = 0). Channel: the horizontal direction of increasing s (z = 0)."),
      K("length", Type::number)
          .required("20.0")
          .unit("m")
          .gt(0)
          .only_for(plane_chute)
          .doc("Plane: side along `direction`. Chute: floor length along the slope."),
      K("width", Type::number)
          .required("8.0")
          .unit("m")
          .gt(0)
          .only_for(plane_chute_channel)
          .doc("Side across (a channel: between its side walls)."),
      K("slope_deg", Type::number)
          .required("20.0")
          .unit("degree")
          .ge(0)
          .lt(90)
          .only_for({"chute"})
          .doc("Inclination of the floor below the horizontal."),
      K("wall_height", Type::number)
          .def(Shape{}.wall_height)
          .unit("m")
          .ge(0)
          .only_for(chute_channel)
          .doc("Height of the side walls (0: none); a channel's measured vertically from the bed."),
      K("end_wall_height", Type::number)
          .def(Shape{}.end_wall_height)
          .unit("m")
          .ge(0)
          .only_for(chute_channel)
          .doc("Height of the wall closing the lower end (a channel: its last point; 0: open end)."),
      K("start_wall_height", Type::number)
          .def(Shape{}.start_wall_height)
          .unit("m")
          .ge(0)
          .only_for({"channel"})
          .doc("Height of the vertical wall closing the channel at its first point (0: open end)."),
      K("floor", Type::boolean)
          .def(Shape{}.floor)
          .only_for({"channel"})
          .doc("`false`: the channel's walls without its floor, a part of their own (another friction on the walls "
               "than on the bed: a channel of the same profile with `wall_height = 0` is the bed)."),
      K("profile", Type::pair_list)
          .absent("use `profile_file`")
          .example("[[0.0, 1300.0], [400.0, 1150.0], [900.0, 985.0]]")
          .unit("m")
          .only_for({"channel"})
          .doc("The longitudinal profile: points (s, z), s strictly increasing, at least two. Give exactly one of "
               "`profile` and `profile_file`."),
      K("profile_file", Type::string)
          .absent("use `profile`")
          .example("\"wenjia_profile.csv\"")
          .only_for({"channel"})
          .allowed("a CSV file, relative to the scene file's folder")
          .doc("The longitudinal profile as a CSV file: one point per line, distance and elevation (m) separated by "
               "a comma, a semicolon or blanks; `#` starts a comment line; the first line may be a header."),
      K("min", Type::vec3).required("[0.0, 0.0, 0.0]").unit("m").only_for({"box"}).doc("Lower corner."),
      K("max", Type::vec3)
          .required("[1.0, 1.0, 1.0]")
          .unit("m")
          .only_for({"box"})
          .doc("Upper corner, above `min` on every axis."),
      K("element_size", Type::number)
          .def(Shape{}.element_size)
          .unit("m")
          .ge(0)
          .only_for({"plane", "box", "chute", "channel", "terrain"})
          .doc("Target edge length of the generated triangles (0: the coarsest mesh; a terrain: the raster's "
               "cell)."),
      K("file", Type::string)
          .required("\"meshes/dam.stl\"")
          .only_for({"mesh"})
          .allowed("an existing `.stl` file (rigid) or `.msh` file (deformable)")
          .doc("STL file, relative to the scene file's folder; for `rigid = false`, a Gmsh msh 4.1 ASCII file of "
               "8-node hexahedra (solid) or 4-node quadrangles (shells of `thickness`)."),
      K("scale", Type::number)
          .def(Shape{}.scale)
          .gt(0)
          .only_for({"mesh"})
          .doc("Scale applied to the file's coordinates."),
      K("translate", Type::vec3)
          .def(Shape{}.translate)
          .unit("m")
          .only_for({"mesh", "terrain"})
          .doc("Translation applied after scaling (a terrain: added to the raster's x, y and elevation)."),
      K("raster_file", Type::string)
          .required("\"terrain/gully.tif\"")
          .only_for({"terrain"})
          .allowed("a raster GDAL reads, relative to the scene file's folder")
          .doc("The elevation raster: band 1 in m, north-up (a rotated raster: `gdalwarp` it first)."),
      K("strip", Type::pair_list)
          .absent("the whole raster, or `clip_polygon`")
          .example("[[500.0, 300.0], [800.0, 420.0], [1200.0, 430.0]]")
          .unit("m")
          .only_for({"terrain"})
          .doc("The centre line (x, y) of the strip kept, at least two points, in the raster's coordinates; at a "
               "bend the cross-section follows the bisector. Needs `strip_width`."),
      K("strip_width", Type::number)
          .absent("no strip")
          .example("40.0")
          .unit("m")
          .gt(0)
          .only_for({"terrain"})
          .doc("Width of the strip, across its centre line."),
      K("clip_polygon", Type::pair_list)
          .absent("the whole raster, or `strip`")
          .example("[[500.0, 300.0], [900.0, 300.0], [900.0, 600.0]]")
          .unit("m")
          .only_for({"terrain"})
          .doc("The polygon (x, y) whose inside is kept, at least three corners, in the raster's coordinates: the "
               "elements of the grid that lie wholly inside."),
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

}  // namespace sabo::scene::schema::detail

namespace sabo::scene::detail {

// Deformable structures: a box meshed with hexahedra, fixed faces, initial velocity.
void Builder::read_deformable(Reader& r, Structure& structure, const std::optional<std::string>& shape) {
  if (auto v = r.strings("fixed")) structure.fixed_faces = *v;
  if (const toml::array* list = r.table_list("constraints")) read_constraints(r, *list, structure);
  if (auto v = r.vec3("velocity")) structure.velocity = *v;
  if (auto v = r.string("element_formulation")) {
    structure.element_formulation = value_named<Structure::ElementFormulation>(*v);
    if (!structure.rigid && structure.thickness > 0 &&
        structure.element_formulation == Structure::ElementFormulation::enhanced_strain) {
      diag_.add(r.line("element_formulation"), r.key_path("element_formulation"),
                value_text(*r.node("element_formulation")),
                "enhanced-strain elements exist for solids (hexahedra) only; this structure has a thickness "
                "(shells)",
                "use element_formulation = \"fully_integrated\" (MITC4 shells) or \"one_point\", or remove the "
                "thickness for a solid of hexahedra");
    }
  }
  const bool building_keys = shape && *shape == "box";
  if (building_keys) {
    if (auto v = r.integer("floors")) structure.floors = static_cast<std::size_t>(*v);
    if (auto v = r.number("roof_thickness")) structure.roof_thickness = *v;
    if (auto v = r.string("roof_material")) {
      structure.roof_material = *v;
      check_material(r, *v, "roof_material");
    }
    if (auto v = r.integer("slit_count")) structure.slit_count = static_cast<std::size_t>(*v);
    if (auto v = r.number("slit_width")) structure.slit_width = *v;
    if (auto v = r.number("slit_depth")) structure.slit_depth = *v;
    if (auto v = r.string("slit_axis")) structure.slit_axis = *v == "x" ? 0 : 1;
    if (!structure.rigid && structure.thickness == 0) {
      for (const char* key : {"floors", "roof_thickness", "roof_material"}) {
        if (r.has(key)) {
          diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                    "belongs to thin-walled buildings, but this box has no thickness (a solid)",
                    "give the walls a thickness, or remove the key");
        }
      }
    }
    if (!structure.rigid && structure.thickness > 0) {
      for (const char* key : kSlitKeys) {
        if (r.has(key)) {
          diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                    "belongs to slit dams (solid boxes), but this box has a thickness (a shell building)",
                    "remove the thickness for a solid dam of hexahedra, or remove the key");
        }
      }
    }
  }
  if (structure.rigid) {
    for (const char* key : {"fixed", "constraints", "velocity", "element_formulation", "floors", "roof_thickness",
                            "roof_material", "slit_count", "slit_width", "slit_depth", "slit_axis"}) {
      if (r.has(key)) {
        diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                  "belongs to deformable structures, but this one is rigid",
                  "remove it, or set rigid = false (shape = \"box\")");
      }
    }
    return;
  }
  if (shape && *shape != "box" && *shape != "mesh" && !(*shape == "plane" && structure.thickness > 0)) {
    diag_.add(r.line("rigid"), r.key_path("rigid"), "false",
              fmt::format("deformable structures are boxes (hexahedra, or shells with a thickness), planes "
                          "with a thickness (shells) or Gmsh meshes, not shape = {}{}",
                          quote_text(*shape), *shape == "plane" ? " without a thickness" : ""),
              "use shape = \"box\" with element_size, give the plane a thickness, or set rigid = true");
  }
}

// The constraints of a deformable structure: each a box or a tag, and its DOFs. What needs the shape
// (the mesh file, the structure's extent) is checked by check_constraints once the shape is read.
void Builder::read_constraints(Reader& structure_reader, const toml::array& list, Structure& structure) {
  constraint_keys_.clear();
  for (std::size_t k = 0; k < list.size(); ++k) {
    const std::string path = structure_reader.key_path(fmt::format("constraints[{}]", k));
    Reader r(diag_, spec("structures-constraints"), *list.get(k)->as_table(), path);
    Constraint constraint;
    constraint.origin = origin(r.line(), path);
    ConstraintKeys keys{r.line(), r.line("box"), r.line("tag"), path, {}};
    const toml::table* box = r.table("box");
    const auto tag = r.string("tag");
    if (box != nullptr) {
      keys.box_value = value_text(*r.node("box"));
      Reader b(diag_, spec("structures-constraints-box"), *box, r.key_path("box"));
      const auto min = b.vec3("min"), max = b.vec3("max");
      if (min && max) {
        constraint.box = Aabb{*min, *max};
        if (((*max).array() < (*min).array()).any()) {
          diag_.add(b.line("max"), b.key_path("max"), value_text(*b.node("max")),
                    fmt::format("the box is inverted: max must be at least min = {} on every axis",
                                value_text(*b.node("min"))),
                    "swap the values of min and max where max < min");
        }
      }
    }
    if (tag) {
      constraint.selection = Constraint::Selection::tag;
      constraint.tag = *tag;
    }
    const bool both = r.has("box") && r.has("tag"), neither = !r.has("box") && !r.has("tag");
    if (both || neither) {
      diag_.add(r.line(), path, value_text(*list.get(k)),
                both ? "gives both box and tag: a constraint selects its nodes one way"
                     : "selects no nodes: it needs a box or a tag",
                both ? "keep one of box and tag (two constraints for two node sets)"
                     : "add box = { min = [...], max = [...] }, or tag = \"GROUP\" for a mesh's physical group");
    }
    if (auto dofs = r.strings("dofs")) {
      if (dofs->empty()) {
        diag_.add(r.line("dofs"), r.key_path("dofs"), "[]", "holds no degree of freedom",
                  "name at least one of \"x\", \"y\", \"z\", \"rx\", \"ry\", \"rz\" or \"all\"");
      }
      for (const std::string& dof : *dofs) {
        if (dof == "all") {
          constraint.all = true;
          constraint.dofs |= Constraint::translations;
          continue;
        }
        static constexpr std::array<std::pair<const char*, unsigned>, 6> kBits{{{"x", Constraint::x},
                                                                                {"y", Constraint::y},
                                                                                {"z", Constraint::z},
                                                                                {"rx", Constraint::rx},
                                                                                {"ry", Constraint::ry},
                                                                                {"rz", Constraint::rz}}};
        for (const auto& [name, bit] : kBits) {
          if (dof == name) constraint.dofs |= bit;
        }
      }
      if ((constraint.dofs & Constraint::rotations) != 0 && structure.thickness == 0) {
        diag_.add(r.line("dofs"), r.key_path("dofs"), value_text(*r.node("dofs")),
                  "rotations belong to shells, and this structure has no thickness (a solid: its nodes have the "
                  "three translations only)",
                  "hold \"x\", \"y\" or \"z\" (or \"all\"), or give the structure a thickness for shells");
      }
    }
    structure.constraints.push_back(std::move(constraint));
    constraint_keys_.push_back(std::move(keys));
  }
}

// The constraints' selections against the structure's shape: a tag names a non-empty physical group of
// the structure's .msh file; a box holds one of its nodes (meshes) or meets its extent (generated shapes,
// checked node by node by the fem_solver).
void Builder::check_constraints(const Structure& structure, const std::optional<std::string>& shape) {
  if (structure.rigid || structure.constraints.empty() || !shape) return;
  const bool mesh = structure.shape.type == Shape::Type::mesh;
  std::optional<io::GmshGroups> groups;
  std::optional<std::string> unreadable;
  // A missing file or one that is not a .msh file is reported with the key `file`.
  bool reported = false;
  const auto read_groups = [&]() {
    if (groups || unreadable) return;
    std::error_code ec;
    std::string extension = structure.shape.file.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (structure.shape.file.empty() || !fs::is_regular_file(structure.shape.file, ec) || extension != ".msh") {
      unreadable = "the mesh file is missing";
      reported = true;
      return;
    }
    try {
      groups = io::read_gmsh_groups(structure.shape.file);
    } catch (const Error& error) {
      unreadable = error.what();
    }
  };
  const auto final_position = [&](const Vec3& p) {
    return Vec3(structure.shape.scale * p + structure.shape.translate);
  };
  for (std::size_t k = 0; k < structure.constraints.size(); ++k) {
    const Constraint& c = structure.constraints[k];
    const ConstraintKeys& keys = constraint_keys_[k];
    if (c.selection == Constraint::Selection::tag) {
      const std::string key = keys.path + ".tag";
      if (!mesh) {
        diag_.add(keys.tag_line, key, quote_text(c.tag),
                  fmt::format("a tag names a physical group of a Gmsh mesh, and this structure's shape is {}",
                              quote_text(*shape)),
                  "select the nodes with box = { min = [...], max = [...] }");
        continue;
      }
      read_groups();
      if (unreadable) {
        if (reported) continue;
        diag_.add(keys.tag_line, key, quote_text(c.tag),
                  fmt::format("cannot read the physical groups of {}: {}", structure.shape.file.string(), *unreadable),
                  "repair the mesh file");
        continue;
      }
      const io::GmshGroup* group = groups->find(c.tag);
      if (group == nullptr) {
        const auto names = groups->names();
        const auto suggestion = closest_match(c.tag, names);
        diag_.add(keys.tag_line, key, quote_text(c.tag),
                  fmt::format("{} has no physical group of that name{}", structure.shape.file.filename().string(),
                              suggestion ? fmt::format(". Did you mean '{}'?", *suggestion) : std::string()),
                  names.empty() ? std::string("name the node set in Gmsh (Physical Surface, Physical Curve, ...) "
                                              "and export again, or select the nodes with a box")
                                : fmt::format("use one of the file's groups: {}", join(names)));
        continue;
      }
      if (group->node.empty()) {
        diag_.add(keys.tag_line, key, quote_text(c.tag),
                  fmt::format("the physical group {} of {} holds no elements, so no nodes", quote_text(c.tag),
                              structure.shape.file.filename().string()),
                  "assign elements to the group in Gmsh and export again (Save all elements off), or select the "
                  "nodes with a box");
      }
      continue;
    }
    if (!(c.box.max.array() >= c.box.min.array()).all()) continue;  // inverted: reported
    const std::string key = keys.path + ".box";
    if (mesh) {
      read_groups();
      if (!groups) continue;  // the file's problem is reported with the file (or by the fem_solver)
      Aabb extent;
      bool hit = false;
      for (const Vec3& p : groups->node) {
        const Vec3 q = final_position(p);
        extent.extend(q);
        hit = hit || c.box.contains(q);
      }
      if (!hit) {
        diag_.add(keys.box_line, key, keys.box_value,
                  fmt::format("the box holds no node of the mesh, whose nodes span {} to {} (after scale and "
                              "translate)",
                              vec_text(extent.min), vec_text(extent.max)),
                  "move or grow the box over the nodes to hold");
      }
      continue;
    }
    const Aabb extent = structure_extent(structure);
    if (!extent.overlaps(c.box)) {
      diag_.add(
          keys.box_line, key, keys.box_value,
          fmt::format("the box misses the structure, which spans {} to {}", vec_text(extent.min), vec_text(extent.max)),
          "move or grow the box over the nodes to hold");
    }
  }
}

// The box around a generated deformable structure (a box, or a plane panel).
Aabb Builder::structure_extent(const Structure& structure) {
  const Shape& shape = structure.shape;
  if (shape.type != Shape::Type::plane) return shape.box;
  const Vec3 side = shape.normal.cross(shape.direction).normalized();
  Aabb extent;
  for (double a : {-0.5, 0.5}) {
    for (double b : {-0.5, 0.5})
      extent.extend(shape.origin + a * shape.length * shape.direction + b * shape.width * side);
  }
  return extent;
}

// A slit dam's slits must fit the (deformable, solid) box read before.
void Builder::check_slits(Reader& r, const Structure& structure) {
  if (structure.rigid || structure.thickness > 0) return;
  const Aabb& box = structure.shape.box;
  if (structure.slit_count == 0) {
    for (const char* key : {"slit_width", "slit_depth", "slit_axis"}) {
      if (r.has(key)) {
        diag_.add(r.line(key), r.key_path(key), value_text(*r.node(key)),
                  "a slit dimension without slits (slit_count is 0)",
                  "give slit_count = the number of slits, or remove the key");
      }
    }
    return;
  }
  const int across = structure.slit_axis == 0 ? 1 : 0;  // the axis along which the slits are spaced
  const double length = box.max(across) - box.min(across), height = box.max.z() - box.min.z();
  const char* across_name = across == 0 ? "x" : "y";
  const auto count_text = std::to_string(structure.slit_count);
  if (!(structure.slit_width > 0)) {
    diag_.add(r.has("slit_width") ? r.line("slit_width") : r.line("slit_count"), r.key_path("slit_width"),
              r.has("slit_width") ? std::optional<std::string>(value_text(*r.node("slit_width"))) : std::nullopt,
              fmt::format("slit_count = {} needs the width of the slits", count_text), "give slit_width > 0 (m)");
  } else if (static_cast<double>(structure.slit_count) * structure.slit_width >= length) {
    diag_.add(r.line("slit_width"), r.key_path("slit_width"), value_text(*r.node("slit_width")),
              fmt::format("{} slits of this width take {} m of the box's {} m along {}, leaving no piers", count_text,
                          number_literal(static_cast<double>(structure.slit_count) * structure.slit_width),
                          number_literal(length), across_name),
              fmt::format("give slit_width below {} m, or fewer slits",
                          number_literal(length / static_cast<double>(structure.slit_count))));
  }
  if (!(structure.slit_depth > 0)) {
    diag_.add(r.has("slit_depth") ? r.line("slit_depth") : r.line("slit_count"), r.key_path("slit_depth"),
              r.has("slit_depth") ? std::optional<std::string>(value_text(*r.node("slit_depth"))) : std::nullopt,
              fmt::format("slit_count = {} needs the depth of the slits below the top of the box", count_text),
              fmt::format("give slit_depth in (0, {}] m", number_literal(height)));
  } else if (structure.slit_depth > height) {
    diag_.add(r.line("slit_depth"), r.key_path("slit_depth"), value_text(*r.node("slit_depth")),
              fmt::format("deeper than the box is high ({} m)", number_literal(height)),
              fmt::format("give slit_depth <= {} m (equal: the slits reach the ground)", number_literal(height)));
  }
}

void Builder::read_structure(const toml::table& table, std::size_t index) {
  const std::string path = fmt::format("structures[{}]", index);
  Reader r(diag_, spec("structures"), table, path);
  Structure structure;
  structure.origin = origin(r.line(), path);
  if (auto v = r.string("name")) {
    structure.name = *v;
    register_body(r, structure.name, false);
  }
  if (auto v = r.string("material")) {
    structure.material = *v;
    check_material(r, structure.material);
  }
  if (auto v = r.boolean("rigid")) structure.rigid = *v;
  if (auto v = r.number("thickness")) structure.thickness = *v;
  const auto shape = r.string("shape");
  if (!shape) {
    scene_.structures.push_back(std::move(structure));
    return;
  }
  r.select(*shape);
  read_deformable(r, structure, shape);
  Shape& s = structure.shape;
  if (*shape == "plane") {
    s.type = Shape::Type::plane;
    if (auto v = r.vec3("origin")) s.origin = *v;
    if (auto v = r.number("length")) s.length = *v;
    if (auto v = r.number("width")) s.width = *v;
    const auto normal = r.vec3("normal");
    const auto direction = r.vec3("direction");
    if (normal) {
      if (normal->norm() == 0.0) {
        diag_.add(r.line("normal"), r.key_path("normal"), value_text(*r.node("normal")), "the normal is zero",
                  "give the direction the plane faces, e.g. normal = [0.0, 0.0, 1.0]");
      } else {
        s.normal = normal->normalized();
        if (direction) {
          const Vec3 in_plane = *direction - direction->dot(s.normal) * s.normal;
          if (in_plane.norm() <= 1e-9 * direction->norm()) {
            diag_.add(r.line("direction"), r.key_path("direction"),
                      r.has("direction") ? value_text(*r.node("direction")) : std::string("[1.0, 0.0, 0.0]"),
                      "the direction is zero or along the normal, so it gives no direction in the plane",
                      "give a direction that is not parallel to the normal");
          } else {
            s.direction = in_plane.normalized();
          }
        }
      }
    }
  } else if (*shape == "box") {
    s.type = Shape::Type::box;
    const auto min = r.vec3("min"), max = r.vec3("max");
    if (min && max) {
      s.box = Aabb{*min, *max};
      if (((*max).array() <= (*min).array()).any()) {
        diag_.add(r.line("max"), r.key_path("max"), value_text(*r.node("max")),
                  fmt::format("the box is empty or inverted: max must exceed min = {} on every axis",
                              value_text(*r.node("min"))),
                  "swap the values of min and max where max <= min");
      }
    }
    if (min && max && ((*max).array() > (*min).array()).all()) check_slits(r, structure);
  } else if (*shape == "chute" || *shape == "channel") {
    const bool chute = *shape == "chute";
    s.type = chute ? Shape::Type::chute : Shape::Type::channel;
    if (auto v = r.vec3("origin")) s.origin = *v;
    if (auto v = r.number("width")) s.width = *v;
    if (auto v = r.number("wall_height")) s.wall_height = *v;
    if (auto v = r.number("end_wall_height")) s.end_wall_height = *v;
    if (chute) {
      if (auto v = r.number("length")) s.length = *v;
      if (auto v = r.number("slope_deg")) s.slope_deg = *v;
    } else {
      if (auto v = r.number("start_wall_height")) s.start_wall_height = *v;
      if (auto v = r.boolean("floor")) s.floor = *v;
      if (!s.floor && !(s.wall_height > 0) && !(s.start_wall_height > 0) && !(s.end_wall_height > 0)) {
        diag_.add(r.line("floor"), r.key_path("floor"), "false",
                  "a channel without its floor needs walls, but its wall heights are all 0",
                  "give wall_height (or start_wall_height, end_wall_height) > 0, or remove floor = false");
      }
      read_channel_profile(r, s);
    }
    if (auto direction = r.vec3("direction")) {
      const double horizontal = std::hypot(direction->x(), direction->y());
      if (horizontal == 0.0 || std::abs(direction->z()) > 1e-9 * horizontal) {
        diag_.add(r.line("direction"), r.key_path("direction"),
                  r.has("direction") ? value_text(*r.node("direction")) : std::string("[1.0, 0.0, 0.0]"),
                  fmt::format("a {}'s direction must be horizontal (z = 0) and not zero; {} sets the descent", *shape,
                              chute ? "slope_deg" : "the profile"),
                  fmt::format("write direction = [{}, {}, 0.0]", number_literal(direction->x()),
                              number_literal(direction->y())));
      } else {
        s.direction = Vec3(direction->x(), direction->y(), 0.0) / horizontal;
      }
    }
  } else if (*shape == "terrain") {
    s.type = Shape::Type::terrain;
    if (auto v = r.vec3("translate")) s.translate = *v;
  } else if (*shape == "mesh") {
    s.type = Shape::Type::mesh;
    if (auto v = r.number("scale")) s.scale = *v;
    if (auto v = r.vec3("translate")) s.translate = *v;
    if (auto v = r.string("file")) {
      const std::size_t problems = diag_.count();
      s.file = resolve_mesh(r, *v, structure.rigid);
      if (diag_.count() == problems) read_mesh(r, *v, structure);
    }
  }
  if (s.type != Shape::Type::mesh) {
    if (auto v = r.number("element_size")) s.element_size = *v;
  }
  if (s.type == Shape::Type::terrain) read_terrain(r, structure);
  check_constraints(structure, shape);
  scene_.structures.push_back(std::move(structure));
}

// A channel's profile, inline or from its CSV file (io/pairs_csv.hpp): exactly one of the two, at least
// two points, the distance strictly increasing.
void Builder::read_channel_profile(Reader& r, Shape& shape) {
  const bool inline_profile = r.has("profile"), file_profile = r.has("profile_file");
  if (inline_profile == file_profile) {
    diag_.add(r.line(), r.key_path(inline_profile ? "profile" : "profile_file"),
              inline_profile ? std::optional(value_text(*r.node("profile"))) : std::nullopt,
              inline_profile ? "gives both profile and profile_file: a channel has one profile"
                             : "a channel needs its longitudinal profile",
              inline_profile ? "keep one of profile and profile_file"
                             : "add profile = [[0.0, 100.0], [50.0, 90.0]] (distance, elevation in m) or "
                               "profile_file = \"profile.csv\"");
    return;
  }
  if (inline_profile) {
    const auto points = r.pairs("profile");
    if (!points) return;
    const std::string value = value_text(*r.node("profile"));
    if (points->size() < 2) {
      diag_.add(r.line("profile"), r.key_path("profile"), value,
                fmt::format("a profile needs at least 2 points, not {}", points->size()),
                "list the points (distance, elevation) in order of distance, e.g. [[0.0, 100.0], [50.0, 90.0]]");
      return;
    }
    for (std::size_t k = 1; k < points->size(); ++k) {
      if (!((*points)[k][0] > (*points)[k - 1][0])) {
        diag_.add(r.line("profile"), r.key_path("profile"), value,
                  fmt::format("point {} has distance {} after {} at point {}: a profile is not monotone in distance", k,
                              number_literal((*points)[k][0]), number_literal((*points)[k - 1][0]), k - 1),
                  "sort the points by distance and drop repeated ones");
        return;
      }
    }
    shape.profile = *points;
    return;
  }
  const auto file = r.string("profile_file");
  if (!file) return;
  const fs::path full = scene_relative(*file);
  try {
    for (const io::CsvPair& point : io::read_pairs_csv(full, io::kProfileColumns)) {
      shape.profile.push_back({point.first, point.second});
    }
  } catch (const FileError& error) {
    add_file_error(r, "profile_file", quote_text(*file), "the profile cannot be read", error,
                   "correct the path; it is relative to the scene file's folder");
  }
}

namespace {

// Nodes, triangles and area of a rigid surface (an STL mesh, a terrain): its share of the scene's estimate.
MeshSize surface_size(const geometry::SurfaceMesh& surface) {
  MeshSize size;
  size.nodes = surface.node_position.size();
  size.triangles = surface.triangle.size();
  for (std::size_t f = 0; f < surface.face_count(); ++f) size.area += surface.face_area(f);
  return size;
}

}  // namespace

// A terrain's raster and the ground kept of it (a strip or a polygon), checked by building its surface
// as the solvers will (geometry::triangulate), whose size goes into the scene's estimate.
void Builder::read_terrain(Reader& r, Structure& structure) {
  Shape& shape = structure.shape;
  const bool has_strip = r.has("strip"), has_polygon = r.has("clip_polygon");
  if (has_strip && has_polygon) {
    diag_.add(r.line("clip_polygon"), r.key_path("clip_polygon"), value_text(*r.node("clip_polygon")),
              "gives both strip and clip_polygon: a terrain keeps one region of its raster",
              "keep one of strip (with strip_width) and clip_polygon");
    return;
  }
  if (has_strip) {
    const auto points = r.pairs("strip");
    if (!points) return;
    const std::string value = value_text(*r.node("strip"));
    if (points->size() < 2) {
      diag_.add(r.line("strip"), r.key_path("strip"), value,
                fmt::format("a strip needs a polyline of at least 2 points, not {}", points->size()),
                "list the points (x, y) of the strip's centre line in order, e.g. [[0.0, 0.0], [100.0, 20.0]]");
      return;
    }
    for (std::size_t k = 1; k < points->size(); ++k) {
      if ((*points)[k] == (*points)[k - 1]) {
        diag_.add(r.line("strip"), r.key_path("strip"), value,
                  fmt::format("points {} and {} are the same point", k - 1, k), "drop the repeated point");
        return;
      }
    }
    shape.strip = *points;
    const auto width = r.number("strip_width");
    if (!width) {
      diag_.add(r.line("strip"), r.key_path("strip_width"), std::nullopt, "a strip needs its width",
                "add strip_width = 20.0 (m, across the polyline)");
      return;
    }
    shape.strip_width = *width;
  } else if (r.has("strip_width")) {
    diag_.add(r.line("strip_width"), r.key_path("strip_width"), value_text(*r.node("strip_width")),
              "strip_width without a strip", "add strip = [[x, y], ...] (the strip's centre line) or remove it");
    return;
  }
  if (has_polygon) {
    const auto points = r.pairs("clip_polygon");
    if (!points) return;
    if (points->size() < 3) {
      diag_.add(r.line("clip_polygon"), r.key_path("clip_polygon"), value_text(*r.node("clip_polygon")),
                fmt::format("a polygon needs at least 3 points, not {}", points->size()),
                "list the corners (x, y) in order");
      return;
    }
    shape.clip_polygon = *points;
  }
  const auto file = r.string("raster_file");
  if (!file) return;
  shape.file = scene_relative(*file);
  const std::string region_key = has_strip ? "strip" : has_polygon ? "clip_polygon" : "raster_file";
  try {
    shape.raster = io::describe_raster(shape.file);
  } catch (const FileError& error) {
    add_file_error(r, "raster_file", quote_text(*file), "the raster cannot be read", error,
                   "correct the path; it is relative to the scene file's folder");
    return;
  }
  try {
    shape.mesh_size = surface_size(geometry::triangulate(shape, structure.name));  // the key is named here
  } catch (const Error& error) {
    add_file_error(r, region_key, r.has(region_key) ? value_text(*r.node(region_key)) : quote_text(*file),
                   "the terrain cannot be built", error, "keep the region inside the raster");
  }
}

void Builder::add_file_error(Reader& r, const std::string& key, const std::string& value, const std::string& what,
                             const Error& error, const std::string& fallback_fix) {
  const std::string text = error.what();
  const auto fix = text.rfind(". Fix: ");
  diag_.add(r.line(key), r.key_path(key), value,
            fmt::format("{}: {}", what, fix == std::string::npos ? text : text.substr(0, fix)),
            fix == std::string::npos ? fallback_fix
                                     : text.substr(fix + 7, text.ends_with('.') ? text.size() - fix - 8 : text.npos));
}

// Rigid structures take STL surfaces; deformable ones Gmsh .msh volume or shell meshes.
fs::path Builder::resolve_mesh(Reader& r, const std::string& file, bool rigid) {
  const fs::path full = scene_relative(file);
  const int line = r.line("file");
  std::error_code ec;
  if (!fs::exists(full, ec)) {
    diag_.add(line, r.key_path("file"), quote_text(file), fmt::format("file not found (looked for {})", full.string()),
              "correct the path; it is relative to the scene file's folder");
  } else if (!fs::is_regular_file(full, ec)) {
    diag_.add(line, r.key_path("file"), quote_text(file), fmt::format("{} is not a regular file", full.string()),
              "give the path of an STL file");
  } else {
    std::string extension = full.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (rigid && extension != ".stl") {
      diag_.add(line, r.key_path("file"), quote_text(file), "a mesh must be an STL file ending in .stl",
                "convert the mesh to STL (ASCII or binary)");
    }
    if (!rigid && extension != ".msh") {
      diag_.add(line, r.key_path("file"), quote_text(file),
                "a deformable structure's mesh must be a Gmsh file ending in .msh (hexahedra or quadrangles)",
                "export the mesh from Gmsh as msh 4.1 ASCII, or set rigid = true for an STL surface");
    }
  }
  return fs::weakly_canonical(full, ec);
}

// Reads the mesh file through the reader its solver uses (io/stl.hpp for rigid structures, io/gmsh.hpp
// for deformable ones), so that a file the fem_solver would die of is refused here, and keeps its size
// for the estimate of the scene (scene/estimate.hpp).
void Builder::read_mesh(Reader& r, const std::string& file, Structure& structure) {
  const int line = r.line("file");
  const std::string key = r.key_path("file");
  MeshSize size;
  try {
    if (structure.rigid) {
      size = surface_size(io::read_stl(structure.shape.file).mesh);
    } else {
      const io::GmshMesh gmsh = io::read_gmsh(structure.shape.file);
      size.nodes = gmsh.node.size();
      size.hexahedra = gmsh.hexahedra.size();
      size.quads = gmsh.quads.size();
      double smallest = std::numeric_limits<double>::infinity();
      for (const auto& e : gmsh.hexahedra) {
        std::array<Vec3, 8> x;
        for (std::size_t a = 0; a < 8; ++a) x[a] = gmsh.node[e[a]];
        smallest = std::min(smallest, std::cbrt(geometry::hexahedron_volume(x)));
      }
      for (const auto& q : gmsh.quads) {
        const auto& x = gmsh.node;
        const double area = 0.5 * ((x[q[1]] - x[q[0]]).cross(x[q[2]] - x[q[0]]).norm() +
                                   (x[q[2]] - x[q[0]]).cross(x[q[3]] - x[q[0]]).norm());
        smallest = std::min(smallest, std::sqrt(area));
      }
      size.smallest = smallest;
      if (!gmsh.quads.empty() && gmsh.hexahedra.empty() && !(structure.thickness > 0)) {
        diag_.add(
            line, key, quote_text(file),
            fmt::format("the mesh holds {} quadrangles (shells) but the structure has no thickness", gmsh.quads.size()),
            "give thickness = the shells' thickness in m");
      }
    }
  } catch (const Error& error) {
    add_file_error(r, "file", quote_text(file), "the mesh cannot be read", error, "export the mesh again");
    return;
  }
  structure.shape.mesh_size = size;
}

}  // namespace sabo::scene::detail
