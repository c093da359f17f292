// The coupler's ZAP handler (coupler/authenticator.hpp) with real sockets: over tcp only the CURVE keys of the
// run's roles get a message through, over ipc only the run's token; the role each authenticated as reaches the
// coupler as the registration's User-Id. The connection guard logs each refusal with the peer's address.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "coupler/authenticator.hpp"
#include "coupler/connection_guard.hpp"
#include "libsabo/protocol/security.hpp"
#include "libsabo/protocol/socket.hpp"

namespace sabo::coupler {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using protocol::Mechanism;

const std::vector<std::string> kRoles{"dem_solver", "fem_solver"};

class AuthenticatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("sabo-auth-" + std::to_string(::getpid()) + "-" +
                                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(folder_);
    protocol::write_key_set(folder_, std::vector<std::string>{"coupler", "dem_solver", "fem_solver"}, false);
  }
  void TearDown() override { fs::remove_all(folder_); }

  // A coupler-like ROUTER with the authenticator and the connection guard; returns the bound endpoint.
  std::string serve(const std::string& endpoint) {
    const auto credentials = protocol::read_server_credentials(folder_, kRoles, endpoint);
    server_.secure_server(credentials);
    authenticator_ = std::make_unique<Authenticator>(context_, credentials);
    guard_ = std::make_unique<ConnectionGuard>(context_, server_, ConnectionLimits{}, authenticator_.get());
    server_.bind(endpoint);
    return server_.endpoint();
  }

  // Sends a Register from a client with `credentials`; the User-Id it arrives with, or nullopt when nothing
  // arrives within a second (the handshake was refused).
  std::optional<std::string> register_with(const std::string& endpoint,
                                           const protocol::ClientCredentials& credentials) {
    zmq::context_t context(1);
    protocol::Socket client(context, zmq::socket_type::dealer);
    client.secure_client(credentials);
    client.connect(endpoint);
    sabo::v1::Register registration;
    registration.set_role(sabo::v1::ROLE_DEM);
    client.send(registration);
    protocol::Inbound inbound;
    const auto deadline = std::chrono::steady_clock::now() + 1000ms;
    while (std::chrono::steady_clock::now() < deadline) {
      guard_->tick();
      if (server_.receive(inbound, 20ms)) return inbound.user_id;
    }
    return std::nullopt;
  }

  using RefusalCases = std::vector<std::pair<const char*, protocol::ClientCredentials>>;

  // Each (reason, credentials) of `cases` tried until its refusal is logged from `address`, at most six
  // times: the guard reads the peer's address when the monitor's "accepted" event passes its relay thread,
  // and on a loaded machine a refused connection may be gone by then (logged as from "unknown").
  void refuse_each(const std::string& endpoint, const RefusalCases& cases, const std::string& address) {
    for (const auto& [reason, credentials] : cases) {
      for (int attempt = 0; attempt < 6 && !refused_from(reason, address); ++attempt) {
        EXPECT_EQ(register_with(endpoint, credentials), std::nullopt) << reason;
        std::this_thread::sleep_for(200ms);
        guard_->tick();
      }
    }
  }

  // A refusal for `reason` logged with an address that starts with `address`.
  [[nodiscard]] bool refused_from(const std::string& reason, const std::string& address) const {
    return std::any_of(guard_->refused().begin(), guard_->refused().end(), [&](const RefusedConnection& refused) {
      return refused.reason.find(reason) != std::string::npos && refused.address.starts_with(address);
    });
  }

  fs::path folder_;
  zmq::context_t context_{1};
  protocol::Socket server_{context_, zmq::socket_type::router};
  std::unique_ptr<Authenticator> authenticator_;
  std::unique_ptr<ConnectionGuard> guard_;
};

