// Shared by the visualization tests: one simulated drive per test binary, PNG pixel helpers.
#pragma once

#include "../common/TestUtil.h"

#include <mrpt/img/CImage.h>

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <string>

namespace wheelchair::visualization::testutil {

/// A simulated three_task drive (shortened) with its truth JSON, generated once.
class SimulatedDrive : public ::testing::Environment {
 public:
  static const std::string& rawlog() {
    static std::unique_ptr<test::TempDir> dir;
    static std::string path;
    if (path.empty()) {
      dir = std::make_unique<test::TempDir>();
      path = *dir / "drive.rawlog";
      const auto r = test::cli(
          fmt::format("simulate --scenario three_task --seed 1 --duration 20 -o {}", path));
      if (r.exit_code != 0) ADD_FAILURE() << r.out;
    }
    return path;
  }
};

struct Rgb {
  int r, g, b;
};

/// Pixels within `tol` (per channel) of `c` inside the rectangle given as fractions of the size.
inline long countColour(const mrpt::img::CImage& im, Rgb c, int tol, double fx0 = 0, double fy0 = 0,
                        double fx1 = 1, double fy1 = 1) {
  long n = 0;
  const int w = static_cast<int>(im.getWidth()), h = static_cast<int>(im.getHeight());
  for (int y = static_cast<int>(fy0 * h); y < static_cast<int>(fy1 * h); ++y) {
    const uint8_t* row = im.ptrLine<uint8_t>(y);
    for (int x = static_cast<int>(fx0 * w); x < static_cast<int>(fx1 * w); ++x) {
      const int b = row[3 * x], g = row[3 * x + 1], r = row[3 * x + 2];  // BGR in memory
      if (std::abs(r - c.r) <= tol && std::abs(g - c.g) <= tol && std::abs(b - c.b) <= tol) ++n;
    }
  }
  return n;
}

/// Pixels that differ from the background colour (taken at the centre of the top-left corner
/// region... passed explicitly) inside the rectangle.
inline long countNonBackground(const mrpt::img::CImage& im, Rgb bg, double fx0, double fy0,
                               double fx1, double fy1) {
  const long all = static_cast<long>((fx1 - fx0) * im.getWidth()) *
                   static_cast<long>((fy1 - fy0) * im.getHeight());
  return all - countColour(im, bg, 3, fx0, fy0, fx1, fy1);
}

inline mrpt::img::CImage loadPng(const std::string& path) {
  mrpt::img::CImage im;
  EXPECT_TRUE(im.loadFromFile(path, 1)) << path;
  return im;
}

}  // namespace wheelchair::visualization::testutil
