#pragma once
// The coupler's event stream: one JSON object per line on stdout, read by the
// supervisor (docs/protocol.md, "Events"). Logs go to stderr, never here.
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

namespace sabo::coupler {

class EventStream {
 public:
  explicit EventStream(std::FILE* out = stdout) : out_(out) {}
  void emit(const nlohmann::json& event);
  void listening(const std::string& endpoint);
  // `peer_pid`: the process at the other end of an ipc connection as the kernel names it (0: not known), which
  // the supervisor holds against the one it started; `address`: the peer's tcp address (empty for ipc).
  void registered(const std::string& role, std::uint32_t pid, const std::string& name, int peer_pid,
                  const std::string& address);
  void error(const std::string& process, const std::string& message);
  void done(const std::string& status, const std::string& summary_file);

 private:
  std::FILE* out_;
};

}  // namespace sabo::coupler
