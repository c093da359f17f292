#include "tests/support/fuzz_targets.hpp"

namespace sabo::testing::fuzz {

std::filesystem::path source_dir() {
  return SABO_SOURCE_DIR;
}

std::vector<std::filesystem::path> seed_scenes(const std::filesystem::path& work) {
  std::vector<std::filesystem::path> seeds;
  for (const char* folder : {"configs", "configs/tests"}) {
    for (const auto& entry : std::filesystem::directory_iterator(source_dir() / folder)) {
      if (entry.path().extension() == ".toml") seeds.push_back(entry.path());
    }
  }
  std::sort(seeds.begin(), seeds.end());
  std::filesystem::create_directories(work / "meshes");
  for (const auto& entry : std::filesystem::directory_iterator(source_dir() / "configs/tests/meshes")) {
    std::filesystem::copy_file(entry.path(), work / "meshes" / entry.path().filename(),
                               std::filesystem::copy_options::overwrite_existing);
  }
  return seeds;
}

bool every_line_has_a_fix(const std::string& message) {
  std::size_t start = 0;
  while (start < message.size()) {
    const std::size_t end = std::min(message.find('\n', start), message.size());
    if (message.substr(start, end - start).find("Fix: ") == std::string::npos) return false;
    start = end + 1;
  }
  return true;
}

Outcome fuzz_scenes(std::size_t count, std::uint64_t seed, const std::filesystem::path& work) {
  Outcome out;
  const auto seeds = seed_scenes(work);
  std::vector<std::string> texts;
  for (const auto& path : seeds) texts.push_back(read_file(path));
  const auto file = work / "mutant.toml";
  for (std::size_t k = 0; k < count; ++k) {
    Mutator mutator(seed + k);
    const std::size_t origin = mutator.below(texts.size());
    std::string what;
    write_file(file, mutator.mutate_text(texts[origin], &what));
    const std::string label =
        "seed " + std::to_string(seed + k) + " (" + seeds[origin].filename().string() + ": " + what + ")";
    const auto start = std::chrono::steady_clock::now();
    try {
      (void)scene::load_scene(file);
      ++out.accepted;
    } catch (const SceneError& error) {
      ++out.refused;
      if (!every_line_has_a_fix(error.what()))
        out.failures.push_back(label + ": a line without a fix: " + error.what());
    } catch (const FileError& error) {
      ++out.refused;
    } catch (const std::exception& error) {
      out.failures.push_back(label + ": " + typeid(error).name() + ": " + error.what());
    }
    out.time(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), label);
    ++out.inputs;
  }
  return out;
}

std::vector<std::filesystem::path> seed_meshes() {
  return {source_dir() / "configs/tests/meshes/basin.stl", source_dir() / "tests/libsabo/io/data/two_hexes.msh",
          source_dir() / "tests/libsabo/io/data/shell_strip.msh"};
}

Outcome fuzz_meshes(std::size_t count, std::uint64_t seed, const std::filesystem::path& work) {
  Outcome out;
  std::vector<std::string> data;
  std::vector<std::filesystem::path> seeds = seed_meshes();
  for (const auto& path : seeds) data.push_back(read_file(path));
  // A binary STL of the same basin's first triangles, so that both STL readers are fed.
  {
    const auto basin = io::read_stl(seeds[0]);
    std::string binary(80, ' ');
    const auto n = static_cast<std::uint32_t>(std::min<std::size_t>(basin.mesh.triangle.size(), 40));
    binary.append(reinterpret_cast<const char*>(&n), 4);
    for (std::uint32_t t = 0; t < n; ++t) {
      float values[12] = {0, 0, 1};
      for (int c = 0; c < 3; ++c) {
        for (int a = 0; a < 3; ++a) {
          values[3 + 3 * c + a] = static_cast<float>(basin.mesh.node_position[basin.mesh.triangle[t][c]][a]);
        }
      }
      binary.append(reinterpret_cast<const char*>(values), sizeof values);
      binary.append(2, '\0');
    }
    data.push_back(binary);
    seeds.push_back(work / "binary.stl");
  }
  for (std::size_t k = 0; k < count; ++k) {
    Mutator mutator(seed + k);
    const std::size_t origin = mutator.below(data.size());
    const bool binary = origin == 3;
    std::string what;
    const std::string mutant = binary || mutator.chance(0.2) ? mutator.mutate_bytes(data[origin], &what)
                                                             : mutator.mutate_text(data[origin], &what);
    const auto file = work / ("mutant" + seeds[origin].extension().string());
    write_file(file, mutant);
    const std::string label =
        "seed " + std::to_string(seed + k) + " (" + seeds[origin].filename().string() + ": " + what + ")";
    const auto start = std::chrono::steady_clock::now();
    try {
      if (file.extension() == ".stl") {
        (void)io::read_stl(file);
      } else {
        (void)io::read_gmsh(file);
      }
      ++out.accepted;
    } catch (const FileError& error) {
      ++out.refused;
      if (std::string(error.what()).find("Fix: ") == std::string::npos) {
        out.failures.push_back(label + ": no fix: " + error.what());
      }
    } catch (const std::exception& error) {
      out.failures.push_back(label + ": " + typeid(error).name() + ": " + error.what());
    }
    out.time(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), label);
    ++out.inputs;
  }
  return out;
}

}  // namespace sabo::testing::fuzz
