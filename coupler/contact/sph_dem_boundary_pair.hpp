#pragma once
// The SPH-DEM pair with model = "boundary_particles": every boulder of a
// particle set that meets the fluid so is sampled as SPH wall particles
// (geometry::sample_sphere, the layers of the structure walls) that move with
// it, x + r, v + w x r, a + alpha x r + w x (w x r). They travel to the
// sph_solver with the structure walls (BoundaryChannel), only those within
// the kernel support of a fluid particle; the forces the fluid put on them
// come back in a later StepState and are summed per boulder into a force and
// a torque (r x f about its centre at the time they were sent).
//
// Placed ahead of the fluid's state: the particles of step n are those within
// support + margin (margin = support / 4) of the fluid of the exchange before,
// which the pair keeps (and its checkpoint holds), so that they can go as soon
// as the dem_solver's state n is in, while the sph_solver still integrates.
// A fluid particle moves far less than the margin in one step (its CFL
// condition keeps it to a few percent of the support), so every particle within
// the support of the fluid at x_n is among them; compute() checks that on the
// fluid's state n and stops the run naming the particle otherwise. The extra
// particles lie beyond the support of every fluid particle and exert nothing.
// Only the first exchange (no fluid kept yet) places from the fluid at x_n.
//
// Impulse, not force: the fluid felt those forces over its step m (the step
// whose StepForces carried the particles, or with lagged boundary particles
// the step after it, which took them moved ahead), dt_avg,m = (dt_{m-1} +
// dt_m) / 2, and the boulder integrates them at step n > m over dt_avg,n. The boulder
// gets F dt_avg,m / dt_avg,n, so that the momentum it gains is exactly the
// momentum the fluid lost, whatever the steps did in between.
#include <map>

#include "coupler/contact/contact_pair.hpp"
#include "libsabo/geometry/sphere_sampling.hpp"
#include "libsabo/physics/cell_list.hpp"

namespace sabo::coupler {

class SphDemBoundaryPair final : public ContactPair {
 public:
  explicit SphDemBoundaryPair(const scene::Scene& scene);

  [[nodiscard]] std::string name() const override { return "sph_dem"; }
  [[nodiscard]] std::array<Role, 2> roles() const override { return {Role::sph, Role::dem}; }
  void start(const Solvers& solvers, Replies& replies) override;
  void compute(const Solvers& solvers, const StepClock& clock) override;
  [[nodiscard]] bool can_place_ahead() const override { return kept_; }
  void place_ahead(const Solvers& solvers, const StepClock& clock) override;
  void scatter(const Solvers& solvers, double dt, Replies& replies) override;
  [[nodiscard]] InterestRequest interest(Role role) const override;
  [[nodiscard]] bool every_exchange() const override { return true; }
  [[nodiscard]] const physics::BoundaryParticles* boundary_particles() const override { return &selected_; }
  [[nodiscard]] NewtonBalance newton_balance() const override { return balance_; }
  [[nodiscard]] std::size_t contact_count() const override { return boulders_touched_; }
  [[nodiscard]] nlohmann::json effect() const override;
  void save_history(io::hdf5::Group& group) const override;
  void restore_history(const io::hdf5::Group& group) override;

  [[nodiscard]] const physics::BoundaryParticles& selected() const { return selected_; }

 private:
  // The particles of one StepForces: whose boulder (DEM table index) each is, its lever arm (m),
  // and the fluid's step over which it acts.
  struct Sent {
    std::vector<std::uint32_t> owner;
    std::vector<Vec3> lever;
    double dt_avg = 0;  // s
  };

  double spacing_, support_;
  std::size_t layers_;
  std::vector<std::pair<int, std::array<double, 2>>> periodic_;    // the fluid's periodic axes and spans, m
  std::vector<std::uint8_t> boundary_set_;                         // per particle set: meets the fluid so
  std::map<double, geometry::SphereSampling> sampling_by_radius_;  // radius (m) -> its sampling
  std::vector<const geometry::SphereSampling*> sampling_;          // per DEM table index; null: not sampled
  double max_radius_ = 0;                                          // m, of the sampled boulders
  std::size_t slot_ = 0;
  const BoundaryChannel* channel_ = nullptr;

  // This step.
  std::vector<Vec3> force_, torque_;                // per DEM table index: the fluid's, N and N m
  double force_dt_avg_ = 0;                         // s, the fluid step they act over
  std::vector<std::uint32_t> touched_;              // DEM table indices with a force, ascending
  std::vector<double> reply_force_, reply_torque_;  // per particle of the DEM state
  physics::BoundaryParticles selected_;
  Sent pending_;                    // the record of selected_
  std::array<Sent, 2> sent_;        // [0]: the last StepForces, [1]: the one before
  std::vector<Vec3> centre_cover_;  // centres of the sampled boulders this step
  NewtonBalance balance_;
  std::size_t boulders_touched_ = 0;
  std::size_t max_sent_ = 0;
  double dt_previous_ = 0;

  // Per DEM table index: the last state's velocities, for the accelerations.
  std::vector<Vec3> last_velocity_, last_spin_;
  std::vector<std::uint8_t> has_last_;

  // Scratch.
  std::vector<Vec3> candidate_position_;
  std::vector<std::uint32_t> candidate_owner_, candidate_point_;
  std::vector<char> near_;
  std::vector<Vec3> fluid_position_;
  physics::CellList fluid_grid_;  // of the fluid the particles are placed from, cell = support

  // The particles of step n from the boulders at x_n, those within support + margin of `fluid` (positions, m).
  void place(const Solvers& solvers, const StepClock& clock, std::span<const Vec3> fluid, double margin);
  // Throws ProtocolError when a particle of the fluid's state n lies within the support of a boulder particle
  // that the placement from the kept fluid may have left out.
  void check_fluid_moved_within_margin(const sabo::v1::StepState& fluid, std::uint64_t step);
  [[nodiscard]] Vec3 minimum_image(Vec3 d) const;  // across the fluid's periodic axes

  double margin_;                              // m: support / 4
  double max_reach_ = 0;                       // m: the farthest particle of a sampled boulder from its centre
  bool placed_ = false;                        // this exchange's particles are placed
  bool kept_ = false;                          // kept_index_ and kept_position_ hold a fluid (possibly empty)
  std::vector<std::uint32_t> kept_index_;      // the fluid of the exchange before: its particle ids
  std::vector<Vec3> kept_position_;            // m
  std::vector<std::int64_t> kept_slot_of_id_;  // per fluid particle: its slot in kept_ during the check, else -1
};

}  // namespace sabo::coupler
