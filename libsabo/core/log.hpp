#pragma once
// One logging set-up for every process: spdlog to stderr (the supervisor
// writes it into <role>.log), with the process name in each line.
#include <spdlog/spdlog.h>

#include <string>

namespace sabo {

// level: trace, debug, info, warn, error. Throws sabo::Error for an unknown level.
void setup_logging(const std::string& process_name, const std::string& level = "info");

}  // namespace sabo
