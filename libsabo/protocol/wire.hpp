#pragma once
// Wire format of the Sabo protocol (docs/protocol.md): every ZeroMQ message
// has two frames, an 8-byte header ("SABO", uint16 version, uint16 type, both
// little endian) and the serialized protobuf message of that type.
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include "libsabo/core/role.hpp"
#include "sabo/v1/sabo.pb.h"

namespace sabo::protocol {

inline constexpr std::uint16_t kProtocolVersion = 1;
inline constexpr std::size_t kHeaderSize = 8;

using MessageType = sabo::v1::MessageType;

struct Header {
  std::uint16_t version = kProtocolVersion;
  MessageType type = sabo::v1::MESSAGE_TYPE_UNSPECIFIED;
};

void encode_header(const Header& header, std::span<std::uint8_t, kHeaderSize> out);
// Returns nullopt and sets `problem` when the bytes are not a Sabo header.
std::optional<Header> decode_header(std::span<const std::uint8_t> bytes, std::string& problem);

[[nodiscard]] const char* message_type_name(MessageType type);

// The message type of each protobuf message class.
template <class Message>
constexpr MessageType message_type_of();
template <>
constexpr MessageType message_type_of<sabo::v1::Register>() {
  return sabo::v1::MESSAGE_TYPE_REGISTER;
}
template <>
constexpr MessageType message_type_of<sabo::v1::RegisterReply>() {
  return sabo::v1::MESSAGE_TYPE_REGISTER_REPLY;
}
template <>
constexpr MessageType message_type_of<sabo::v1::StepState>() {
  return sabo::v1::MESSAGE_TYPE_STEP_STATE;
}
template <>
constexpr MessageType message_type_of<sabo::v1::StepForces>() {
  return sabo::v1::MESSAGE_TYPE_STEP_FORCES;
}
template <>
constexpr MessageType message_type_of<sabo::v1::Error>() {
  return sabo::v1::MESSAGE_TYPE_ERROR;
}
template <>
constexpr MessageType message_type_of<sabo::v1::Stop>() {
  return sabo::v1::MESSAGE_TYPE_STOP;
}
template <>
constexpr MessageType message_type_of<sabo::v1::Goodbye>() {
  return sabo::v1::MESSAGE_TYPE_GOODBYE;
}

// The wire's role enum against sabo::Role: the only place that knows both.
[[nodiscard]] sabo::v1::Role to_wire(Role role);                   // Role::dem -> ROLE_DEM
[[nodiscard]] std::optional<Role> from_wire(sabo::v1::Role role);  // nullopt: ROLE_UNSPECIFIED or an unknown value
[[nodiscard]] std::string role_name(sabo::v1::Role role);          // ROLE_DEM -> "dem_solver"; 9 -> "role 9"

}  // namespace sabo::protocol
