#pragma once
// Who may talk to the coupler (docs/security.md). A run's key set is a folder the supervisor makes per run
// (0700, files 0600):
//   coupler.key, coupler.key_secret        the coupler's CURVE key pair
//   ROLE.key, ROLE.key_secret              one pair per solver role (sph_solver, dem_solver, fem_solver)
//   ipc.token                              a random secret shared by the processes of the run
// The .key files hold the public key only (what may be copied to another host); .key_secret holds both. The
// files are ZeroMQ certificates in CZMQ's format (zcert), so ZeroMQ's own tools read them.
//
// Over tcp the coupler is a CURVE server and accepts only the roles' public keys; over ipc it is a PLAIN
// server and accepts only the run's token (the socket sits in a folder only the user can enter: the token
// tells the processes of this run from any other process of the same user). Either way a ZAP handler
// (coupler/authenticator.hpp) decides, and names the role a connection authenticated as.
#include <chrono>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace sabo::protocol {

// A CURVE key pair, each key Z85-encoded (40 characters).
struct CurveKeys {
  std::string public_key;
  std::string secret_key;
};

// A new key pair from libsodium (through libzmq); LibraryError when this libzmq was built without CURVE.
[[nodiscard]] CurveKeys make_curve_keys();
// The 32 bytes a Z85 key stands for; nullopt when `z85` is not a 40-character Z85 key.
[[nodiscard]] std::optional<std::string> decode_key(const std::string& z85);

enum class Transport { ipc, tcp, other };
[[nodiscard]] Transport transport_of(const std::string& endpoint);

// What a connection to the coupler uses (ZMTP security mechanisms).
enum class Mechanism { none, plain, curve };
[[nodiscard]] const char* mechanism_name(Mechanism mechanism);

// The file names of a key set.
inline constexpr const char* kCouplerKeyName = "coupler";
inline constexpr const char* kTokenFile = "ipc.token";
[[nodiscard]] std::filesystem::path public_key_file(const std::filesystem::path& folder, const std::string& name);
[[nodiscard]] std::filesystem::path secret_key_file(const std::filesystem::path& folder, const std::string& name);

// Writes a key set into `folder` (created 0700 if absent; files 0600): a CURVE pair for each of `names`
// (the coupler and the solver roles) and a new ipc.token. Refuses (FileError naming the file and the fix) to
// replace files already there unless `replace`.
void write_key_set(const std::filesystem::path& folder, std::span<const std::string> names, bool replace);

// Reads one certificate: a .key file (public only) or a .key_secret file (both keys; refused when others may
// read it). FileError naming the file, the line and the fix.
[[nodiscard]] CurveKeys read_certificate(const std::filesystem::path& file, bool with_secret);
[[nodiscard]] std::string read_token(const std::filesystem::path& folder);

// What a solver needs to connect over `endpoint` with the key set in `folder`: over tcp its own pair and the
// coupler's public key; over ipc the token.
struct ClientCredentials {
  Mechanism mechanism = Mechanism::none;
  std::string user;        // plain: the process's role name
  std::string token;       // plain
  CurveKeys own;           // curve
  std::string server_key;  // curve: the coupler's public key
};
[[nodiscard]] ClientCredentials read_client_credentials(const std::filesystem::path& folder, const std::string& name,
                                                        const std::string& endpoint);

// What the coupler needs: over tcp its own pair and the public key of each role in `roles` (role name ->
// 32-byte key); over ipc the token.
struct ServerCredentials {
  Mechanism mechanism = Mechanism::none;
  CurveKeys own;                               // curve
  std::map<std::string, std::string> clients;  // curve: 32-byte public key -> role name
  std::string token;                           // plain
  std::vector<std::string> roles;              // names a plain client may give
};
[[nodiscard]] ServerCredentials read_server_credentials(const std::filesystem::path& folder,
                                                        std::span<const std::string> roles,
                                                        const std::string& endpoint);

// ZMTP heartbeats (ZMQ_HEARTBEAT_IVL / _TIMEOUT / _TTL): a peer whose host vanished or whose process stopped
// answers no PING, and its connection is closed `timeout` after the last sign of life.
struct Heartbeat {
  std::chrono::milliseconds interval{1000};
  std::chrono::milliseconds timeout{5000};
  // The scene's run.heartbeat_timeout (s): a ping every fifth of it.
  [[nodiscard]] static Heartbeat after(double timeout_seconds) {
    const auto timeout = std::chrono::milliseconds(static_cast<long>(1000 * timeout_seconds));
    return {.interval = timeout / 5, .timeout = timeout};
  }
};

}  // namespace sabo::protocol
