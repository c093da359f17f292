#pragma once
// The three solver roles: one enum for the scene, the coupler and the solvers. The wire has its own
// enum (sabo::v1::Role, proto/sabo/v1/sabo.proto); protocol/wire.hpp converts between the two, and
// outside libsabo/protocol only a test that sends a value the wire does not know names the wire's.
#include <array>
#include <optional>
#include <string_view>

namespace sabo {

enum class Role { sph, dem, fem };

inline constexpr std::array<Role, 3> kRoles = {Role::sph, Role::dem, Role::fem};

// The process of a role, as the scene's [solvers.*] sections, traffic.h5's groups, the checkpoints
// and the logs name it: "sph_solver", "dem_solver", "fem_solver".
[[nodiscard]] constexpr const char* role_name(Role role) {
  switch (role) {
    case Role::sph: return "sph_solver";
    case Role::dem: return "dem_solver";
    case Role::fem: return "fem_solver";
  }
  return "unknown";
}

// The role's key in the scene ([solvers.sph]) and on the command lines of ./sabo replay: "sph", "dem", "fem".
[[nodiscard]] constexpr const char* role_key(Role role) {
  switch (role) {
    case Role::sph: return "sph";
    case Role::dem: return "dem";
    case Role::fem: return "fem";
  }
  return "unknown";
}

// role_name's inverse; nullopt for any other text.
[[nodiscard]] constexpr std::optional<Role> role_from_name(std::string_view name) {
  for (const Role role : kRoles) {
    if (name == role_name(role)) return role;
  }
  return std::nullopt;
}

}  // namespace sabo
