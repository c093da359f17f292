// Every message travels through a real ROUTER/DEALER pair and comes back equal.
#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>

#include "libsabo/protocol/socket.hpp"
#include "libsabo/protocol/surface_codec.hpp"

using namespace sabo;
using namespace std::chrono_literals;

namespace {

struct Pair {
  zmq::context_t context{1};
  protocol::Socket router{context, zmq::socket_type::router};
  protocol::Socket dealer{context, zmq::socket_type::dealer};
  Pair() {
    router.bind("inproc://round-trip");
    dealer.connect("inproc://round-trip");
  }
};

template <class Message>
void expect_round_trip(const Message& original) {
  Pair pair;
  protocol::SendBuffer buffer;
  pair.dealer.send(original, buffer);
  protocol::Inbound at_router;
  ASSERT_TRUE(pair.router.receive(at_router, 2000ms));
  ASSERT_TRUE(at_router.valid()) << at_router.problem;
  EXPECT_EQ(at_router.header.type, protocol::message_type_of<Message>());
  Message received;
  at_router.parse(received);
  EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(original, received)) << original.GetTypeName();

  // And back, through the ROUTER's zero-copy path to the peer that sent it.
  pair.router.send(received, buffer, at_router.peer);
  protocol::Inbound at_dealer;
  ASSERT_TRUE(pair.dealer.receive(at_dealer, 2000ms));
  Message returned;
  at_dealer.parse(returned);
  EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(original, returned)) << original.GetTypeName();
}

sabo::v1::ParticleTable table(int n) {
  sabo::v1::ParticleTable t;
  for (int i = 0; i < n; ++i) {
    t.add_id(1000u + static_cast<std::uint64_t>(i));
    t.add_radius(0.5 + 0.001 * i);
    t.add_mass(1500.0 + i);
    t.add_material(static_cast<std::uint32_t>(i % 3));
    t.add_body(static_cast<std::uint32_t>(i % 2));
  }
  return t;
}

}  // namespace

TEST(RoundTrip, Register) {
  sabo::v1::Register m;
  m.set_protocol_version(protocol::kProtocolVersion);
  m.set_role(sabo::v1::ROLE_DEM);
  m.set_name("dem_solver test");
  m.set_exposes_particles(true);
  m.set_exposes_angular_velocity(true);
  *m.mutable_particles() = table(17);
  m.set_stable_dt(1.5e-4);
  m.set_pid(4242);
  expect_round_trip(m);
}

TEST(RoundTrip, RegisterWithSurface) {
  geometry::SurfaceMesh mesh;
  mesh.node_id = {1, 2, 3, 4};
  mesh.node_position = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0.5)};
  mesh.triangle = {{0, 1, 2}, {1, 3, 2}};
  mesh.face_part = {0, 0};
  mesh.face_material = {1, 1};
  mesh.face_thickness = {0.0, 0.24};
  mesh.face_bulk_modulus = {1e10, 1e10};
  mesh.face_element_volume = {0.0, 0.0};
  mesh.part_name = {"chute"};
  sabo::v1::Register m;
  m.set_role(sabo::v1::ROLE_FEM);
  m.set_exposes_surface(true);
  protocol::surface_to_message(mesh, 3, *m.mutable_surface());
  expect_round_trip(m);
  const auto back = protocol::surface_from_message(m.surface(), "test");
  EXPECT_EQ(back.node_position[3], mesh.node_position[3]);
  EXPECT_EQ(back.triangle[1], mesh.triangle[1]);
  EXPECT_EQ(back.face_thickness[1], 0.24);
}

TEST(RoundTrip, RegisterReply) {
  sabo::v1::RegisterReply m;
  m.set_accepted(false);
  m.set_error("role taken");
  m.set_protocol_version(1);
  m.set_end_time(20.0);
  auto* box = m.add_interest();
  box->set_min_x(-1), box->set_max_z(3.5);
  expect_round_trip(m);
}

TEST(RoundTrip, LargeStepStateUsesZeroCopyPath) {
  sabo::v1::StepState m;
  m.set_step(12);
  m.set_time(0.25);
  m.set_stable_dt(1e-3);
  const int n = 20000;  // ~1.5 MB: above the copy threshold
  for (int i = 0; i < n; ++i) {
    m.add_index(static_cast<std::uint32_t>(i));
    for (int c = 0; c < 3; ++c) {
      m.add_position(i * 0.1 + c);
      m.add_velocity(-i * 0.01 + c);
      m.add_angular_velocity(c * 1e-3 * i);
    }
  }
  m.add_node_position(1.0), m.add_node_position(2.0), m.add_node_position(3.0);
  m.add_node_velocity(0), m.add_node_velocity(0), m.add_node_velocity(0);
  *m.mutable_particle_table() = table(3);
  m.mutable_energies()->set_kinetic(12.5);
  m.mutable_energies()->set_dissipated(1.25);
  m.set_compute_seconds(0.01);
  m.set_wait_seconds(0.02);
  expect_round_trip(m);
}

