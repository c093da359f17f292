#include "coupler/contact/surface_penalty_pair.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "libsabo/contact/surface_contact_history.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/protocol/surface_codec.hpp"

namespace sabo::coupler {

namespace {

std::unique_ptr<contact::SurfaceContact> make_contact(const scene::Scene& scene, Role particles) {
  if (particles == Role::dem) return std::make_unique<contact::SurfaceContact>(scene);
  std::vector<std::string> fluids;
  for (const auto& fluid : scene.fluids) fluids.push_back(fluid.name);
  // Keep only what the pair lookup needs, so that the scene need not outlive the pair.
  scene::Scene pairs_only;
  pairs_only.fluids = scene.fluids;
  pairs_only.interactions = scene.interactions;
  pairs_only.sph_fem_default = scene.sph_fem_default;
  auto settings = [pairs_only = std::move(pairs_only)](const std::string& fluid, const std::string& part) {
    return pairs_only.surface_contact(fluid, part);
  };
  return std::make_unique<contact::SurfaceContact>(std::move(fluids), std::move(settings));
}

std::span<const double> span_of(const google::protobuf::RepeatedField<double>& field) {
  return {field.data(), static_cast<std::size_t>(field.size())};
}

}  // namespace

SurfacePenaltyPair::SurfacePenaltyPair(const scene::Scene& scene, Role particles)
    : particles_(particles),
      source_(particles == Role::dem ? "particles" : "fluid"),
      contact_(make_contact(scene, particles)) {}

std::string SurfacePenaltyPair::name() const {
  return particles_ == Role::dem ? "dem_fem" : "sph_fem";
}

void SurfacePenaltyPair::start(const Solvers& solvers, Replies& /*replies*/) {
  beta_ = solvers.at(particles_).beta;
  contact_->set_surface(protocol::surface_from_message(solvers.at(Role::fem).registration->surface(), "fem_solver"));
}

void SurfacePenaltyPair::compute(const Solvers& solvers, const StepClock& clock) {
  const sabo::v1::StepState& surface = *solvers.at(Role::fem).state;
  if (surface.has_topology()) {
    // Faces that left (eroded elements) leave the contact; exposed faces join.
    // Tangential springs carry over where their nodes remain (keyed by node ids).
    contact_->set_surface(protocol::surface_from_message(surface.topology(), "fem_solver"));
  }
  if (surface.node_position_size() > 0) {
    contact_->update_nodes(span_of(surface.node_position()), span_of(surface.node_velocity()));
  }
  const SolverView& particles = solvers.at(particles_);
  gather_.gather(particles.registration->particles(), *particles.state);
  contact_->compute(gather_.view(), clock.dt_previous, out_);
  warn_deep_overlap(clock.time);
}

void SurfacePenaltyPair::scatter(const Solvers& solvers, double /*dt*/, Replies& replies) {
  const bool torque = solvers.at(particles_).registration->exposes_angular_velocity();
  replies.add_particle_forces(particles_, out_.particle_force,
                              torque ? std::span<const double>(out_.particle_torque) : std::span<const double>());
  if (out_.contact_count > 0) replies.add_node_forces(out_.node_force);
}

void SurfacePenaltyPair::point_loads(std::vector<PointLoad>& out) const {
  const auto& face_part = contact_->surface().face_part;
  for (const contact::ContactRecord& record : contact_->contacts()) {
    out.push_back(PointLoad{face_part[record.face], record.point, -record.force});
  }
}

InterestRequest SurfacePenaltyPair::interest(Role role) const {
  if (role == Role::fem) return {.all = true, .boxes = {}};
  return {.all = false, .boxes = contact_->interest_regions()};
}

NewtonBalance SurfacePenaltyPair::newton_balance() const {
  NewtonBalance balance;
  const auto& pf = out_.particle_force;
  for (std::size_t i = 0; i + 2 < pf.size(); i += 3) {
    balance.sum += Vec3(pf[i], pf[i + 1], pf[i + 2]);
    balance.scale += std::abs(pf[i]) + std::abs(pf[i + 1]) + std::abs(pf[i + 2]);
  }
  if (out_.contact_count == 0) return balance;
  const auto& nf = out_.node_force;
  for (std::size_t i = 0; i + 2 < nf.size(); i += 3) balance.sum += Vec3(nf[i], nf[i + 1], nf[i + 2]);
  return balance;
}

nlohmann::json SurfacePenaltyPair::effect() const {
  return {{"effect", particles_ == Role::dem ? "dem_fem_contact" : "sph_fem_penalty_contact"}, {"process", "coupler"}};
}

void SurfacePenaltyPair::warn_deep_overlap(double time) {
  constexpr double kDeepOverlapRatio = 0.5;
  if (warned_deep_overlap_ || !(out_.deepest_overlap_ratio > kDeepOverlapRatio)) return;
  warned_deep_overlap_ = true;
  spdlog::warn(
      "t = {:.6g} s, contact of the {} with the structures: a particle overlaps a face by {:.3g} m, {:.2f} times the "
      "face's edge ({:.3g} m; "
      "warned once per run above {}). The penalty spring (paper eq. 6, k = k1 K A^2 / V, softer on finer meshes) "
      "is too soft for this mesh: the particle sinks through the element scale and contact forces and energies "
      "become unreliable. Fix: raise penalty_scale (k1) or set model = \"hertz_mindlin\" in [contact.dem_fem] "
      "([contact.sph_fem] for fluids; or the pair's [[interactions]]), or coarsen the structure's element_size",
      time, source_, out_.deepest_overlap, out_.deepest_overlap_ratio, out_.deepest_face_edge, kDeepOverlapRatio);
}

void SurfacePenaltyPair::save_history(io::hdf5::Group& group) const {
  group.set_attribute("pair", name());
  contact::write_history(group, contact_->history());
}

void SurfacePenaltyPair::restore_history(const io::hdf5::Group& group) {
  if (group.string_attribute("pair") != name()) {
    throw FileError(fmt::format("{}: holds the history of the {} pair, not of {}", group.path(),
                                group.string_attribute("pair"), name()));
  }
  contact::SurfaceContact::History history = contact::read_history(group);
  try {
    contact_->restore(std::move(history));
  } catch (const ProtocolError& error) {
    throw FileError(fmt::format("{}: {}", group.path(), error.what()));
  }
}

}  // namespace sabo::coupler
