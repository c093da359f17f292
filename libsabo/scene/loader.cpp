#include "libsabo/scene/loader.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>

#include "libsabo/scene/detail/builder.hpp"

namespace sabo::scene {

namespace detail {

Builder::Builder(const fs::path& file, const toml::table& document)
    : diag_(file.string()), document_(document), scene_dir_(fs::absolute(file).parent_path()) {
  scene_.file = fs::weakly_canonical(fs::absolute(file));
}

Scene Builder::build() {
  Reader root(diag_, schema::root(), document_, "");
  if (auto version = root.integer("format_version"); version && *version != 1) {
    diag_.add(root.line("format_version"), "format_version", std::to_string(*version),
              "this build reads format_version 1 only", "write format_version = 1 and use the keys of format 1");
  }
  if (const toml::table* run = root.table("run")) read_run(*run);
  read_materials(root);

  const toml::array* particles = root.table_list("particles");
  const toml::array* structures = root.table_list("structures");
  const toml::array* fluids = root.table_list("fluids");
  const toml::array* inflows = root.table_list("inflows");
  has_particles_ = particles != nullptr && !particles->empty();
  has_structures_ = structures != nullptr && !structures->empty();
  has_fluids_ = (fluids != nullptr && !fluids->empty()) || (inflows != nullptr && !inflows->empty());
  const bool lists_readable =
      (particles != nullptr || !root.has("particles")) && (structures != nullptr || !root.has("structures")) &&
      (fluids != nullptr || !root.has("fluids")) && (inflows != nullptr || !root.has("inflows"));
  if (!has_particles_ && !has_structures_ && !has_fluids_ && lists_readable) {
    diag_.add_plain(1, "the scene has no bodies, so there is nothing to simulate",
                    "add at least one [[fluids]], [[inflows]], [[particles]] or [[structures]] table");
  }
  read_sph(root);
  if (fluids != nullptr) {
    for (std::size_t k = 0; k < fluids->size(); ++k) read_fluid(*fluids->get(k)->as_table(), k);
  }
  if (inflows != nullptr) {
    for (std::size_t k = 0; k < inflows->size(); ++k) read_inflow(*inflows->get(k)->as_table(), k);
  }
  check_fluid_materials();
  if (particles != nullptr) {
    for (std::size_t k = 0; k < particles->size(); ++k) read_particle_set(*particles->get(k)->as_table(), k);
  }
  if (structures != nullptr) {
    for (std::size_t k = 0; k < structures->size(); ++k) read_structure(*structures->get(k)->as_table(), k);
  }
  read_solvers(root);
  read_contact(root);
  read_interactions(root);
  check_sph_dem();
  check_free_slip_walls();
  check_lagged_boundary_particles();
  read_recording(root);
  read_gauges(root);
  read_fronts(root);
  read_sensors(root);
  check_overlaps();
  if (diag_.count() == 0) check_costs();
  if (diag_.count() == 0) check_fills();

  diag_.throw_if_any();
  std::sort(scene_.materials.begin(), scene_.materials.end(),
            [](const Material& a, const Material& b) { return a.name < b.name; });
  return std::move(scene_);
}

}  // namespace detail

namespace {

namespace fs = std::filesystem;
using detail::Builder;

// "FILE:LINE:COL: key 'k' = v: TOML syntax error: ..." from toml++'s error.
std::string syntax_message(const std::string& file, const std::string& text, const toml::parse_error& error) {
  const auto line = error.source().begin.line, column = error.source().begin.column;
  std::string line_text;
  {
    std::istringstream stream(text);
    for (std::size_t k = 0; k < line && std::getline(stream, line_text); ++k) {
    }
  }
  const auto trim = [](std::string s) {
    const auto first = s.find_first_not_of(" \t\r");
    const auto last = s.find_last_not_of(" \t\r");
    return first == std::string::npos ? std::string() : s.substr(first, last - first + 1);
  };
  std::string where;
  const auto equals = line_text.find('=');
  const std::string trimmed = trim(line_text);
  if (equals != std::string::npos && !trimmed.starts_with('[') && !trimmed.starts_with('#')) {
    where = fmt::format(" key '{}' = {}:", trim(line_text.substr(0, equals)), trim(line_text.substr(equals + 1)));
  } else if (!trimmed.empty()) {
    where = fmt::format(" the line reads '{}':", trimmed);
  }
  return fmt::format(
      "{}:{}:{}:{} TOML syntax error: {}. Fix: correct the TOML at line {}, column {} (strings in \"quotes\", "
      "arrays in [ ], inline tables {{ ... }} on one line; see https://toml.io).",
      file, line, column, detail::printable_text(where), detail::printable_text(error.description()), line, column);
}

// Where `text` stops being UTF-8 text: a NUL byte (TOML allows none), a UTF-16 or UTF-32 file, or a byte
// sequence that is not UTF-8; the byte offset and what is there. toml++ would read on and report the key
// before it with no reason.
struct NotText {
  enum class Kind { nul, utf16, other };
  std::size_t offset;
  std::string what;
  Kind kind = Kind::other;
};
std::optional<NotText> not_utf8_text(std::string_view text) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[k]); };
  if (text.size() >= 2 && ((byte(0) == 0xFF && byte(1) == 0xFE) || (byte(0) == 0xFE && byte(1) == 0xFF))) {
    return NotText{0, fmt::format("the UTF-16 byte-order mark {:02X} {:02X}", byte(0), byte(1)), NotText::Kind::utf16};
  }
  for (std::size_t k = 0; k < text.size();) {
    const unsigned char c = byte(k);
    if (c == 0) {
      // UTF-16 text of ASCII characters has a NUL in every other byte.
      std::size_t nul[2] = {0, 0};
      const std::size_t head = std::min<std::size_t>(text.size(), 256);
      for (std::size_t i = 0; i < head; ++i) nul[i % 2] += byte(i) == 0 ? 1 : 0;
      const bool utf16 = std::max(nul[0], nul[1]) * 4 >= head && std::min(nul[0], nul[1]) == 0;
      return utf16 ? NotText{k, "a NUL byte (0x00), and every other byte is one: the file looks like UTF-16",
                             NotText::Kind::utf16}
                   : NotText{k, "a NUL byte (0x00)", NotText::Kind::nul};
    }
    std::size_t length = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    bool valid = length > 0 && k + length <= text.size();
    for (std::size_t i = 1; valid && i < length; ++i) valid = (byte(k + i) & 0xC0) == 0x80;
    if (valid && length == 2) valid = c >= 0xC2;  // overlong
    if (valid && length == 3) {
      const unsigned next = byte(k + 1);
      valid = !(c == 0xE0 && next < 0xA0) && !(c == 0xED && next >= 0xA0);  // overlong, surrogates
    }
    if (valid && length == 4) {
      const unsigned next = byte(k + 1);
      valid = c <= 0xF4 && !(c == 0xF0 && next < 0x90) && !(c == 0xF4 && next >= 0x90);
    }
    if (!valid) return NotText{k, fmt::format("the byte 0x{:02X}, which does not start a UTF-8 character", c)};
    k += length;
  }
  return std::nullopt;
}

}  // namespace

