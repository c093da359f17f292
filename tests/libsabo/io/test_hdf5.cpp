#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <functional>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/io/hdf5.hpp"
#include "tests/support/scratch.hpp"

namespace fs = std::filesystem;
using namespace sabo::io;

namespace {

using sabo::testing::scratch;

std::string message_of(const std::function<void()>& action) {
  try {
    action();
  } catch (const sabo::Error& error) {
    return error.what();
  }
  return "(no exception)";
}

}  // namespace

TEST(Hdf5, DatasetsGrowAndReadBack) {
  const fs::path path = scratch("datasets.h5");
  {
    auto file = hdf5::File::create(path);
    auto group = file.create_group("run");
    auto doubles = group.create_dataset<double>("x", 4);
    auto u64 = group.create_dataset<std::uint64_t>("id", 3);
    auto u32 = group.create_dataset<std::uint32_t>("index", 2);
    auto u8 = group.create_dataset<std::uint8_t>("bytes", 16);
    const std::vector<double> first{1.5, -2.25, 3e300};
    const std::vector<double> second{4.0, 5.0, 6.0, 7.0, 8.0};
    doubles.append<double>(first);
    doubles.append<double>(std::vector<double>{});  // no-op
    doubles.append<double>(second);
    u64.append<std::uint64_t>(std::vector<std::uint64_t>{0, UINT64_MAX, 42});
    u32.append<std::uint32_t>(std::vector<std::uint32_t>{7, 8, 9});
    u8.append<std::uint8_t>(std::vector<std::uint8_t>{0, 255});
    EXPECT_EQ(doubles.size(), 8u);
    EXPECT_EQ(doubles.path(), "/run/x");
    file.flush();
  }
  auto file = hdf5::File::open(path);
  auto group = file.group("run");
  EXPECT_EQ(group.children(), (std::vector<std::string>{"bytes", "id", "index", "x"}));
  EXPECT_TRUE(group.exists("x"));
  EXPECT_FALSE(group.exists("y"));
  auto x = group.dataset("x");
  EXPECT_EQ(x.type(), hdf5::Type::float64);
  EXPECT_EQ(x.read_all<double>(), (std::vector<double>{1.5, -2.25, 3e300, 4.0, 5.0, 6.0, 7.0, 8.0}));
  std::vector<double> middle(3);
  x.read<double>(2, middle);
  EXPECT_EQ(middle, (std::vector<double>{3e300, 4.0, 5.0}));
  EXPECT_EQ(group.dataset("id").read_all<std::uint64_t>(), (std::vector<std::uint64_t>{0, UINT64_MAX, 42}));
  EXPECT_EQ(group.dataset("index").read_all<std::uint32_t>(), (std::vector<std::uint32_t>{7, 8, 9}));
  EXPECT_EQ(group.dataset("bytes").read_all<std::uint8_t>(), (std::vector<std::uint8_t>{0, 255}));

  // Past the end, and the wrong element type.
  std::vector<double> too_many(4);
  EXPECT_THROW(x.read<double>(6, too_many), sabo::FileError);
  const std::string wrong_type = message_of([&] { (void)x.read_all<std::uint32_t>(); });
  EXPECT_NE(wrong_type.find("holds float64 but the program asked for uint32"), std::string::npos) << wrong_type;
  EXPECT_NE(wrong_type.find("/run/x"), std::string::npos) << wrong_type;
}

TEST(Hdf5, Attributes) {
  const fs::path path = scratch("attributes.h5");
  {
    auto file = hdf5::File::create(path);
    file.set_attribute("name", "débris flow");
    file.set_attribute("gravity", -9.81);
    file.set_attribute("steps", std::int64_t{1} << 40);
    file.set_attribute("steps", 12);  // replaces
    auto data = file.create_dataset<double>("data", 8);
    data.set_attribute("unit", std::string("m"));
  }
  auto file = hdf5::File::open(path);
  EXPECT_EQ(file.string_attribute("name"), "débris flow");
  EXPECT_EQ(file.double_attribute("gravity"), -9.81);
  EXPECT_EQ(file.int_attribute("steps"), 12);
  EXPECT_TRUE(file.has_attribute("name"));
  EXPECT_FALSE(file.has_attribute("missing"));
  EXPECT_EQ(file.dataset("data").string_attribute("unit"), "m");
  EXPECT_THROW((void)file.string_attribute("gravity"), sabo::LibraryError);
  const std::string missing = message_of([&] { (void)file.double_attribute("missing"); });
  EXPECT_NE(missing.find("could not read attribute 'missing'"), std::string::npos) << missing;
  EXPECT_NE(missing.find("HDF5 error stack"), std::string::npos) << missing;
}

TEST(Hdf5, ErrorsCarryTheLibraryStack) {
  const fs::path not_hdf5 = scratch("not_hdf5.h5");
  std::ofstream(not_hdf5) << "this is not an HDF5 file\n";
  const std::string text = message_of([&] { (void)hdf5::File::open(not_hdf5); });
  std::cout << text << "\n";
  EXPECT_NE(text.find("could not open file '" + not_hdf5.string() + "' for reading"), std::string::npos);
  EXPECT_NE(text.find("HDF5 error stack"), std::string::npos);
  EXPECT_NE(text.find("H5Fopen"), std::string::npos);  // the stack names the failing API call
  EXPECT_THROW((void)hdf5::File::open(scratch("does_not_exist.h5")), sabo::FileError);

  auto file = hdf5::File::create(scratch("errors.h5"));
  file.create_group("g");
  const std::string twice = message_of([&] { file.create_group("g"); });
  EXPECT_NE(twice.find("could not create group 'g'"), std::string::npos) << twice;
  EXPECT_THROW((void)file.dataset("nothing"), sabo::LibraryError);
}

TEST(Hdf5, SwmrFileReadsWhileWritten) {
  const fs::path path = scratch("swmr.h5");
  auto writer = hdf5::File::create(path, /*swmr=*/true);
  auto values = writer.create_dataset<double>("values", 4);
  writer.start_swmr_write();
  values.append<double>(std::vector<double>{1, 2, 3});
  values.flush();

  auto reader = hdf5::File::open(path, hdf5::Access::swmr_read);
  auto seen = reader.dataset("values");
  EXPECT_EQ(seen.read_all<double>(), (std::vector<double>{1, 2, 3}));
  values.append<double>(std::vector<double>{4, 5});
  values.flush();
  seen.refresh();
  EXPECT_EQ(seen.read_all<double>(), (std::vector<double>{1, 2, 3, 4, 5}));
}
