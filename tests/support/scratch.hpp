#pragma once
// A folder of this test process's files, created on first use and removed when
// the test program ends: scratch("x.h5") is a path inside it.
#include <unistd.h>

#include <filesystem>
#include <string>

namespace sabo::testing {

std::filesystem::path scratch(const std::string& name);

}  // namespace sabo::testing
