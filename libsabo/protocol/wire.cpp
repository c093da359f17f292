#include "libsabo/protocol/wire.hpp"

#include <fmt/format.h>

#include <cstring>

namespace sabo::protocol {

namespace {
constexpr char kMagic[4] = {'S', 'A', 'B', 'O'};

void put_u16(std::uint8_t* out, std::uint16_t value) {
  out[0] = static_cast<std::uint8_t>(value & 0xffu);
  out[1] = static_cast<std::uint8_t>(value >> 8);
}
std::uint16_t get_u16(const std::uint8_t* in) {
  return static_cast<std::uint16_t>(in[0] | (in[1] << 8));
}
}  // namespace

void encode_header(const Header& header, std::span<std::uint8_t, kHeaderSize> out) {
  std::memcpy(out.data(), kMagic, 4);
  put_u16(out.data() + 4, header.version);
  put_u16(out.data() + 6, static_cast<std::uint16_t>(header.type));
}

std::optional<Header> decode_header(std::span<const std::uint8_t> bytes, std::string& problem) {
  if (bytes.size() != kHeaderSize) {
    problem = fmt::format("header frame has {} bytes, expected {}", bytes.size(), kHeaderSize);
    return std::nullopt;
  }
  if (std::memcmp(bytes.data(), kMagic, 4) != 0) {
    problem = "header frame does not start with the magic \"SABO\"";
    return std::nullopt;
  }
  Header header;
  header.version = get_u16(bytes.data() + 4);
  const std::uint16_t type = get_u16(bytes.data() + 6);
  if (!sabo::v1::MessageType_IsValid(type) || type == sabo::v1::MESSAGE_TYPE_UNSPECIFIED) {
    problem = fmt::format("unknown message type {}", type);
    return std::nullopt;
  }
  header.type = static_cast<MessageType>(type);
  return header;
}

const char* message_type_name(MessageType type) {
  switch (type) {
    case sabo::v1::MESSAGE_TYPE_REGISTER: return "Register";
    case sabo::v1::MESSAGE_TYPE_REGISTER_REPLY: return "RegisterReply";
    case sabo::v1::MESSAGE_TYPE_STEP_STATE: return "StepState";
    case sabo::v1::MESSAGE_TYPE_STEP_FORCES: return "StepForces";
    case sabo::v1::MESSAGE_TYPE_ERROR: return "Error";
    case sabo::v1::MESSAGE_TYPE_STOP: return "Stop";
    case sabo::v1::MESSAGE_TYPE_GOODBYE: return "Goodbye";
    default: return "Unknown";
  }
}

sabo::v1::Role to_wire(Role role) {
  switch (role) {
    case Role::sph: return sabo::v1::ROLE_SPH;
    case Role::dem: return sabo::v1::ROLE_DEM;
    case Role::fem: return sabo::v1::ROLE_FEM;
  }
  return sabo::v1::ROLE_UNSPECIFIED;
}

std::optional<Role> from_wire(sabo::v1::Role role) {
  switch (role) {
    case sabo::v1::ROLE_SPH: return Role::sph;
    case sabo::v1::ROLE_DEM: return Role::dem;
    case sabo::v1::ROLE_FEM: return Role::fem;
    default: return std::nullopt;
  }
}

std::string role_name(sabo::v1::Role role) {
  const auto known = from_wire(role);
  return known ? sabo::role_name(*known) : fmt::format("role {}", static_cast<int>(role));
}

}  // namespace sabo::protocol
