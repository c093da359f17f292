// Coupling overhead per step with N interface entities and trivial physics:
// one solver process and one coupler process exchange a full StepState
// (index, position, velocity, angular velocity of N spheres) and a full
// StepForces (index, force, torque) every step, through the same library code
// as a real run (Socket, SendBuffer, SolverLink), with the security of a real run
// (--security: CURVE over tcp, the run's token over ipc, or none). Prints one JSON line.
//
//   bench_coupling_overhead --entities 10000 --transport ipc --steps 2000
//   bench_coupling_overhead --entities 10000 --transport tcp --security curve
// Across two network stacks (issue 25's veth benchmark; as root, namespaces made with `ip netns add`):
//   bench_coupling_overhead --transport tcp --host 10.231.0.1 --coupler-netns sabo-a --solver-netns sabo-b
#include <fcntl.h>
#include <fmt/format.h>
#include <sched.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "coupler/authenticator.hpp"
#include "libsabo/protocol/security.hpp"
#include "libsabo/protocol/solver_link.hpp"
#include "libsabo/protocol/wire.hpp"

using namespace sabo;
using Clock = std::chrono::steady_clock;

namespace {

// The coupler side (the forked child). Binds `endpoint` and writes the bound
// endpoint (the port chosen by the system for tcp) to `endpoint_pipe`.
// Moves the calling process (single-threaded: before any ZeroMQ context) into the named network namespace.
void enter_netns(const std::string& name) {
  if (name.empty()) return;
  const std::string path = "/run/netns/" + name;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || ::setns(fd, CLONE_NEWNET) != 0) {
    throw std::runtime_error(fmt::format("cannot enter the network namespace {}: {}", path, std::strerror(errno)));
  }
  ::close(fd);
}

int run_coupler(const std::string& endpoint, int endpoint_pipe, int steps, const std::filesystem::path& keys) {
  zmq::context_t context(1);
  protocol::Socket socket(context, zmq::socket_type::router);
  std::unique_ptr<coupler::Authenticator> authenticator;
  if (!keys.empty()) {
    const std::vector<std::string> roles{"dem_solver"};
    auto credentials = protocol::read_server_credentials(keys, roles, endpoint);
    socket.secure_server(credentials);
    authenticator = std::make_unique<coupler::Authenticator>(context, credentials);
  }
  socket.bind(endpoint);
  const std::string& bound = socket.endpoint();
  if (::write(endpoint_pipe, bound.data(), bound.size()) != static_cast<ssize_t>(bound.size())) return 1;
  ::close(endpoint_pipe);
  protocol::Inbound inbound;
  if (!socket.receive(inbound, std::chrono::milliseconds(20000))) return 1;  // the solver never registered
  sabo::v1::RegisterReply reply;
  reply.set_accepted(true);
  reply.set_interest_all(true);
  socket.send(reply, inbound.peer);
  const std::string peer = inbound.peer;

  sabo::v1::StepState state;
  sabo::v1::StepForces forces;
  protocol::SendBuffer buffer;
  for (int step = 0; step < steps; ++step) {
    if (!socket.receive(inbound, std::chrono::milliseconds(10000))) return 1;
    inbound.parse(state);
    forces.Clear();
    forces.set_step(state.step());
    forces.set_dt(1e-4);
    forces.mutable_index()->CopyFrom(state.index());
    const int n3 = state.position_size();
    auto* f = forces.mutable_force();
    auto* t = forces.mutable_torque();
    f->Resize(n3, 0.0);
    t->Resize(n3, 0.0);
    const double* x = state.position().data();
    double* fp = f->mutable_data();
    for (int i = 0; i < n3; ++i) fp[i] = -1e-3 * x[i];
    socket.send(forces, buffer, peer);
  }
  return 0;
}

struct Result {
  double median_us, min_us, p90_us;
};

Result run_solver(const std::string& endpoint, int entities, int steps, int warmup, const std::filesystem::path& keys) {
  const auto credentials =
      keys.empty() ? protocol::ClientCredentials{} : protocol::read_client_credentials(keys, "dem_solver", endpoint);
  protocol::SolverLink link(endpoint, std::chrono::milliseconds(20000), credentials);
  sabo::v1::Register registration;
  registration.set_protocol_version(protocol::kProtocolVersion);
  registration.set_role(sabo::protocol::to_wire(sabo::Role::dem));
  registration.set_exposes_particles(true);
  registration.set_exposes_angular_velocity(true);
  link.register_solver(registration);

  std::vector<double> x(3 * static_cast<std::size_t>(entities)), v(x.size(), 1.0), w(x.size(), 0.5);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = static_cast<double>(i) * 1e-3;
  sabo::v1::StepState state;
  std::vector<double> per_step;
  per_step.reserve(static_cast<std::size_t>(steps));
  for (int step = 0; step < steps; ++step) {
    const auto start = Clock::now();
    state.Clear();
    state.set_step(static_cast<std::uint64_t>(step));
    auto* index = state.mutable_index();
    index->Resize(entities, 0);
    for (int i = 0; i < entities; ++i) index->Set(i, static_cast<std::uint32_t>(i));
    state.mutable_position()->Assign(x.begin(), x.end());
    state.mutable_velocity()->Assign(v.begin(), v.end());
    state.mutable_angular_velocity()->Assign(w.begin(), w.end());
    link.send_state(state);
    const auto& forces = link.receive_forces(static_cast<std::uint64_t>(step));
    const double* f = forces.force().data();
    for (std::size_t i = 0; i < x.size(); ++i) x[i] += 1e-9 * f[i];
    if (step >= warmup) per_step.push_back(std::chrono::duration<double, std::micro>(Clock::now() - start).count());
  }
  std::sort(per_step.begin(), per_step.end());
  const auto at = [&](double q) {
    return per_step[static_cast<std::size_t>(q * static_cast<double>(per_step.size() - 1))];
  };
  return {at(0.5), per_step.front(), at(0.9)};
}

}  // namespace