TEST_F(AuthenticatorTest, OverTcpOnlyTheRolesCurveKeysJoinEachAsItsRole) {
  const std::string endpoint = serve("tcp://127.0.0.1:*");
  const auto dem = protocol::read_client_credentials(folder_, "dem_solver", endpoint);
  const auto fem = protocol::read_client_credentials(folder_, "fem_solver", endpoint);
  EXPECT_EQ(register_with(endpoint, dem), "dem_solver");
  EXPECT_EQ(register_with(endpoint, fem), "fem_solver");  // the role comes from the key, not from the message

  protocol::ClientCredentials stranger = dem;  // knows the coupler's public key, has a key of its own
  stranger.own = protocol::make_curve_keys();
  protocol::ClientCredentials wrong_server = dem;  // the keys of another run's coupler
  wrong_server.server_key = protocol::make_curve_keys().public_key;
  // Each refusal names the peer's address where it is still known. A client without keys (the NULL mechanism)
  // hangs up as soon as it reads the coupler's greeting, and on a loaded machine it is gone before the guard's
  // relay thread reads its address: then the refusal is logged as from "unknown" (CI lost three tries in a row).
  const RefusalCases named{{"is not one of this run's", stranger}, {"does not decrypt", wrong_server}};
  const RefusalCases unnamed{{"another security mechanism", {}}};
  refuse_each(endpoint, named, "127.0.0.1:");
  refuse_each(endpoint, unnamed, "");
  EXPECT_EQ(register_with(endpoint, dem), "dem_solver");  // and the run's own still join

  std::this_thread::sleep_for(200ms);
  guard_->tick();
  for (const auto& refused : guard_->refused()) std::cout << refused.address << ": " << refused.reason << "\n";
  EXPECT_EQ(authenticator_->accepted(), 3u);
  // A refused client tries again every 100 ms until it is closed: one entry per kind, each counted.
  EXPECT_GE(authenticator_->refused(), 1u);  // the stranger's key reached the handler; the others failed before
  EXPECT_GE(guard_->stats().refused_handshakes, 3u);
  for (const auto& [reason, credentials] : named) EXPECT_TRUE(refused_from(reason, "127.0.0.1:")) << reason;
  for (const auto& [reason, credentials] : unnamed) EXPECT_TRUE(refused_from(reason, "")) << reason;
}

TEST_F(AuthenticatorTest, OverIpcOnlyTheRunsTokenJoins) {
  const std::string endpoint = serve("ipc://" + (folder_ / "c.sock").string());
  const auto dem = protocol::read_client_credentials(folder_, "dem_solver", endpoint);
  EXPECT_EQ(dem.mechanism, Mechanism::plain);
  EXPECT_EQ(register_with(endpoint, dem), "dem_solver");
  protocol::ClientCredentials wrong = dem;
  wrong.token = std::string(64, 'a');
  protocol::ClientCredentials unknown = dem;
  unknown.user = "sph_solver";  // a role the scene does not have
  const std::string self = "pid " + std::to_string(::getpid());
  // Each refusal names this process (the peer's pid).
  const RefusalCases cases{{"gave a token that is not this run's", wrong},
                           {"'sph_solver' is not a role of this scene", unknown},
                           {"another security mechanism", {}}};
  refuse_each(endpoint, cases, self);
  for (const auto& refused : guard_->refused()) std::cout << refused.address << ": " << refused.reason << "\n";
  for (const auto& [reason, credentials] : cases) EXPECT_TRUE(refused_from(reason, self)) << reason;
}

TEST(AuthenticatorDecision, NamesTheRoleOrWhyNot) {
  protocol::ServerCredentials curve;
  curve.mechanism = Mechanism::curve;
  curve.clients[std::string(32, 'k')] = "dem_solver";
  zmq::context_t context(1);
  Authenticator authenticator(context, curve);
  std::string reason;
  EXPECT_EQ(authenticator.decide("CURVE", {std::string(32, 'k')}, reason), "dem_solver");
  EXPECT_EQ(authenticator.decide("CURVE", {std::string(32, 'x')}, reason), std::nullopt);
  EXPECT_NE(reason.find("is not one of this run's"), std::string::npos);
  EXPECT_EQ(authenticator.decide("NULL", {}, reason), std::nullopt);
  EXPECT_EQ(reason, "it offers the NULL mechanism; this coupler takes only CURVE keys");
  EXPECT_EQ(authenticator.decide("PLAIN", {"dem_solver", "t"}, reason), std::nullopt);
}

}  // namespace
}  // namespace sabo::coupler