Scene load_scene(const std::filesystem::path& file) {
  std::error_code ec;
  if (fs::is_directory(file, ec)) {
    throw FileError(
        fmt::format("{}: is a folder, not a scene file. Fix: give the path of a .toml file.", file.string()));
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    throw FileError(
        fmt::format("{}: cannot open the scene file ({}). Fix: check the path.", file.string(), std::strerror(errno)));
  }
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (const auto problem = not_utf8_text(text)) {
    const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(problem->offset), '\n');
    const std::string name = file.filename().string();
    std::string fix;
    switch (problem->kind) {
      case NotText::Kind::utf16:
        fix = fmt::format("save the scene as UTF-8 text (e.g. iconv -f UTF-16 -t UTF-8 {} > scene.toml)", name);
        break;
      case NotText::Kind::nul:
        fix = fmt::format(
            "remove the NUL byte (most editors do not show it; tr -d '\\000' < {} > scene.toml removes "
            "every one)",
            name);
        break;
      case NotText::Kind::other:
        fix = fmt::format(
            "save the scene as UTF-8 text (a file in another encoding, e.g. Latin-1: iconv -f LATIN1 "
            "-t UTF-8 {} > scene.toml)",
            name);
        break;
    }
    throw SceneError(fmt::format("{}:{}: the file is not UTF-8 text: at byte offset {} there is {}. Fix: {}.",
                                 file.string(), line, problem->offset, problem->what, fix));
  }
  toml::table document;
  try {
    document = toml::parse(std::string_view(text), file.string());
  } catch (const toml::parse_error& error) {
    throw SceneError(syntax_message(file.string(), text, error));
  }
  return Builder(file, document).build();
}

}  // namespace sabo::scene
