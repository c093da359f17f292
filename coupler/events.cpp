#include "coupler/events.hpp"

namespace sabo::coupler {

void EventStream::emit(const nlohmann::json& event) {
  const std::string line = event.dump() + "\n";
  std::fwrite(line.data(), 1, line.size(), out_);
  std::fflush(out_);
}

void EventStream::listening(const std::string& endpoint) {
  emit({{"event", "listening"}, {"endpoint", endpoint}});
}

void EventStream::registered(const std::string& role, std::uint32_t pid, const std::string& name, int peer_pid,
                             const std::string& address) {
  nlohmann::json event = {{"event", "registered"}, {"role", role}, {"pid", pid}, {"name", name}};
  if (peer_pid > 0) event["peer_pid"] = peer_pid;
  if (!address.empty()) event["address"] = address;
  emit(event);
}

void EventStream::error(const std::string& process, const std::string& message) {
  emit({{"event", "error"}, {"process", process}, {"message", message}});
}

void EventStream::done(const std::string& status, const std::string& summary_file) {
  emit({{"event", "done"}, {"status", status}, {"summary", summary_file}});
}

}  // namespace sabo::coupler
