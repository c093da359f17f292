#pragma once
// SIGINT/SIGTERM turn into a flag that long waits poll, so that every process
// stops at a clean point with its files closed.
namespace sabo {

void install_stop_handlers();
[[nodiscard]] bool stop_requested();
[[nodiscard]] int stop_signal();  // the signal that set the flag, 0 if none

}  // namespace sabo
