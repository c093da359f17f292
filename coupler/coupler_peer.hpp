#pragma once
// One registered solver as the coupler's loop keeps it, and the loop's clock (coupler.cpp,
// coupler_registration.cpp, coupler_summary.cpp and coupler_checkpoint.cpp).
#include <chrono>
#include <memory>
#include <optional>
#include <string>

#include "coupler/coupler.hpp"
#include "coupler/restart_journal.hpp"
#include "libsabo/protocol/socket.hpp"
#include "sabo/v1/sabo.pb.h"

namespace sabo::coupler {

using Clock = std::chrono::steady_clock;
// How long one receive waits before the loop checks for stop signals and hung peers.
inline constexpr std::chrono::milliseconds kPollSlice{100};

inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

struct Coupler::Peer {
  std::string identity;
  int source_fd = -1;   // its connection (ConnectionGuard::take_lost)
  std::string address;  // "10.0.0.2:41234" (tcp) or "pid 1234" (ipc), for messages
  Role role = Role::dem;
  [[nodiscard]] const char* name() const { return role_name(role); }
  double beta = 1.0;
  sabo::v1::Register registration;
  sabo::v1::StepState state;     // its last whole state
  sabo::v1::StepState incoming;  // the message being accepted; a held state stays here
  sabo::v1::StepForces forces;
  protocol::SendBuffer buffer;
  bool has_state = false;
  bool said_goodbye = false;
  sabo::v1::Goodbye goodbye;
  double compute_seconds = 0;       // reported in StepState, summed
  double reported_compute = 0;      // s: compute_seconds of its last message, held or whole
  double reported_wait = 0;         // s: wait_seconds of its last message
  double waited = 0;                // s: what it waited for the forces of the exchange before its last message
  double reported_forces_wait = 0;  // s: forces_wait_seconds of its last message
  double waited_for_forces = 0;     // s: of `waited`, after its walls came ahead (walls ahead only)
  // Hold exchanges (docs/architecture.md, "Multirate"): the exchange at which it steps next (it holds at
  // those before) and the time its states carry until then.
  std::uint64_t next_step_exchange = 0;
  double ahead_time = 0;
  std::uint64_t holds = 0;         // hold exchanges answered, summed
  std::uint64_t solver_steps = 0;  // steps it took (multirate: several per exchange), summed from StepForces
  // Restarts (docs/restart.md): what the coupler keeps to catch a restarted process up.
  std::unique_ptr<RestartJournal> journal;
  std::optional<std::uint64_t> checkpoint_step;  // the step of the checkpoint it was last asked for
  std::optional<std::string> send_error;         // its forces of this step could not be sent (send_forces)
  bool catching_up = false;
  std::uint64_t resumed_at = 0;  // step of the checkpoint its replacement started from
  std::chrono::steady_clock::time_point restarted_wall;
  std::size_t restarts = 0;
};

}  // namespace sabo::coupler
