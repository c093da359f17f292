// Cell list against brute force on random points and boxes.
#include <gtest/gtest.h>

#include <algorithm>
#include <iostream>
#include <random>
#include <vector>

#include "libsabo/physics/cell_list.hpp"

namespace sabo::physics {
namespace {

double uniform(std::mt19937_64& random) {
  return static_cast<double>(random() >> 11) * 0x1.0p-53;
}

std::vector<Vec3> random_points(std::size_t count, std::uint64_t seed) {
  std::mt19937_64 random(seed);
  std::vector<Vec3> points;
  for (std::size_t i = 0; i < count; ++i) {
    // A dense cluster plus a sparse cloud, and a few far outliers.
    const double spread = i % 3 == 0 ? 5.0 : 1.0;
    points.emplace_back(spread * uniform(random), spread * uniform(random), 0.5 * spread * uniform(random));
  }
  points.emplace_back(1e6, -3e5, 42.0);
  points.emplace_back(-1e5, 0.5, 0.5);
  return points;
}

TEST(CellList, FindsExactlyTheBruteForceNeighbours) {
  const std::vector<Vec3> points = random_points(3000, 7);
  const double range = 0.08;  // interaction distance = cell size
  CellList cells;
  cells.build_points(points, range);
  std::cout << "items " << cells.item_count() << " occupied cells " << cells.occupied_cell_count() << "\n";
  EXPECT_EQ(cells.item_count(), points.size());
  EXPECT_EQ(cells.cell_size(), range);  // far outliers do not coarsen the grid
  EXPECT_LE(cells.occupied_cell_count(), points.size());

  std::size_t pairs_found = 0, pairs_expected = 0, candidates = 0;
  std::vector<std::uint32_t> found, expected, visited;
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    found.clear();
    visited.clear();
    cells.for_each_near(points[i], [&](std::uint32_t j) {
      visited.push_back(j);
      if (j != i && (points[j] - points[i]).norm() <= range) found.push_back(j);
    });
    expected.clear();
    for (std::uint32_t j = 0; j < points.size(); ++j) {
      if (j != i && (points[j] - points[i]).norm() <= range) expected.push_back(j);
    }
    std::sort(found.begin(), found.end());
    ASSERT_EQ(found, expected) << "point " << i;
    // Each point is binned once, so visited once.
    std::sort(visited.begin(), visited.end());
    ASSERT_TRUE(std::adjacent_find(visited.begin(), visited.end()) == visited.end());
    pairs_found += found.size();
    pairs_expected += expected.size();
    candidates += visited.size();
  }
  std::cout << "neighbour pairs: measured " << pairs_found << " expected (brute force) " << pairs_expected
            << "; candidates visited " << candidates << "\n";
  EXPECT_GT(pairs_expected, 1000U);  // the test exercises real neighbourhoods
}

TEST(CellList, SameInputSameVisitOrderAfterRebuild) {
  std::vector<Vec3> points = random_points(500, 11);
  CellList cells;
  auto order = [&](const CellList& list) {
    std::vector<std::uint32_t> sequence;
    for (const Vec3& p : points) list.for_each_near(p, [&](std::uint32_t j) { sequence.push_back(j); });
    return sequence;
  };
  cells.build_points(points, 0.1);
  const auto first = order(cells);
  // Rebuild with other content in between: buffers are reused, the result must not change.
  cells.build_points(random_points(2000, 12), 0.05);
  cells.build_points(points, 0.1);
  EXPECT_EQ(order(cells), first);
}

TEST(CellList, BoxesAreFoundByEveryPointInsideAndByOverlappingBoxes) {
  std::mt19937_64 random(3);
  std::vector<Aabb> boxes;
  for (int i = 0; i < 800; ++i) {
    const Vec3 corner(2 * uniform(random), 2 * uniform(random), uniform(random));
    const Vec3 size(0.3 * uniform(random), 0.3 * uniform(random), 0.05 * uniform(random));
    boxes.push_back(Aabb{corner, corner + size});
  }
  boxes.push_back(Aabb{});  // empty: left out
  CellList cells;
  cells.build_boxes(boxes, 0.1);
  EXPECT_EQ(cells.item_count(), boxes.size() - 1);
  std::vector<std::uint32_t> found, expected;
  std::size_t total = 0;
  for (int q = 0; q < 500; ++q) {
    const Vec3 p(2.2 * uniform(random), 2.2 * uniform(random), 1.1 * uniform(random));
    const Aabb query = Aabb{p, p}.inflated(0.07 * uniform(random));
    cells.candidates(query, found);
    // Candidates may include boxes that do not overlap; they must include all that do.
    expected.clear();
    for (std::uint32_t b = 0; b < boxes.size(); ++b) {
      if (boxes[b].overlaps(query)) expected.push_back(b);
    }
    for (std::uint32_t b : expected) ASSERT_TRUE(std::binary_search(found.begin(), found.end(), b)) << "box " << b;
    ASSERT_TRUE(std::adjacent_find(found.begin(), found.end()) == found.end());
    total += expected.size();
  }
  std::cout << "overlapping boxes found: " << total << " (all, as brute force)\n";
  EXPECT_GT(total, 200U);
}

TEST(CellList, EmptyAndNonFiniteInputs) {
  CellList cells;
  cells.build_points({}, 1.0);
  int visits = 0;
  cells.for_each_near(Vec3::Zero(), [&](std::uint32_t) { ++visits; });
  EXPECT_EQ(visits, 0);
  const std::vector<Vec3> points{Vec3(0, 0, 0), Vec3::Constant(std::numeric_limits<double>::quiet_NaN()),
                                 Vec3(0.5, 0, 0)};
  cells.build_points(points, 1.0);
  EXPECT_EQ(cells.item_count(), 2U);
  std::vector<std::uint32_t> near;
  cells.for_each_near(Vec3(0.1, 0, 0), [&](std::uint32_t j) { near.push_back(j); });
  EXPECT_EQ(near, (std::vector<std::uint32_t>{0, 2}));
}

}  // namespace
}  // namespace sabo::physics
