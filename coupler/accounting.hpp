#pragma once
// What the coupler accounts for a run: the force on every structure part split
// by source (forces.csv) and the energy balance (energy.csv).
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "libsabo/core/types.hpp"
#include "libsabo/io/hdf5.hpp"

namespace sabo::coupler {

// One solver's part of an exchange, from the state that ends it: the seconds it computed since its state
// before (its own forces of the exchange before included, also those computed while the coupler worked), and
// the seconds it then waited for its forces.
struct SolverCycle {
  double compute = 0;
  double waited = 0;
  // Walls ahead at that exchange: of `waited`, what it waited for its forces after its walls came (the rest
  // was for the walls); nullopt: it waited for one StepForces.
  std::optional<double> waited_for_forces;
};
// The pairs' seconds at an exchange: all of them, and of those the pairs whose boundary particles went ahead.
struct PairSeconds {
  double all = 0;
  double walls_ahead = 0;
};
// The seconds by which the pairs' `pair_seconds` lengthened an exchange: what the slowest solver (the one that
// computed longest) waited for its forces, up to pair_seconds; had the forces come pair_seconds sooner, it
// would have waited that much less. All of them when the slowest solver waits for them, none when it computes
// its own forces meanwhile. (The longest compute + wait over all solvers against the same with each wait
// shortened says the same, but each solver's compute + wait is the exchange's length plus its own noise, and
// the largest of them over-counts.) A solver that got its walls ahead waited for the pairs that placed them
// before it could compute, and for the others only after: each part counts against its own wait.
[[nodiscard]] double pairs_on_critical_path(const std::vector<SolverCycle>& cycles, const PairSeconds& pairs);

// Opens `file` for writing (created or truncated); throws FileError naming it.
[[nodiscard]] std::FILE* open_for_writing(const std::filesystem::path& file);
// Opens `file` to append to it (a resumed run continues its histories); FileError naming it when it cannot.
[[nodiscard]] std::FILE* open_for_appending(const std::filesystem::path& file);

// forces.csv: one row per output time, part and source:
//   time, part, source, Fx, Fy, Fz, F, F_peak
// F* is the mean force over the output interval that ends at `time` (impulse
// divided by duration; N), F its magnitude, F_peak the largest instantaneous
// magnitude within the interval. The first row (t = 0) holds the force at t = 0.
class ForceHistory {
 public:
  ForceHistory(const std::filesystem::path& file, std::vector<std::string> part_names,
               std::vector<std::string> sources);
  // Writes to `file`, opened before (open_for_writing), which it then owns; `header`: false when continuing
  // a file (open_for_appending) whose state restore() then reads.
  ForceHistory(std::FILE* file, std::vector<std::string> part_names, std::vector<std::string> sources,
               bool header = true);
  // sensors.csv: the same accounting over the scene's sensors instead of parts,
  //   time, sensor, part, source, Fx, Fy, Fz, F, F_peak, area, pressure
  // with each sensor's part, area (m^2) and the mean normal pressure -F.n / area (Pa).
  struct SensorRow {
    std::string part;
    double area = 0;             // m^2, > 0
    Vec3 normal = Vec3::Zero();  // unit, outward (zero: no pressure, written 0)
  };
  ForceHistory(std::FILE* file, std::vector<std::string> sensor_names, std::vector<SensorRow> sensors,
               std::vector<std::string> sources, bool header = true);
  ~ForceHistory();
  ForceHistory(const ForceHistory&) = delete;
  ForceHistory& operator=(const ForceHistory&) = delete;

  // The force of `source` on `part` during a step of length dt (s).
  void add(std::size_t part, std::size_t source, const Vec3& force, double dt);
  void write(double time);
  void close();
  // The open output interval and the run's peaks, for the coupler's checkpoint. restore() throws FileError
  // when the parts or sources differ.
  void save(io::hdf5::Group& group) const;
  void restore(const io::hdf5::Group& group);
  // Largest instantaneous |F| over the run per part and source, N.
  [[nodiscard]] const std::vector<std::vector<double>>& peak() const { return run_peak_; }
  [[nodiscard]] const std::vector<std::string>& part_names() const { return part_names_; }
  [[nodiscard]] const std::vector<std::string>& sources() const { return sources_; }

 private:
  struct Accumulator {
    Vec3 impulse = Vec3::Zero();
    Vec3 last = Vec3::Zero();
    double duration = 0;
    double peak = 0;
  };
  std::FILE* file_ = nullptr;
  std::vector<std::string> part_names_;
  std::vector<std::string> sources_;
  std::vector<SensorRow> sensors_;                      // [part]: sensors.csv's columns; empty for forces.csv
  std::vector<std::vector<Accumulator>> accumulators_;  // [part][source]
  std::vector<std::vector<double>> run_peak_;
};

// The energy of the coupled system (J) at one time.
struct EnergySample {
  double time = 0;
  double kinetic = 0;
  double potential = 0;
  double solver_elastic = 0;   // springs and strain inside the solvers
  double contact_elastic = 0;  // penalty springs of the coupler
  double dissipated = 0;       // reported by the solvers
  double inflow = 0;           // reported by the solvers: brought in from outside the scene (inflows)
  [[nodiscard]] double total() const { return kinetic + potential + solver_elastic + contact_elastic; }
  // What the scene's own energy is: the total less what the inflows brought in.
  [[nodiscard]] double own() const { return total() - inflow; }
};

// energy.csv: time, kinetic, potential, solver_elastic, contact_elastic, total, dissipated, inflow.
class EnergyHistory {
 public:
  explicit EnergyHistory(const std::filesystem::path& file);
  explicit EnergyHistory(std::FILE* file, bool header = true);  // opened before, then owned
  ~EnergyHistory();
  EnergyHistory(const EnergyHistory&) = delete;
  EnergyHistory& operator=(const EnergyHistory&) = delete;

  // Every step: tracks the initial sample and the largest own() energy (the total less what inflows
  // brought in: the total itself in a closed scene). `write` appends a row.
  void observe(const EnergySample& sample, bool write);
  void close();
  void save(io::hdf5::Group& group) const;
  void restore(const io::hdf5::Group& group);
  [[nodiscard]] const EnergySample& initial() const { return initial_; }
  [[nodiscard]] const EnergySample& last() const { return last_; }
  [[nodiscard]] double max_total() const { return max_total_; }  // of own()

 private:
  std::FILE* file_ = nullptr;
  bool first_ = true;
  EnergySample initial_, last_;
  double max_total_ = 0;
};

// One deformable FEM part's energies at one time (StepState.part_energies), J.
struct PartEnergySample {
  double time = 0;  // s
  double kinetic = 0, internal = 0, plastic_work = 0, hourglass = 0, eroded = 0, external_work = 0;
  std::uint64_t eroded_elements = 0;
};

// The energy history of the deformable FEM parts for summary.json: a sample
// per part at every output time, and the last one.
class PartEnergyHistory {
 public:
  // Every step; `keep`: an output time.
  void observe(const PartEnergySample& sample, const std::string& part, bool keep);
  // Per part (sorted by name): the kept samples, the last one appended when it was not kept.
  [[nodiscard]] std::map<std::string, std::vector<PartEnergySample>> history() const;
  void save(io::hdf5::Group& group) const;
  void restore(const io::hdf5::Group& group);

 private:
  struct Series {
    std::vector<PartEnergySample> kept;
    PartEnergySample last;
    bool last_kept = false;
  };
  std::map<std::string, Series> parts_;
};

}  // namespace sabo::coupler
