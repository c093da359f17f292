// The checks of the scene loader that span sections: body names, materials, sphere overlaps,
// the cost and the memory of the scene.

#include "libsabo/scene/detail/builder.hpp"

namespace sabo::scene::detail {

void Builder::register_body(Reader& r, const std::string& name, bool is_particle_set, bool is_fluid) {
  const int line = r.line("name");
  if (!valid_name(name)) {
    diag_.add(line, r.key_path("name"), quote_text(name), "a name must be made of letters, digits, '_' and '-'",
              "rename it, e.g. \"boulders_1\"");
    return;
  }
  auto [it, inserted] = bodies_.try_emplace(name, BodyName{is_particle_set, r.path(), line, is_fluid});
  if (!inserted) {
    diag_.add(line, r.key_path("name"), quote_text(name),
              fmt::format("the name is already used by {} (line {})", it->second.path, it->second.line),
              "give each fluid, particle set and structure its own name");
  }
}

void Builder::check_material(Reader& r, const std::string& material, const char* key) {
  if (std::find(material_names_.begin(), material_names_.end(), material) != material_names_.end()) return;
  const auto suggestion = closest_match(material, material_names_);
  std::string problem = "no material of that name";
  if (suggestion) problem += fmt::format(". Did you mean '{}'?", *suggestion);
  const std::string fix = material_names_.empty()
                              ? fmt::format("add a [materials.{}] table", material)
                              : fmt::format("define [materials.{}] or use one of: {}", material, join(material_names_));
  diag_.add(r.line(key), r.key_path(key), quote_text(material), problem, fix);
}

// Listed spheres must not overlap: sweep along x over spheres sorted by
// their lowest x (deterministic order: ties broken by file order).
void Builder::check_overlaps() {
  std::vector<std::size_t> order(listed_.size());
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return listed_[a].center.x() - listed_[a].radius < listed_[b].center.x() - listed_[b].radius;
  });
  std::size_t reported = 0, more = 0;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const ListedSphere& a = listed_[order[i]];
    for (std::size_t j = i + 1; j < order.size(); ++j) {
      const ListedSphere& b = listed_[order[j]];
      if (b.center.x() - b.radius >= a.center.x() + a.radius) break;
      const double depth = a.radius + b.radius - (a.center - b.center).norm();
      if (depth <= 1e-9 * (a.radius + b.radius)) continue;
      const bool a_first = order[i] < order[j];
      const ListedSphere& earlier = a_first ? a : b;
      const ListedSphere& later = a_first ? b : a;
      if (reported == kMaxOverlapReports) {
        ++more;
        continue;
      }
      ++reported;
      diag_.add(
          later.line, later.path,
          fmt::format("{{ center = [{}, {}, {}], radius = {} }}", number_literal(later.center.x()),
                      number_literal(later.center.y()), number_literal(later.center.z()), number_literal(later.radius)),
          fmt::format("overlaps {} (line {}) by {} m", earlier.path, earlier.line, fmt::format("{:.4g}", depth)),
          "move the spheres apart or make them smaller; initial spheres must not overlap");
    }
  }
  if (more > 0) {
    diag_.add_plain(listed_[order.front()].line, fmt::format("{} more pairs of listed spheres overlap", more),
                    "separate every overlapping pair");
  }
}

// The line of a dotted key of the document ("sph.particle_spacing", "particles[2].fill.count"), else of the
// nearest table above it that is written, else 1.
int Builder::line_of_key(std::string path) const {
  while (!path.empty()) {
    const toml::node_view<const toml::node> node = toml::at_path(document_, path);
    if (node && line_of(*node.node()) > 0) return line_of(*node.node());
    const auto cut = path.find_last_of(".[");
    path = cut == std::string::npos ? std::string() : path.substr(0, cut);
  }
  return 1;
}

std::optional<std::string> Builder::value_of_key(const std::string& path) const {
  const toml::node_view<const toml::node> node = toml::at_path(document_, path);
  if (!node) return std::nullopt;
  return value_text(*node.node());
}