int main(int argc, char** argv) {
  int entities = 1000;
  int steps = 2000;
  int warmup = 100;
  std::string transport = "ipc";
  CLI::App app{"Coupling overhead per step: full state in, forces out, N entities."};
  app.add_option("--entities", entities, "interface entities (spheres) exchanged per step")->capture_default_str();
  app.add_option("--steps", steps, "measured steps + warmup")->capture_default_str();
  app.add_option("--warmup", warmup, "steps not measured")->capture_default_str();
  app.add_option("--transport", transport, "ipc or tcp")->check(CLI::IsMember({"ipc", "tcp"}))->capture_default_str();
  std::string security = "none";
  app.add_option("--security", security, "none, or as a run: CURVE over tcp, the token over ipc")
      ->check(CLI::IsMember({"none", "run"}))
      ->capture_default_str();
  std::string host = "127.0.0.1", coupler_netns, solver_netns;
  app.add_option("--host", host, "tcp: the address the coupler listens on")->capture_default_str();
  app.add_option("--coupler-netns", coupler_netns, "run the coupler process in this network namespace");
  app.add_option("--solver-netns", solver_netns, "run the solver process in this network namespace");
  CLI11_PARSE(app, argc, argv);
  steps += warmup;

  const std::string ipc_path = fmt::format("/tmp/sabo-bench-{}.sock", ::getpid());
  const std::string endpoint = transport == "ipc" ? "ipc://" + ipc_path : fmt::format("tcp://{}:*", host);
  std::filesystem::path keys;
  if (security == "run") {
    keys = std::filesystem::temp_directory_path() / fmt::format("sabo-bench-keys-{}", ::getpid());
    const std::vector<std::string> names{"coupler", "dem_solver"};
    protocol::write_key_set(keys, names, true);
  }

  int endpoint_pipe[2];
  if (::pipe(endpoint_pipe) != 0) {
    std::perror("pipe");
    return 1;
  }
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(endpoint_pipe[0]);
    int code = 1;
    try {
      enter_netns(coupler_netns);
      code = run_coupler(endpoint, endpoint_pipe[1], steps, keys);
    } catch (const std::exception& error) {
      std::fprintf(stderr, "coupler process: %s\n", error.what());
    }
    _exit(code);
  }
  ::close(endpoint_pipe[1]);
  std::string bound;
  char chunk[256];
  for (ssize_t got; (got = ::read(endpoint_pipe[0], chunk, sizeof chunk)) > 0;)
    bound.append(chunk, static_cast<std::size_t>(got));
  ::close(endpoint_pipe[0]);
  if (bound.empty()) {
    std::fprintf(stderr, "the coupler process could not bind %s\n", endpoint.c_str());
    ::waitpid(child, nullptr, 0);
    return 1;
  }
  Result result{};
  try {
    enter_netns(solver_netns);
    result = run_solver(bound, entities, steps, warmup, keys);
  } catch (const std::exception& error) {
    std::fprintf(stderr, "solver process: %s\n", error.what());
    ::kill(child, SIGKILL);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  if (transport == "ipc") std::filesystem::remove(ipc_path);
  if (!keys.empty()) std::filesystem::remove_all(keys);
  const double bytes_per_step =
      static_cast<double>(entities) * (4 + 3 * 8 * 3) + static_cast<double>(entities) * (4 + 2 * 3 * 8);
  fmt::print(
      "{{\"bench\": \"coupling_overhead\", \"transport\": \"{}\", \"security\": \"{}\", \"across_netns\": {}, "
      "\"entities\": {}, \"steps\": {}, "
      "\"median_us_per_step\": {:.2f}, \"min_us_per_step\": {:.2f}, \"p90_us_per_step\": {:.2f}, "
      "\"payload_bytes_per_step\": {:.0f}}}\n",
      transport, security == "none" ? "none" : (transport == "tcp" ? "curve" : "token"),
      coupler_netns.empty() && solver_netns.empty() ? "false" : "true", entities, steps - warmup, result.median_us,
      result.min_us, result.p90_us, bytes_per_step);
  return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? 0 : 1;
}
