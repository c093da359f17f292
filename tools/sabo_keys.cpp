// sabo_keys: writes the key set of a run (libsabo/protocol/security.hpp, docs/security.md).
//   sabo_keys DIR [--name NAME ...] [--force]
// DIR is created 0700 and every file 0600: coupler.key / coupler.key_secret and one pair per solver role
// (ZeroMQ CURVE certificates), and ipc.token. `./sabo run` makes one per run in RUN_DIR/keys; `./sabo keys DIR`
// makes one to hand out before a run whose solvers are started by hand on other hosts. Exit status: 0 written,
// 1 not written (message on stderr), 2 bad command line.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/core/role.hpp"
#include "libsabo/protocol/security.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "Writes the key set of a Sabo run: CURVE key pairs for the coupler and each solver role, and the "
      "run's ipc token (docs/security.md)."};
  std::string folder;
  std::vector<std::string> names;
  bool force = false;
  app.add_option("folder", folder, "folder to write (created with mode 0700)")->required();
  app.add_option("--name", names, "the processes to make keys for (default: coupler and every solver role)");
  app.add_flag("--force", force, "replace a key set already in the folder");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    const int code = app.exit(error);
    return code == 0 ? 0 : 2;
  }
  if (names.empty()) {
    names.emplace_back(sabo::protocol::kCouplerKeyName);
    for (const sabo::Role role : sabo::kRoles) names.emplace_back(sabo::role_name(role));
  }
  for (const auto& name : names) {
    if (name.empty() || name.find_first_of("/.\\ ") != std::string::npos) {
      std::cerr << "sabo_keys: --name '" << name << "' is not a process name (e.g. coupler, dem_solver)\n";
      return 2;
    }
  }
  try {
    sabo::protocol::write_key_set(folder, names, force);
  } catch (const sabo::Error& error) {
    std::cerr << "sabo_keys: " << error.what() << "\n";
    return 1;
  }
  std::cout << "wrote the key set of " << names.size() << " processes and the run's token in " << folder << "\n";
  return 0;
}
