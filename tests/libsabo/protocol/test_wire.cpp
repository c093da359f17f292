#include <gtest/gtest.h>

#include <array>

#include "libsabo/protocol/wire.hpp"

using namespace sabo::protocol;

TEST(Wire, HeaderRoundTrip) {
  for (int type = 1; type <= 7; ++type) {
    std::array<std::uint8_t, kHeaderSize> bytes{};
    encode_header({kProtocolVersion, static_cast<MessageType>(type)}, bytes);
    std::string problem;
    auto header = decode_header(bytes, problem);
    ASSERT_TRUE(header) << problem;
    EXPECT_EQ(header->version, kProtocolVersion);
    EXPECT_EQ(header->type, type);
  }
}

TEST(Wire, HeaderRejectsGarbage) {
  std::string problem;
  const std::array<std::uint8_t, 8> wrong_magic = {'H', 'T', 'T', 'P', 1, 0, 3, 0};
  EXPECT_FALSE(decode_header(wrong_magic, problem));
  EXPECT_NE(problem.find("magic"), std::string::npos) << problem;

  const std::array<std::uint8_t, 3> short_frame = {'S', 'A', 'B'};
  EXPECT_FALSE(decode_header(short_frame, problem));
  EXPECT_NE(problem.find("3 bytes"), std::string::npos) << problem;

  const std::array<std::uint8_t, 8> unknown_type = {'S', 'A', 'B', 'O', 1, 0, 99, 0};
  EXPECT_FALSE(decode_header(unknown_type, problem));
  EXPECT_NE(problem.find("unknown message type 99"), std::string::npos) << problem;
}

TEST(Wire, RoleNames) {
  for (const sabo::Role role : sabo::kRoles) {
    EXPECT_EQ(from_wire(to_wire(role)), role) << sabo::role_name(role);
    EXPECT_EQ(role_name(to_wire(role)), sabo::role_name(role));
    EXPECT_EQ(sabo::role_from_name(sabo::role_name(role)), role);
  }
  EXPECT_EQ(to_wire(sabo::Role::dem), sabo::v1::ROLE_DEM);
  EXPECT_EQ(role_name(sabo::v1::ROLE_FEM), "fem_solver");
  EXPECT_EQ(from_wire(sabo::v1::ROLE_UNSPECIFIED), std::nullopt);
  EXPECT_EQ(from_wire(static_cast<sabo::v1::Role>(9)), std::nullopt);
  EXPECT_EQ(role_name(static_cast<sabo::v1::Role>(9)), "role 9");
  EXPECT_EQ(sabo::role_from_name("nonsense"), std::nullopt);
}
