#pragma once
// Instability detection (docs/physics.md, "Instability detection"): after every step each solver looks at its
// state for what a stable explicit step never produces (a value that is not finite, a speed above a bound, a
// density far from rest, an inverted element). The first bad step stops the run with the process, the step,
// the entities and their values, and RUN_DIR/instability.vtp holds those entities and their neighbours for
// ParaView.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/core/role.hpp"
#include "libsabo/core/types.hpp"
#include "libsabo/io/vtk.hpp"

namespace sabo::scene {
struct Scene;
}

namespace sabo::solver {

// A run that stopped on an instability; what() names the process, the step, the entities, their values and
// the file with them.
class InstabilityError : public Error {
 public:
  using Error::Error;
};

struct StabilityLimits {
  double max_speed = 0;  // m/s
  // SPH: rho / rho0 outside [min, max] is no weakly compressible flow any more.
  double min_density_ratio = 0;
  double max_density_ratio = 0;
};

// The limits of `role` in `scene`: run.max_speed, or, when absent, the sound speed for the sph_solver (the
// weakly compressible model needs speeds well below it) and kDefaultMaxSpeed (or ten times the fastest initial
// speed of the scene, if more) for the others; sph.density_ratio_limits.
inline constexpr double kDefaultMaxSpeed = 1000.0;  // m/s: no debris flow, boulder or structure node comes near
[[nodiscard]] StabilityLimits stability_limits(const scene::Scene& scene, Role role);

struct Instability {
  std::string what;                  // "not finite", "too fast", "density", "inverted"
  std::vector<std::size_t> indices;  // into the solver's own arrays: the culprits, the first kMaxReported
  std::string detail;                // "sphere 12: speed 1.3e+03 m/s above max_speed = 1000 m/s; ..."
  std::size_t group = 0;             // the solver's own: which body the indices are of (the fem_solver's part)
  static constexpr std::size_t kMaxReported = 10;
};

// The entities (`noun`: "sphere", "particle", "node") whose position or velocity is not finite, or whose speed
// is above `max_speed`; entities with active[i] == 0 are skipped (empty: all active). nullopt: none. `ids`:
// the numbers to report (empty: the index).
[[nodiscard]] std::optional<Instability> check_motion(std::span<const Vec3> position, std::span<const Vec3> velocity,
                                                      std::span<const std::uint8_t> active, double max_speed,
                                                      std::string_view noun, std::span<const std::uint64_t> ids = {});

// The active particles whose density over their rest density, density[i] / rest_density[material[i]], is
// outside [min_density_ratio, max_density_ratio] (or not finite); nullopt: none.
[[nodiscard]] std::optional<Instability> check_density(std::span<const double> density,
                                                       std::span<const std::uint32_t> material,
                                                       std::span<const double> rest_density,
                                                       std::span<const std::uint8_t> active,
                                                       const StabilityLimits& limits);

// Writes the culprits of `instability` and every entity within `radius` (m) of one of them into `file` (a
// .vtp of points): position, velocity, `culprit` (1 for the culprits) and the index, plus `point_data` (full
// arrays, one value a point of `position`, picked for the points written).
void write_instability(const std::filesystem::path& file, std::span<const Vec3> position,
                       std::span<const Vec3> velocity, const Instability& instability, double radius,
                       std::span<const std::pair<std::string, std::span<const double>>> point_data = {});

// RUN_DIR/instability.vtp, or instability_<role>.vtp when another process wrote that first.
[[nodiscard]] std::filesystem::path instability_file(const std::filesystem::path& run_dir, Role role);

}  // namespace sabo::solver
