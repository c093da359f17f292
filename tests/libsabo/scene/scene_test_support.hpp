#pragma once
// Helpers of the scene tests: temporary scene files and running sabo_scene.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace sabo::scene::testing {

inline std::filesystem::path source_dir() {
  return SABO_SOURCE_DIR;
}
inline std::filesystem::path bin_dir() {
  return SABO_BIN_DIR;
}

// A fresh folder under the system temp folder, removed at the end of the test.
class TempFolder {
 public:
  TempFolder() {
    static int counter = 0;
    path_ = std::filesystem::temp_directory_path() /
            ("sabo_scene_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempFolder() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempFolder(const TempFolder&) = delete;
  TempFolder& operator=(const TempFolder&) = delete;

  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

  std::filesystem::path write(const std::string& name, const std::string& text) const {
    const auto file = path_ / name;
    std::filesystem::create_directories(file.parent_path());
    std::ofstream(file) << text;
    return file;
  }

 private:
  std::filesystem::path path_;
};

inline std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

struct ToolResult {
  int exit_code = -1;
  std::string out, err;
};

// Runs SABO_BIN_DIR/sabo_scene with `arguments` (shell words, already quoted).
inline ToolResult run_tool(const std::string& arguments) {
  TempFolder folder;
  const auto out = folder.path() / "out.txt", err = folder.path() / "err.txt";
  // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on a chain of `+`.
  std::string command = "'";
  command += (bin_dir() / "sabo_scene").string();
  command += "' ";
  command += arguments;
  command += " >'";
  command += out.string();
  command += "' 2>'";
  command += err.string();
  command += "'";
  const int status = std::system(command.c_str());
  ToolResult result;
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.out = read_text(out);
  result.err = read_text(err);
  return result;
}

// The beginning of a valid scene: run settings and two materials.
inline const char* const kSceneHead = R"(format_version = 1
[run]
end_time = 1.0
output_interval = 0.1
[materials.granite]
density = 3000.0
youngs_modulus = 30e9
poisson_ratio = 0.3
[materials.concrete]
density = 2300.0
youngs_modulus = 8e9
poisson_ratio = 0.23
)";

inline const char* const kOneSphere = R"(
[[particles]]
name = "boulders"
material = "granite"
spheres = [ { center = [0.0, 0.0, 3.0], radius = 0.5 } ]
)";

inline const char* const kGround = R"(
[[structures]]
name = "ground"
material = "concrete"
shape = "plane"
origin = [0.0, 0.0, 0.0]
length = 10.0
width = 10.0
)";

}  // namespace sabo::scene::testing