TEST(RoundTrip, StepForces) {
  sabo::v1::StepForces m;
  m.set_step(12);
  m.set_dt(2e-4);
  for (int i = 0; i < 50; ++i) {
    m.add_index(static_cast<std::uint32_t>(i));
    for (int c = 0; c < 3; ++c) {
      m.add_force(1.0 * i + c);
      m.add_torque(-0.5 * i);
      m.add_node_force(0.25 * i);
    }
  }
  m.set_interest_all(false);
  m.add_interest()->set_max_x(7.0);
  m.set_checkpoint(true);
  m.set_output(true);
  m.set_stop(true);
  expect_round_trip(m);
}

TEST(RoundTrip, StepForcesWithBoundaryParticles) {
  // SPH walls sampled as boundary particles (docs/protocol.md, "SPH walls").
  sabo::v1::StepForces m;
  m.set_step(3);
  m.set_dt(1e-4);
  const int n = 30000;  // ~2.9 MB: the zero-copy path as well
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      m.add_boundary_position(0.01 * i + c);
      m.add_boundary_velocity(-1e-3 * i);
      m.add_boundary_normal(c == 2 ? 1.0 : 0.0);
      m.add_boundary_acceleration(c == 2 ? -0.5 : 0.0);
    }
    m.add_boundary_volume(1e-6 * (1 + i % 5));
  }
  expect_round_trip(m);
  EXPECT_EQ(m.boundary_position_size(), 3 * n);
  EXPECT_EQ(m.boundary_volume_size(), n);
}

TEST(RoundTrip, StepStateWithBoundaryForce) {
  sabo::v1::StepState m;
  m.set_step(4);
  m.set_stable_dt(1e-4);
  for (int i = 0; i < 1000; ++i) {
    for (int c = 0; c < 3; ++c) m.add_boundary_force(c == 2 ? -9.81 * i : 1e-3 * i);
  }
  expect_round_trip(m);
}

TEST(RoundTrip, ErrorStopGoodbye) {
  sabo::v1::Error error;
  error.set_code(sabo::v1::Error::CODE_INVALID);
  error.set_message("bad arrays");
  error.set_fatal(true);
  expect_round_trip(error);
  sabo::v1::Stop stop;
  stop.set_reason("user pressed Ctrl-C");
  expect_round_trip(stop);
  sabo::v1::Goodbye goodbye;
  goodbye.set_compute_seconds(1.5);
  goodbye.set_wait_seconds(0.5);
  goodbye.set_steps(1000);
  goodbye.set_reason("completed");
  expect_round_trip(goodbye);
}

TEST(RoundTrip, SendBufferIsReusedAcrossSteps) {
  Pair pair;
  protocol::SendBuffer buffer;
  sabo::v1::StepState m;
  for (int i = 0; i < 30000; ++i) m.add_position(i);
  for (int step = 0; step < 5; ++step) {
    m.set_step(static_cast<std::uint64_t>(step));
    m.set_position(0, step);
    pair.dealer.send(m, buffer);
    protocol::Inbound in;
    ASSERT_TRUE(pair.router.receive(in, 2000ms));
    sabo::v1::StepState got;
    in.parse(got);
    EXPECT_EQ(got.step(), static_cast<std::uint64_t>(step));
    EXPECT_EQ(got.position(0), step);
    EXPECT_EQ(got.position(29999), 29999);
  }
}

TEST(RoundTrip, MalformedFramesAreReportedNotThrown) {
  Pair pair;
  zmq::socket_t raw(pair.context, zmq::socket_type::dealer);
  raw.connect("inproc://round-trip");
  raw.send(zmq::str_buffer("garbage"), zmq::send_flags::none);
  protocol::Inbound in;
  ASSERT_TRUE(pair.router.receive(in, 2000ms));
  EXPECT_FALSE(in.valid());
  EXPECT_NE(in.problem.find("2 frames"), std::string::npos) << in.problem;

  raw.send(zmq::str_buffer("SABO\x01\x00\x03\x00"), zmq::send_flags::sndmore);
  raw.send(zmq::str_buffer("\xff\xff\xff not protobuf"), zmq::send_flags::none);
  ASSERT_TRUE(pair.router.receive(in, 2000ms));
  ASSERT_TRUE(in.valid()) << in.problem;
  sabo::v1::StepState state;
  EXPECT_THROW(in.parse(state), ProtocolError);
}
