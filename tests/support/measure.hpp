#pragma once
// Checks of a measured figure against its reference that print both, one line each, in the same form
// for every test ("what: measured M expected E (difference D, R %; tolerance T)"), so that a test log
// reads as a table of measured beside expected. Each records a GoogleTest failure when out of tolerance.
#include <string_view>

#include "libsabo/core/types.hpp"

namespace sabo::testing {

// |measured - expected| <= tolerance * |expected| (tolerance relative, e.g. 0.01 for 1 %).
void expect_relative(std::string_view what, double measured, double expected, double tolerance);
// |measured - expected| <= tolerance (absolute, in the unit of the figure).
void expect_absolute(std::string_view what, double measured, double expected, double tolerance);
// |measured - expected| <= tolerance * max(1, |expected|): relative for large figures, absolute near 0.
void expect_scaled(std::string_view what, double measured, double expected, double tolerance);
// |measured - expected| <= tolerance, and the same scaled by max(1, |expected|), for vectors.
void expect_vec_absolute(std::string_view what, const Vec3& measured, const Vec3& expected, double tolerance);
void expect_vec_scaled(std::string_view what, const Vec3& measured, const Vec3& expected, double tolerance);

}  // namespace sabo::testing
