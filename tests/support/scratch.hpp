#pragma once
// A folder of this test process's files, created on first use and removed when
// the test program ends: scratch("x.h5") is a path inside it.
#include <unistd.h>

#include <filesystem>
#include <string>

namespace sabo::testing {

inline std::filesystem::path scratch(const std::string& name) {
  static const struct Folder {
    std::filesystem::path path = std::filesystem::temp_directory_path() / ("sabo_test_" + std::to_string(::getpid()));
    Folder() { std::filesystem::create_directories(path); }
    ~Folder() {
      std::error_code ignored;
      std::filesystem::remove_all(path, ignored);
    }
  } folder;
  return folder.path / name;
}

}  // namespace sabo::testing
