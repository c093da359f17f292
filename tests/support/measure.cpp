#include "tests/support/measure.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <string>

namespace sabo::testing {
namespace {

std::string vec_text(const Vec3& v) {
  return fmt::format("({:.6g}, {:.6g}, {:.6g})", v.x(), v.y(), v.z());
}

void check(std::string_view what, const std::string& measured, const std::string& expected, double difference,
           double reference_size, double allowed) {
  const std::string relative =
      reference_size > 0 ? fmt::format(", {:.3g} %", 100.0 * difference / reference_size) : std::string();
  const std::string line = fmt::format("{}: measured {} expected {} (difference {:.3g}{}; tolerance {:.3g})", what,
                                       measured, expected, difference, relative, allowed);
  std::cout << line << "\n";
  EXPECT_LE(difference, allowed) << line;
}

void check_number(std::string_view what, double measured, double expected, double allowed) {
  check(what, fmt::format("{:.6g}", measured), fmt::format("{:.6g}", expected), std::abs(measured - expected),
        std::abs(expected), allowed);
}

}  // namespace

void expect_relative(std::string_view what, double measured, double expected, double tolerance) {
  check_number(what, measured, expected, tolerance * std::abs(expected));
}

void expect_absolute(std::string_view what, double measured, double expected, double tolerance) {
  check_number(what, measured, expected, tolerance);
}

void expect_scaled(std::string_view what, double measured, double expected, double tolerance) {
  check_number(what, measured, expected, tolerance * std::max(1.0, std::abs(expected)));
}

void expect_vec_absolute(std::string_view what, const Vec3& measured, const Vec3& expected, double tolerance) {
  check(what, vec_text(measured), vec_text(expected), (measured - expected).norm(), expected.norm(), tolerance);
}

void expect_vec_scaled(std::string_view what, const Vec3& measured, const Vec3& expected, double tolerance) {
  check(what, vec_text(measured), vec_text(expected), (measured - expected).norm(), expected.norm(),
        tolerance * std::max(1.0, expected.norm()));
}

}  // namespace sabo::testing
