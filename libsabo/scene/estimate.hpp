#pragma once
// What a scene will cost before anything runs, from the scene alone (and the
// sizes of its mesh files): the particles, elements and surface of each
// solver, the number of steps, the memory of all the processes together and
// the largest message a solver sends. The scene check refuses a scene that
// cannot run on this machine with it (scene/loader.hpp), and the coupler sizes
// the largest frame it accepts from it (ZMQ_MAXMSGSIZE).
//
// Counts are estimates of what the solvers build (lattices, structured grids,
// surface samplings), close to them but not exact; `*_bound` figures are upper
// bounds, for what must never be exceeded (the message sizes).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "libsabo/scene/scene.hpp"

namespace sabo::scene {

// Bytes per entity of all the processes together (the solver's model, the coupler's copy, the messages
// both ways and their buffers): bench/scene_memory.py's slopes of the peak RSS between two sizes of a scene,
// rounded up (measured 820, 918, 917, 1179, 2551 and 679 B; bench/RESULTS.md, "Scene size").
inline constexpr double kBytesPerFluidParticle = 900;
inline constexpr double kBytesPerWallParticle = 1000;
inline constexpr double kBytesPerSphere = 1000;
inline constexpr double kBytesPerHexahedron = 1200;
inline constexpr double kBytesPerShell = 2600;
inline constexpr double kBytesPerSurfaceTriangle = 700;  // of rigid structures (an element's carry its own)
// What the processes take before their first entity (code, libraries, ZeroMQ, HDF5): measured 12 to 18 MB
// per process (the intercepts), taken as 20 MB.
inline constexpr double kBytesPerProcess = 20e6;

// A run of more steps than this cannot be made (the coupler refuses a stable step that would need more:
// a model blown up, or an input such as a Young's modulus of 1e300).
inline constexpr double kMaxSteps = 1e10;
// More output times than this are refused: every output time writes a file per solver.
inline constexpr double kMaxOutputs = 1e6;

struct SceneEstimate {
  // sph_solver
  std::vector<double> fluid_particles;  // [fluid body]: particles at t = 0
  double fluid_particles_bound = 0;     // all bodies, at most
  double wall_particles = 0;            // structures and boulders sampled as SPH wall particles
  double wall_particles_bound = 0;
  // dem_solver
  std::vector<double> spheres;  // [particle set]
  // fem_solver
  std::vector<double> elements;           // [structure]: hexahedra or shells (0: rigid)
  std::vector<double> surface_triangles;  // [structure]: of its contact surface now
  double surface_nodes_bound = 0;         // all structures: of the contact surface, erosion included
  double surface_triangles_bound = 0;

  // The coupled step: the smallest estimated stable step times its solver's beta, who sets it and how.
  double dt = 0;                        // s (infinite: no solver limits it)
  std::string dt_what;                  // e.g. "the sph_solver's acoustic step cfl h / c"
  std::string dt_key;                   // the scene key that sets it, e.g. "sph.particle_spacing"
  double steps = 0;                     // end_time / dt, at least
  double outputs = 0;                   // output times, end_time / output_interval + 1
  double memory_bytes = 0;              // every process together
  std::vector<double> structure_bytes;  // [structure]: its share of memory_bytes (elements, or rigid triangles)

  // The largest frame a solver of each role sends (its registration or a state), bytes, at most.
  double largest_message_bound = 0;

  [[nodiscard]] double total_fluid_particles() const;
  [[nodiscard]] double total_spheres() const;
  [[nodiscard]] double total_elements() const;
  [[nodiscard]] double total_surface_triangles() const;
};

[[nodiscard]] SceneEstimate estimate_scene(const Scene& scene);

// The largest frame the coupler accepts (ZMQ_MAXMSGSIZE), bytes: twice the estimate's bound plus 64 MiB.
[[nodiscard]] std::int64_t max_message_bytes(const SceneEstimate& estimate);

// Bytes of physical memory of this machine (0: unknown).
[[nodiscard]] double physical_memory_bytes();

}  // namespace sabo::scene
