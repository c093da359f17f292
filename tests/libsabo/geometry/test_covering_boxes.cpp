// geometry::covering_boxes: the interest regions of docs/design.md, "Only the interface travels".
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <numbers>
#include <random>
#include <vector>

#include "libsabo/geometry/covering_boxes.hpp"

namespace sabo::geometry {
namespace {

bool covered(const Aabb& piece, const std::vector<Aabb>& boxes) {
  for (const Aabb& box : boxes) {
    if (box.contains(piece.min) && box.contains(piece.max)) return true;
  }
  return false;
}

void expect_same_boxes(const std::vector<Aabb>& a, const std::vector<Aabb>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].min, b[k].min) << "box " << k;
    EXPECT_EQ(a[k].max, b[k].max) << "box " << k;
  }
}

// Pieces 0.5 m long along a 30° ramp 40 m long and 4 m wide (a sloping channel floor).
std::vector<Aabb> ramp() {
  std::vector<Aabb> pieces;
  const double slope = std::tan(std::numbers::pi / 6);
  for (int i = 0; i < 80; ++i) {
    for (int j = 0; j < 8; ++j) {
      const double x = 0.5 * i, y = 0.5 * j;
      pieces.push_back(Aabb{Vec3(x, y, slope * x), Vec3(x + 0.5, y + 0.5, slope * (x + 0.5))});
    }
  }
  return pieces;
}

TEST(CoveringBoxes, EveryPieceIsInsideABoxAndTheCountIsBounded) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> position(-50.0, 50.0), size(0.0, 3.0);
  std::vector<Aabb> pieces;
  for (int k = 0; k < 2000; ++k) {
    const Vec3 lo(position(random), position(random), 0.1 * position(random));
    pieces.push_back(Aabb{lo, lo + Vec3(size(random), size(random), size(random))});
  }
  pieces.push_back(Aabb{});  // empty pieces are ignored
  for (const std::size_t limit : {1u, 3u, 16u, 64u}) {
    const std::vector<Aabb> boxes = covering_boxes(pieces, limit);
    std::cout << "limit " << limit << ": " << boxes.size() << " boxes\n";
    EXPECT_GE(boxes.size(), 1u);
    EXPECT_LE(boxes.size(), limit);
    for (std::size_t k = 0; k + 1 < pieces.size(); ++k) ASSERT_TRUE(covered(pieces[k], boxes)) << "piece " << k;
  }
  expect_same_boxes(covering_boxes(pieces, 16), covering_boxes(pieces, 16));
  EXPECT_TRUE(covering_boxes(std::vector<Aabb>{}, 16).empty());
  EXPECT_TRUE(covering_boxes(std::vector<Aabb>{Aabb{}}, 16).empty());
}

TEST(CoveringBoxes, TilesHugASlopingFloor) {
  const std::vector<Aabb> pieces = ramp();
  const std::vector<Aabb> one = covering_boxes(pieces, 1);
  const std::vector<Aabb> tiles = covering_boxes(pieces, kMaxInterestBoxes);
  ASSERT_EQ(one.size(), 1u);
  for (const Aabb& piece : pieces) ASSERT_TRUE(covered(piece, tiles));
  // The ramp's own volume is nil; a single box holds 40 x 4 x 23.1 m^3. Tiles along the
  // ramp, each 40/n long, hold 1/n of it with n tiles along x.
  const double single = total_volume(one), tiled = total_volume(tiles);
  std::cout << tiles.size() << " tiles hold " << tiled << " m^3 against " << single << " m^3 for one box (ratio "
            << tiled / single << ", expected <= 1/8)\n";
  EXPECT_LE(tiled, single / 8.0);
}

TEST(CoveringBoxes, PointsAreCoveredLikeZeroSizePieces) {
  std::vector<Vec3> points;
  std::vector<Aabb> as_pieces;
  for (int k = 0; k < 500; ++k) {
    const Vec3 p(0.1 * k, std::sin(0.05 * k), 0.002 * k * k);
    points.push_back(p);
    as_pieces.push_back(Aabb{p, p});
  }
  const std::vector<Aabb> from_points = covering_boxes(points, 16);
  const std::vector<Aabb> from_pieces = covering_boxes(as_pieces, 16);
  expect_same_boxes(from_points, from_pieces);
  for (const Vec3& p : points) ASSERT_TRUE(covered(Aabb{p, p}, from_points));
  const std::vector<Aabb> single = covering_boxes(std::vector<Vec3>{Vec3(1, 2, 3)}, 16);
  ASSERT_EQ(single.size(), 1u);
  EXPECT_EQ(single[0].min, Vec3(1, 2, 3));
}

}  // namespace
}  // namespace sabo::geometry
