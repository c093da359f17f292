// coupler: the central process of a Sabo run (docs/design.md).
//   coupler --scene FILE --endpoint ENDPOINT --out DIR [--resume RUN_DIR/checkpoints/coupler_<step>.h5]
//           [--no-recording]
// stdout carries the JSON event stream for the supervisor; logs go to stderr.
#include <fmt/format.h>
#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <optional>

#include "coupler/coupler.hpp"
#include "libsabo/core/log.hpp"
#include "libsabo/core/signals.hpp"
#include "libsabo/scene/loader.hpp"

int main(int argc, char** argv) {
  using namespace sabo;
  std::filesystem::path scene_file;
  coupler::CouplerOptions options;
  std::string log_level = "info";
  std::optional<double> registration_timeout;
  CLI::App app{"coupler: couples the Sabo solvers of a scene. Normally started by './sabo run SCENE'.", "coupler"};
  app.add_option("--scene", scene_file, "scene file (TOML)")->required();
  app.add_option("--endpoint", options.endpoint, "ZeroMQ endpoint to bind, e.g. ipc:///tmp/run/coupler.sock")
      ->required();
  app.add_option("--out", options.out_dir, "run folder (must exist)")->required();
  app.add_option("--log-level", log_level, "trace, debug, info, warn or error")->capture_default_str();
  app.add_option("--registration-timeout", registration_timeout,
                 "seconds to wait for the solvers to register (default: the scene's run.registration_timeout)");
  double connection_window = 10;
  app.add_option("--connection-window", connection_window,
                 "seconds a connection may stay without registering before it is closed")
      ->capture_default_str();
  app.add_option("--max-unregistered", options.connections.max_unregistered,
                 "connections without a registration kept at once (the oldest beyond are closed)")
      ->capture_default_str();
  app.add_option("--max-message-bytes", options.max_message_bytes,
                 "largest frame accepted (0: from the scene's sizes; also SABO_MAX_MESSAGE_BYTES)")
      ->capture_default_str();
  app.add_option(
      "--resume", options.resume,
      "continue the run in --out from this checkpoint of the coupler (RUN_DIR/checkpoints/coupler_<step>.h5); "
      "every solver must start from its checkpoint of the same step");
  app.add_option("--keys", options.keys,
                 "the run's key set (./sabo keys DIR writes one): over tcp only its roles' CURVE keys join, over ipc "
                 "only its token");
  app.add_option("--resume-reason", options.resume_reason, "why the run is resumed (for summary.json)");
  bool no_recording = false;
  app.add_flag("--no-recording", no_recording,
               "write no traffic.h5 whatever the scene's [recording] says (./sabo replay of the coupler)");
  try {
    app.parse(argc, argv);
    setup_logging("coupler", log_level);
  } catch (const CLI::CallForHelp& help) {
    return app.exit(help);
  } catch (const CLI::ParseError& error) {
    fmt::print(stderr, "coupler: {}. Run 'coupler --help' for the options.\n", error.what());
    return coupler::kBadInput;
  } catch (const std::exception& error) {
    fmt::print(stderr, "coupler: {}\n", error.what());
    return coupler::kBadInput;
  }
  options.record = !no_recording;
  install_stop_handlers();
  coupler::EventStream events;
  options.connections.window = std::chrono::milliseconds(static_cast<long>(1000 * connection_window));
  if (const char* bytes = std::getenv("SABO_MAX_MESSAGE_BYTES"); bytes != nullptr && options.max_message_bytes == 0) {
    options.max_message_bytes = std::atoll(bytes);
  }
  // Every connection takes a file descriptor: take all the system allows (the connection guard keeps
  // peers that do not register to a few of them).
  rlimit files{};
  if (::getrlimit(RLIMIT_NOFILE, &files) == 0 && files.rlim_cur < files.rlim_max) {
    files.rlim_cur = files.rlim_max;
    (void)::setrlimit(RLIMIT_NOFILE, &files);
  }
  try {
    const scene::Scene scene = scene::load_scene(scene_file);
    options.registration_timeout = std::chrono::milliseconds(
        static_cast<long>(1000 * registration_timeout.value_or(scene.run.registration_timeout)));
    coupler::Coupler coupler(scene, options, events);
    return coupler.run();
  } catch (const SceneError& error) {
    spdlog::error("{}", error.what());
    events.error("coupler", error.what());
    return coupler::kBadInput;
  } catch (const std::exception& error) {
    spdlog::error("{}", error.what());
    events.error("coupler", error.what());
    return coupler::kFailed;
  }
}
