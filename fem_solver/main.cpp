// fem_solver: the structures of a scene, coupled through the Sabo protocol.
//   fem_solver --scene FILE --coupler ENDPOINT [--out DIR]
// The physics is FemModel (fem_model.hpp); this file is the protocol side.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "fem_solver/fem_model.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/protocol/surface_codec.hpp"
#include "libsabo/solver/driver.hpp"

namespace sabo::fem {
namespace {

class FemSolver final : public solver::CoupledSolver {
 public:
  FemSolver(const scene::Scene& scene, const solver::SolverOptions& options)
      : model_(scene), out_dir_(options.out_dir), limits_(solver::stability_limits(scene, Role::fem)) {
    spdlog::info("{} parts, {} surface nodes, {} faces", model_.part_count(), model_.surface().node_count(),
                 model_.surface().face_count());
    for (const scene::Structure& structure : scene.structures) {
      if (structure.shape.type == scene::Shape::Type::terrain) {
        spdlog::info("terrain '{}' from the raster {}", structure.name, structure.shape.raster);
      }
    }
  }

  void describe(sabo::v1::Register& registration) override {
    registration.set_name("fem_solver " SABO_VERSION);
    registration.set_exposes_surface(true);
    protocol::surface_to_message(model_.surface(), 0, *registration.mutable_surface());
  }

  double stable_dt() override { return model_.stable_dt(); }

  void fill_state(const solver::Interest& /*interest*/, sabo::v1::StepState& state) override {
    // A new topology (elements eroded) goes out before the nodes that use it.
    if (model_.update_surface()) {
      protocol::surface_to_message(model_.surface(), model_.surface_revision(), *state.mutable_topology());
      spdlog::info("surface changed (revision {}): {} nodes, {} faces", model_.surface_revision(),
                   model_.surface().node_count(), model_.surface().face_count());
    }
    // Rigid parts never move: with only those, no node arrays are sent after
    // registration (empty arrays mean "unchanged", docs/protocol.md).
    if (model_.moved()) {
      const auto& positions = model_.surface().node_position;
      const auto velocities = model_.node_velocities();
      auto* p = state.mutable_node_position();
      auto* v = state.mutable_node_velocity();
      p->Resize(static_cast<int>(3 * positions.size()), 0.0);
      v->Resize(static_cast<int>(3 * positions.size()), 0.0);
      for (std::size_t i = 0; i < positions.size(); ++i) {
        for (int d = 0; d < 3; ++d) {
          p->Set(static_cast<int>(3 * i) + d, positions[i](d));
          v->Set(static_cast<int>(3 * i) + d, velocities[i](d));
        }
      }
    }
    const Energies e = model_.energies();
    solver::set_energies(state, {e.kinetic, e.potential, e.elastic, e.dissipated});
    for (std::size_t index = 0; index < model_.part_count(); ++index) {
      const DeformablePart* part = model_.deformable(index);
      if (part == nullptr) continue;
      const SolidEnergies pe = part->solid_energies();
      auto* out = state.add_part_energies();
      out->set_part(model_.part(index).name);
      out->set_kinetic(pe.kinetic);
      out->set_internal(pe.internal);
      out->set_plastic_work(pe.plastic_work);
      out->set_hourglass(pe.hourglass);
      out->set_eroded(pe.eroded);
      out->set_external_work(pe.external_work);
      out->set_eroded_elements(part->eroded_count());
    }
  }

  void compute_internal_forces(double dt_previous) override { model_.compute_internal_forces(dt_previous); }

  void apply_coupling_forces(const sabo::v1::StepForces& forces) override {
    model_.apply_node_forces({forces.node_force().data(), static_cast<std::size_t>(forces.node_force_size())});
  }

  [[nodiscard]] bool can_take_state() const override { return true; }
  void take_state(const sabo::v1::StepState& recorded) override {
    if (!recorded.index().empty() || !recorded.position().empty() || !recorded.velocity().empty() ||
        !recorded.angular_velocity().empty()) {
      throw ProtocolError("StepForces.taken: particle fields for the fem_solver, which has surface nodes only");
    }
    const auto& ids = recorded.topology().node_id();
    model_.take_node_states({ids.data(), static_cast<std::size_t>(ids.size())},
                            {recorded.node_position().data(), static_cast<std::size_t>(recorded.node_position_size())},
                            {recorded.node_velocity().data(), static_cast<std::size_t>(recorded.node_velocity_size())});
  }

