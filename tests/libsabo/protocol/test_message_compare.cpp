// The replay comparison: what matches, the first divergence (step, field, entity, component), tolerances per field,
// structural differences and the per-field summary.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "libsabo/protocol/message_compare.hpp"

using sabo::protocol::MessageComparison;
using sabo::protocol::Tolerance;

namespace {

sabo::v1::Register registration_with_particles() {
  sabo::v1::Register r;
  for (std::uint64_t id : {10u, 11u, 12u}) r.mutable_particles()->add_id(id);
  return r;
}

sabo::v1::StepState state(std::uint64_t step, double vx_of_particle_11) {
  sabo::v1::StepState s;
  s.set_step(step);
  s.set_time(1e-3 * static_cast<double>(step));
  s.set_stable_dt(1e-3);
  for (std::uint32_t i : {0u, 1u, 2u}) {
    s.add_index(i);
    for (int c = 0; c < 3; ++c) s.add_position(static_cast<double>(i) + 0.1 * c);
    s.add_velocity(i == 1 ? vx_of_particle_11 : 0.0);
    s.add_velocity(0.0);
    s.add_velocity(-1.0);
  }
  s.mutable_energies()->set_kinetic(2.0);
  return s;
}

}  // namespace

TEST(MessageComparison, IdenticalMessagesMatchOverEveryStep) {
  const auto r = registration_with_particles();
  MessageComparison comparison;
  for (std::uint64_t step = 0; step < 4; ++step) comparison.compare_states(r, state(step, 0.5), state(step, 0.5));
  EXPECT_TRUE(comparison.matches());
  EXPECT_EQ(comparison.steps_compared(), 4u);
  EXPECT_EQ(comparison.fields().at("velocity").compared, 4u * 9u);
  EXPECT_NE(comparison.report().find("every field matches over 4 steps"), std::string::npos) << comparison.report();
}

TEST(MessageComparison, NamesTheFirstDivergentStepFieldParticleAndComponent) {
  const auto r = registration_with_particles();
  MessageComparison comparison;
  comparison.compare_states(r, state(0, 0.5), state(0, 0.5));
  comparison.compare_states(r, state(1, 0.5), state(1, 0.5 + 1e-9));
  comparison.compare_states(r, state(2, 0.5), state(2, 0.6));
  ASSERT_FALSE(comparison.matches());
  const auto& d = *comparison.first();
  EXPECT_EQ(d.step, 1u);
  EXPECT_EQ(d.field, "velocity");
  EXPECT_EQ(d.entity, "particle 11");
  EXPECT_EQ(d.component, 0);
  EXPECT_DOUBLE_EQ(d.recorded, 0.5);
  EXPECT_NEAR(d.absolute, 1e-9, 1e-15);
  const auto& summary = comparison.fields().at("velocity");
  EXPECT_EQ(summary.first_step.value(), 1u);
  EXPECT_EQ(summary.steps, 2u);
  EXPECT_EQ(summary.entities, 2u);
  EXPECT_NEAR(summary.max_absolute, 0.1, 1e-12);
  EXPECT_FALSE(comparison.fields().at("position").first_step.has_value());
  const auto json = comparison.json();
  EXPECT_EQ(json["first_divergence"]["component"], "x");
  EXPECT_EQ(json["first_divergence"]["entity"], "particle 11");
}

TEST(MessageComparison, ToleranceOfAFieldAbsorbsSmallDifferences) {
  const auto r = registration_with_particles();
  MessageComparison comparison({{"velocity", Tolerance{1e-6, 0}}});
  comparison.compare_states(r, state(0, 0.5), state(0, 0.5 * (1 + 1e-7)));
  EXPECT_TRUE(comparison.matches()) << comparison.report();
  comparison.compare_states(r, state(1, 0.5), state(1, 0.5 * (1 + 1e-5)));
  EXPECT_FALSE(comparison.matches());
  EXPECT_EQ(comparison.first()->step, 1u);
}

TEST(MessageComparison, NanAgainstNanMatchesAndNanAgainstANumberDoesNot) {
  const auto r = registration_with_particles();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  MessageComparison comparison;
  comparison.compare_states(r, state(0, nan), state(0, nan));
  EXPECT_TRUE(comparison.matches());
  comparison.compare_states(r, state(1, nan), state(1, 0.0));
  ASSERT_FALSE(comparison.matches());
  EXPECT_EQ(comparison.first()->field, "velocity");
}

TEST(MessageComparison, DifferentParticleListsAreAStructuralDivergence) {
  const auto r = registration_with_particles();
  auto shorter = state(0, 0.5);
  shorter.mutable_index()->RemoveLast();
  MessageComparison comparison;
  comparison.compare_states(r, state(0, 0.5), shorter);
  ASSERT_FALSE(comparison.matches());
  EXPECT_EQ(comparison.first()->field, "index");
  EXPECT_NE(comparison.first()->note.find("3 particles recorded, 2 replayed"), std::string::npos)
      << comparison.first()->note;
}

TEST(MessageComparison, ForcesCompareNodeForcesByNodeId) {
  sabo::v1::Register r;
  for (std::uint64_t id : {7u, 9u}) r.mutable_surface()->add_node_id(id);
  sabo::v1::StepForces recorded;
  recorded.set_step(3);
  recorded.set_dt(1e-4);
  for (double f : {0.0, 0.0, 1.0, 0.0, 0.0, 2.0}) recorded.add_node_force(f);
  auto replayed = recorded;
  replayed.set_node_force(5, 2.5);
  MessageComparison comparison;
  comparison.compare_forces(r, recorded, replayed);
  ASSERT_FALSE(comparison.matches());
  EXPECT_EQ(comparison.first()->field, "node_force");
  EXPECT_EQ(comparison.first()->entity, "node 9");
  EXPECT_EQ(comparison.first()->component, 2);
}
