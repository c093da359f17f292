// sabo_traffic: looks after the traffic.h5 of a run folder (docs/traffic.md).
//   sabo_traffic repair FILE   make a recording whose writer was killed open with ordinary tools
// A killed coupler leaves the file consistent but with HDF5's "open for writing" flags set, which h5ls,
// h5dump and a plain h5py.File(path) refuse; `repair` clears them (and extends the end of allocation over
// the data, which plain `h5clear -s` would truncate). It prints what it did, one line. Run it only when no
// process writes the file (`./sabo status` and the supervisor check that). Exit status: 0 the file opens
// (now or already), 1 it cannot be repaired (message on stderr), 2 bad command line.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <string>

#include "libsabo/core/error.hpp"
#include "libsabo/io/hdf5.hpp"

namespace {

bool opens_as_it_is(const std::filesystem::path& file) {
  try {
    (void)sabo::io::hdf5::File::open(file, sabo::io::hdf5::Access::read_only);
    return true;
  } catch (const sabo::Error&) {
    (void)sabo::io::hdf5::take_error_stack();
    return false;
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Looks after the traffic.h5 recording of a Sabo run folder (docs/traffic.md)."};
  app.require_subcommand(1);
  std::string path;
  CLI::App* repair = app.add_subcommand(
      "repair", "Clear the 'open for writing' flags a killed writer left, so that ordinary tools open the file.");
  repair->add_option("file", path, "traffic.h5 of a run folder")->required();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    const int code = app.exit(error);
    return code == 0 ? 0 : 2;
  }
  const std::filesystem::path file(path);
  if (!std::filesystem::is_regular_file(file)) {
    std::cerr << path << ": no such file\n";
    return 1;
  }
  if (opens_as_it_is(file)) {
    std::cout << path << ": opens as it is; nothing to repair\n";
    return 0;
  }
  try {
    sabo::io::hdf5::clear_status_flags(file);
  } catch (const sabo::Error& error) {
    std::cerr << path << ": " << error.what() << "\n";
    return 1;
  }
  if (!opens_as_it_is(file)) {
    std::cerr << path << ": the status flags were cleared but the file still does not open\n";
    return 1;
  }
  std::cout << path << ": repaired: cleared the flags a killed writer left; it now opens with any HDF5 tool\n";
  return 0;
}