  void write_output(std::uint64_t step, double time) override { model_.write_output(out_dir_, step, time); }
  void integrate(double /*dt_previous*/, double dt) override { model_.step(dt); }
  [[nodiscard]] std::uint32_t max_substeps() const override { return solver::kMaxSubsteps; }
  [[nodiscard]] bool can_checkpoint() const override { return true; }
  void save_checkpoint(io::hdf5::Group& group) const override {
    io::hdf5::Group model = group.create_group("model");
    model_.save_state(model);
    io::hdf5::Group output = group.create_group("output");
    model_.save_output_state(output, out_dir_);
  }
  void load_checkpoint(const io::hdf5::Group& group) override {
    model_.load_state(group.group("model"));
    model_.load_output_state(group.group("output"), out_dir_);
  }
  // Each deformable part's largest von Mises stress of the run: summary.json results.fem_solver.parts.
  [[nodiscard]] std::string results() const override {
    nlohmann::json parts = nlohmann::json::object();
    for (std::size_t index = 0; index < model_.part_count(); ++index) {
      const DeformablePart* part = model_.deformable(index);
      if (part == nullptr) continue;
      const DeformablePart::StressPeak& peak = part->peak_stress();
      parts[model_.part(index).name] = {{"peak_von_mises", peak.von_mises},
                                        {"peak_von_mises_time", peak.time},
                                        {"peak_von_mises_element", peak.element}};
    }
    return parts.empty() ? std::string() : nlohmann::json{{"parts", parts}}.dump();
  }
  void finish() override {
    for (std::size_t index = 0; index < model_.part_count(); ++index) {
      const DeformablePart* part = model_.deformable(index);
      if (part == nullptr) continue;
      const SolidEnergies e = part->solid_energies();
      spdlog::info(
          "part '{}': kinetic {:.4g} J, internal {:.4g} J, plastic work {:.4g} J, hourglass {:.4g} J ({:.1f}% of "
          "internal), eroded {:.4g} J, external work {:.4g} J",
          model_.part(index).name, e.kinetic, e.internal, e.plastic_work, e.hourglass,
          e.internal > 0 ? 100.0 * e.hourglass / e.internal : 0.0, e.eroded, e.external_work);
    }
  }

  // Every deformable part's nodes (not finite, too fast), and its hexahedra: one of a material that does not
  // erode turning inside out is an instability (an eroding material's element fails instead).
  [[nodiscard]] std::optional<solver::Instability> check_stability() const override {
    for (std::size_t index = 0; index < model_.part_count(); ++index) {
      const DeformablePart* part = model_.deformable(index);
      if (part == nullptr) continue;
      const std::string noun = fmt::format("node of '{}'", model_.part(index).name);
      const auto [positions, velocities] = motion(*part);
      if (auto found = solver::check_motion(positions, velocities, {}, limits_.max_speed, noun)) {
        found->group = index;
        return found;
      }
      const SolidBody* solid = part->solid();
      if (solid == nullptr || solid->material().erodes()) continue;
      if (auto found = inverted(*solid, model_.part(index).name)) {
        found->group = index;
        return found;
      }
    }
    return std::nullopt;
  }
  void write_instability(const solver::Instability& instability, const std::filesystem::path& file) const override {
    const auto [positions, velocities] = motion(*model_.deformable(instability.group));
    // Neighbours: the nodes within a few elements (an element's size from the part's own extent is not at hand:
    // the nodes within 1/10 of the part's bounding box).
    Aabb box;
    for (const Vec3& x : positions) box.extend(x);
    const double diagonal = (box.max - box.min).norm();
    const double reach = std::isfinite(diagonal) ? 0.1 * diagonal : 0.0;
    solver::write_instability(file, positions, velocities, instability, reach);
  }

 private:
  static std::pair<std::span<const Vec3>, std::span<const Vec3>> motion(const DeformablePart& part) {
    if (part.solid() != nullptr) return {part.solid()->positions(), part.solid()->velocities()};
    return {part.shell()->positions(), part.shell()->velocities()};
  }

  static std::optional<solver::Instability> inverted(const SolidBody& solid, const std::string& name) {
    const std::vector<std::size_t> elements = solid.inverted_elements();
    if (elements.empty()) return std::nullopt;
    solver::Instability found;
    found.what = "inverted";
    std::string list;
    for (std::size_t k = 0; k < elements.size() && k < solver::Instability::kMaxReported; ++k) {
      for (const std::uint32_t node : solid.mesh().element[elements[k]]) found.indices.push_back(node);
      list += fmt::format("{}{}", k > 0 ? ", " : "", elements[k]);
    }
    found.detail = fmt::format(
        "{} hexahedr{} of '{}' turned inside out (its material does not erode, so they cannot "
        "fail): element{} {}{}",
        elements.size(), elements.size() > 1 ? "a" : "on", name, elements.size() > 1 ? "s" : "", list,
        elements.size() > solver::Instability::kMaxReported
            ? fmt::format(" and {} more", elements.size() - solver::Instability::kMaxReported)
            : std::string());
    return found;
  }

  FemModel model_;
  std::filesystem::path out_dir_;
  solver::StabilityLimits limits_;
};

}  // namespace
}  // namespace sabo::fem

int main(int argc, char** argv) {
  return sabo::solver::solver_main(argc, argv, sabo::Role::fem,
                                   [](const sabo::scene::Scene& scene, const sabo::solver::SolverOptions& options) {
                                     return std::make_unique<sabo::fem::FemSolver>(scene, options);
                                   });
}