// What the scene would cost (scene/estimate.hpp): refused when it cannot be run on this machine, naming
// the estimate and the key to change.
void Builder::check_costs() {
  const SceneEstimate estimate = estimate_scene(scene_);
  const RunSettings& run = scene_.run;
  if (estimate.outputs > kMaxOutputs) {
    diag_.add(
        line_of_key("run.output_interval"), "run.output_interval", number_literal(run.output_interval),
        fmt::format("end_time = {} s holds {:.3g} output times, each writing a file per solver; at most {:g} "
                    "are allowed",
                    number_literal(run.end_time), estimate.outputs, kMaxOutputs),
        fmt::format("give output_interval >= end_time / {:g} = {:.3g} s", kMaxOutputs, run.end_time / kMaxOutputs));
  }
  if (estimate.steps > kMaxSteps) {
    const std::string& key = estimate.dt_key;
    diag_.add(line_of_key(key), key, value_of_key(key),
              fmt::format("the run would take about {:.3g} steps, more than the {:g} that can be run: {} gives a "
                          "stable step of about {:.3g} s for end_time = {} s",
                          estimate.steps, kMaxSteps, estimate.dt_what, estimate.dt, number_literal(run.end_time)),
              key.ends_with("youngs_modulus")
                  ? "check the modulus (rock and concrete: 1e10 to 1e11 Pa; a softer material gives a longer step), "
                    "or shorten run.end_time"
                  : fmt::format("raise {} (the step grows with it), or shorten run.end_time", key));
  }
  const double memory = physical_memory_bytes();
  if (memory > 0 && estimate.memory_bytes > memory) report_memory(estimate, memory);
}

// The scene needs more memory than the machine has: the estimate, and the key of its largest share.
void Builder::report_memory(const SceneEstimate& e, double memory) {
  struct Share {
    double bytes;
    std::string what, key, fix;
  };
  std::vector<Share> shares;
  const double fluid = e.total_fluid_particles();
  if (fluid > 0) {
    shares.push_back({fluid * kBytesPerFluidParticle,
                      fmt::format("{:.3g} fluid particles of {:g} B", fluid, kBytesPerFluidParticle),
                      "sph.particle_spacing",
                      "raise sph.particle_spacing (doubling it divides the fluid particles by 8 and the wall "
                      "particles by 4)"});
  }
  if (e.wall_particles > 0) {
    shares.push_back({e.wall_particles * kBytesPerWallParticle,
                      fmt::format("{:.3g} wall particles of {:g} B", e.wall_particles, kBytesPerWallParticle),
                      "sph.particle_spacing",
                      "raise sph.particle_spacing (doubling it divides the wall particles by 4), or use "
                      "sph.wall_model = \"penalty\""});
  }
  for (std::size_t k = 0; k < e.spheres.size(); ++k) {
    if (scene_.particle_sets[k].kind != ParticleSet::Kind::fill) continue;
    shares.push_back({e.spheres[k] * kBytesPerSphere,
                      fmt::format("{:.3g} spheres of {:g} B in particles[{}]", e.spheres[k], kBytesPerSphere, k),
                      fmt::format("particles[{}].fill.count", k), "lower the count"});
  }
  for (std::size_t k = 0; k < scene_.structures.size(); ++k) {
    const Structure& s = scene_.structures[k];
    const bool mesh = s.shape.type == Shape::Type::mesh;
    shares.push_back({e.structure_bytes[k],
                      s.rigid ? fmt::format("{:.3g} surface triangles in structures[{}]", e.surface_triangles[k], k)
                              : fmt::format("{:.3g} elements in structures[{}]", e.elements[k], k),
                      fmt::format("structures[{}].{}", k, mesh ? "file" : "element_size"),
                      mesh ? std::string("give a coarser mesh") : std::string("raise element_size")});
  }
  std::vector<std::string> parts;
  for (const Share& share : shares) parts.push_back(share.what);
  const auto largest =
      std::max_element(shares.begin(), shares.end(), [](const Share& a, const Share& b) { return a.bytes < b.bytes; });
  const std::string key = largest != shares.end() ? largest->key : std::string("run");
  diag_.add(line_of_key(key), key, value_of_key(key),
            fmt::format("the scene needs about {:.3g} GiB of memory ({}), more than this machine's {:.3g} GiB",
                        e.memory_bytes / kGiB, join(parts), memory / kGiB),
            largest != shares.end() ? largest->fix : std::string("make the scene smaller"));
}

}  // namespace sabo::scene::detail
