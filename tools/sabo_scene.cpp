// sabo_scene: checks scene files and prints the scene reference.
//   sabo_scene check SCENE [--bin-dir DIR]  -> launch plan (JSON) on stdout, warnings on stderr
//   sabo_scene schema-doc                   -> docs/scene.md on stdout
// Exit status: 0 success, 2 the scene is wrong (message on stderr), 1 any
// other error (unreadable file, bad command line).
#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <string>

#include "libsabo/core/error.hpp"
#include "libsabo/scene/loader.hpp"
#include "libsabo/scene/plan.hpp"
#include "libsabo/scene/schema.hpp"
#include "libsabo/scene/warnings.hpp"

namespace {

constexpr int kExitOther = 1;
constexpr int kExitSceneError = 2;

// The folder of this executable: the other built executables sit beside it.
std::filesystem::path own_folder() {
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::current_path() : self.parent_path();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Checks Sabo scene files and prints their reference."};
  app.require_subcommand(1);

  std::string scene_path;
  std::string bin_dir = own_folder().string();
  CLI::App* check = app.add_subcommand("check", "Load and validate a scene; print the launch plan as JSON.");
  check->add_option("scene", scene_path, "Scene file (TOML)")->required();
  check->add_option("--bin-dir", bin_dir, "Folder of the built executables (default: this program's folder)");

  app.add_subcommand("schema-doc", "Print the markdown reference of the scene format (docs/scene.md).");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    const int code = app.exit(error);
    return code == 0 ? 0 : kExitOther;
  }

  try {
    if (check->parsed()) {
      const auto scene = sabo::scene::load_scene(scene_path);
      for (const auto& warning : sabo::scene::scene_warnings(scene)) std::cerr << warning << "\n";
      std::cout << sabo::scene::launch_plan(scene, bin_dir).dump(2) << "\n";
    } else {
      std::cout << sabo::scene::schema::markdown();
    }
  } catch (const sabo::SceneError& error) {
    std::cerr << error.what() << "\n";
    return kExitSceneError;
  } catch (const sabo::FileError& error) {
    // An unreadable or missing scene file is bad input too.
    std::cerr << error.what() << "\n";
    return kExitSceneError;
  } catch (const std::exception& error) {
    std::cerr << "sabo_scene: " << error.what() << "\n";
    return kExitOther;
  }
  return 0;
}
