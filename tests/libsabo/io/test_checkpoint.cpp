// Checkpoint files: written whole or not at all, the newest kept, and refused when they are of another
// process, scene or format.
#include <gtest/gtest.h>

#include <fstream>

#include "libsabo/core/error.hpp"
#include "libsabo/io/checkpoint.hpp"
#include "tests/support/scratch.hpp"

using sabo::FileError;
using sabo::io::CheckpointStore;
namespace hdf5 = sabo::io::hdf5;

namespace {

void write_values(CheckpointStore& store, std::uint64_t step, double value) {
  store.write(step, 1e-3 * static_cast<double>(step), [&](hdf5::File& file) {
    auto dataset = file.create_dataset<double>("values", 4);
    const std::vector<double> values{value, value + 1, value + 2};
    dataset.append(std::span<const double>(values));
  });
}

template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const FileError& error) {
    return error.what();
  }
  return "";
}

}  // namespace

TEST(Checkpoint, TextDigestIsFnv1a64) {
  EXPECT_EQ(sabo::io::text_digest(""), "cbf29ce484222325");
  EXPECT_EQ(sabo::io::text_digest("a"), "af63dc4c8601ec8c");
  EXPECT_NE(sabo::io::text_digest("density = 2650"), sabo::io::text_digest("density = 2651"));
}

TEST(Checkpoint, WritesReadsAndKeepsTheNewest) {
  const auto folder = sabo::testing::scratch("keep");
  CheckpointStore store(folder, "dem_solver", "0123456789abcdef", 2);
  EXPECT_TRUE(store.list().empty());
  EXPECT_FALSE(store.latest().has_value());
  for (std::uint64_t step : {100u, 200u, 300u}) write_values(store, step, static_cast<double>(step));
  const auto list = store.list();
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].step, 200u);
  EXPECT_EQ(list[1].step, 300u);
  EXPECT_FALSE(std::filesystem::exists(store.path_of(100)));
  EXPECT_EQ(store.latest()->step, 300u);
  EXPECT_EQ(store.latest(299)->step, 200u);
  EXPECT_FALSE(store.latest(199).has_value());

  const hdf5::File file = store.open(store.at(200));
  EXPECT_DOUBLE_EQ(sabo::io::checkpoint_time(file), 0.2);
  const auto values = file.dataset("values").read_all<double>();
  ASSERT_EQ(values.size(), 3u);
  EXPECT_EQ(values[2], 202.0);
  const std::string missing = error_of([&] { (void)store.at(150); });
  std::cout << missing << "\n";
  EXPECT_NE(missing.find("no checkpoint of dem_solver at step 150 (there are: 200, 300)"), std::string::npos);
}

TEST(Checkpoint, AnUnfinishedWriteLeavesThePreviousCheckpoints) {
  const auto folder = sabo::testing::scratch("unfinished");
  CheckpointStore store(folder, "fem_solver", "d", 2);
  write_values(store, 10, 1);
  EXPECT_THROW(store.write(20, 0.02, [](hdf5::File&) { throw FileError("disk full"); }), FileError);
  ASSERT_EQ(store.list().size(), 1u);
  EXPECT_EQ(store.latest()->step, 10u);
  // The partial file of a killed writer is not a checkpoint.
  std::ofstream(folder / "fem_solver_0000000030.h5.partial") << "half";
  EXPECT_EQ(store.latest()->step, 10u);
}

TEST(Checkpoint, RefusesAnotherRoleSceneFormatOrStep) {
  const auto folder = sabo::testing::scratch("refuse");
  CheckpointStore dem(folder, "dem_solver", "aaaa", 2);
  write_values(dem, 5, 1);
  const auto info = dem.at(5);

  CheckpointStore fem(folder, "fem_solver", "aaaa", 2);
  std::string message = error_of([&] { (void)fem.open(info); });
  std::cout << message << "\n";
  EXPECT_NE(message.find("a checkpoint of dem_solver, not of fem_solver"), std::string::npos);

  CheckpointStore other_scene(folder, "dem_solver", "bbbb", 2);
  message = error_of([&] { (void)other_scene.open(info); });
  std::cout << message << "\n";
  EXPECT_NE(message.find("a checkpoint of another scene (scene digest aaaa, this scene's bbbb)"), std::string::npos);

  std::filesystem::copy_file(info.path, dem.path_of(6));
  message = error_of([&] { (void)dem.open(dem.at(6)); });
  std::cout << message << "\n";
  EXPECT_NE(message.find("holds step 5, its name says 6"), std::string::npos);

  {
    hdf5::File foreign = hdf5::File::create(dem.path_of(7));
    foreign.set_attribute("format", "something else");
  }
  message = error_of([&] { (void)dem.open(dem.at(7)); });
  std::cout << message << "\n";
  EXPECT_NE(message.find("not a Sabo checkpoint"), std::string::npos);
}
