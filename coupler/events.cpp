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

void EventStream::registered(const std::string& role, std::uint32_t pid, const std::string& name) {
  emit({{"event", "registered"}, {"role", role}, {"pid", pid}, {"name", name}});
}

void EventStream::error(const std::string& process, const std::string& message) {
  emit({{"event", "error"}, {"process", process}, {"message", message}});
}

void EventStream::done(const std::string& status, const std::string& summary_file) {
  emit({{"event", "done"}, {"status", status}, {"summary", summary_file}});
}

}  // namespace sabo::coupler
