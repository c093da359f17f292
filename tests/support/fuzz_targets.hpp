#pragma once
// What the fuzz test and the fuzz campaign feed their mutants to, and what they
// expect: a scene is loaded or refused with a SceneError/FileError (every line
// with its fix), a mesh is read or refused with a FileError; nothing else is
// thrown, nothing crashes, nothing takes long.
#include <chrono>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/io/gmsh.hpp"
#include "libsabo/io/stl.hpp"
#include "libsabo/scene/loader.hpp"
#include "tests/support/fuzz.hpp"

namespace sabo::testing::fuzz {

struct Outcome {
  std::size_t inputs = 0, accepted = 0, refused = 0;
  std::vector<std::string> failures;  // seed, mutation and what went wrong
  double seconds = 0, slowest = 0;
  std::string slowest_input;

  void time(double s, const std::string& what) {
    seconds += s;
    if (s > slowest) {
      slowest = s;
      slowest_input = what;
    }
  }
};

std::filesystem::path source_dir();

// The valid scenes the mutants start from: configs/ and configs/tests/, copied with their meshes into
// `work` (mutants are written beside them, so that relative mesh paths still resolve).
std::vector<std::filesystem::path> seed_scenes(const std::filesystem::path& work);

bool every_line_has_a_fix(const std::string& message);

Outcome fuzz_scenes(std::size_t count, std::uint64_t seed, const std::filesystem::path& work);

// The meshes the mutants start from: binary and ASCII STL, hexahedra and quadrangles in Gmsh.
std::vector<std::filesystem::path> seed_meshes();

Outcome fuzz_meshes(std::size_t count, std::uint64_t seed, const std::filesystem::path& work);

}  // namespace sabo::testing::fuzz
