#pragma once
// Reading and validating a scene file (TOML, format 1; reference: docs/scene.md).
#include <filesystem>

#include "libsabo/scene/scene.hpp"

namespace sabo::scene {

// Loads `file`, checks every value against the schema (scene/schema.hpp) and
// the checks across keys, and returns the scene with defaults filled in, names
// and paths resolved (mesh files and relative solver programs made absolute,
// directions normalised, materials sorted by name).
// Throws sabo::SceneError listing every problem of the file, one per line, as
// "FILE:LINE: key 'a.b' = VALUE: problem. Fix: ...", and sabo::FileError when
// the file cannot be read.
[[nodiscard]] Scene load_scene(const std::filesystem::path& file);

}  // namespace sabo::scene
