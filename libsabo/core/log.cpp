#include "libsabo/core/log.hpp"

#include <spdlog/sinks/stdout_sinks.h>

#include "libsabo/core/error.hpp"

namespace sabo {

void setup_logging(const std::string& process_name, const std::string& level) {
  auto logger = spdlog::stderr_logger_mt(process_name);
  logger->set_pattern("%Y-%m-%d %H:%M:%S.%e [%n] %^%l%$: %v");
  const auto parsed = spdlog::level::from_str(level);
  if (parsed == spdlog::level::off && level != "off") {
    throw Error("unknown log level '" + level + "'. Fix: use trace, debug, info, warn or error.");
  }
  logger->set_level(parsed);
  logger->flush_on(spdlog::level::info);
  spdlog::set_default_logger(logger);
}

}  // namespace sabo
