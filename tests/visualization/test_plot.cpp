// The headless plotting helper (libwheelchair/visualization/Plot.h).
#include "VizTestUtil.h"

#include "libwheelchair/visualization/Plot.h"

#include <mrpt/img/CImage.h>

#include <algorithm>
#include <cmath>

namespace wheelchair::visualization {
namespace {

using testutil::countColour;

TEST(NiceTicks, StepsOf125) {
  EXPECT_EQ(niceTicks(0, 10, 5), (std::vector<double>{0, 2, 4, 6, 8, 10}));
  const auto t = niceTicks(-0.33, 0.71, 5);
  ASSERT_GE(t.size(), 4u);
  EXPECT_NEAR(t[1] - t[0], 0.2, 1e-12);
  EXPECT_GE(t.front(), -0.33);
  EXPECT_LE(t.back(), 0.71);
  EXPECT_TRUE(niceTicks(1, 1).empty());
}

TEST(CovarianceEllipse, AxesAreTheSigmas) {
  // sigma_x = 0.1, sigma_y = 0.4, no correlation: extreme points at +-0.1 / +-0.4.
  const auto e = covarianceEllipse(1, 2, 0.01, 0, 0.16, 1.0, 360);
  double xmax = 0, ymax = 0;
  for (const auto& [x, y] : e)
    xmax = std::max(xmax, std::fabs(x - 1)), ymax = std::max(ymax, std::fabs(y - 2));
  EXPECT_NEAR(xmax, 0.1, 1e-3);
  EXPECT_NEAR(ymax, 0.4, 1e-3);
}

TEST(Plot, DrawsSeriesLegendAndText) {
  test::TempDir dir;
  Plot p;
  p.title = "test";
  p.xlabel = "time (s)";
  p.ylabel = "v (m/s)";
  Series s{"sine", {}, {}, Color{0, 0, 255}, LineStyle::Solid, 3.0};
  for (int i = 0; i <= 200; ++i) s.x.push_back(i * 0.05), s.y.push_back(std::sin(i * 0.05));
  p.series.push_back(s);
  p.series.push_back({"points",
                      {1, 2, 3},
                      {0.5, -0.5, 0},
                      Color{255, 0, 0},
                      LineStyle::None,
                      2,
                      Marker::Square,
                      10});
  const std::string f = dir / "p.png";
  p.save(f, 600, 400);
  const auto im = testutil::loadPng(f);
  EXPECT_EQ(im.getWidth(), 600u);
  EXPECT_EQ(im.getHeight(), 400u);
  EXPECT_GT(countColour(im, {0, 0, 255}, 40), 500);  // the sine (and its legend sample)
  EXPECT_GT(countColour(im, {255, 0, 0}, 40), 100);  // the squares
  EXPECT_GT(countColour(im, {0, 0, 0}, 60), 500);    // axes, ticks, text
}

// A line series above Plot::kDecimateAbove points is thinned per pixel column before it is
// drawn (Plot.h): the picture must be the one the same points give drawn one by one (here in
// chunks below the threshold, each drawn point for point, overlapping by one point).
TEST(Plot, LongSeriesIsDrawnAsItsPoints) {
  const std::size_t n = 5 * Plot::kDecimateAbove;
  std::vector<double> x(n), y(n);
  for (std::size_t i = 0; i < n; ++i) {  // a slow sine with fast "noise": a dense band
    x[i] = 0.01 * static_cast<double>(i);
    y[i] = std::sin(x[i] / 100.0) + 0.3 * std::sin(1.7 * static_cast<double>(i)) +
           (i % 9973 == 0 ? 1.5 : 0.0);  // rare spikes must survive
  }
  auto plot = [&]() {
    Plot p;
    p.x_range = std::make_pair(-10.0, 1010.0);
    p.y_range = std::make_pair(-2.0, 3.0);
    return p;
  };
  Plot whole = plot(), chunks = plot();
  whole.series.push_back({"", x, y, Color{0, 0, 255}, LineStyle::Solid, 1.2});
  const std::size_t m = Plot::kDecimateAbove;
  for (std::size_t a = 0; a < n; a += m - 1) {
    const std::size_t b = std::min(n, a + m);
    chunks.series.push_back({"",
                             {x.begin() + a, x.begin() + b},
                             {y.begin() + a, y.begin() + b},
                             Color{0, 0, 255},
                             LineStyle::Solid,
                             1.2});
    if (b == n) break;
  }
  const auto A = whole.render(800, 500).toImage(), B = chunks.render(800, 500).toImage();
  long differ = 0, drawn = 0;
  for (int r = 0; r < 500; ++r) {
    const uint8_t *pa = A.ptrLine<uint8_t>(r), *pb = B.ptrLine<uint8_t>(r);
    for (int c = 0; c < 3 * 800; ++c) {
      differ += std::abs(int(pa[c]) - int(pb[c])) > 64;
      drawn += pb[c] < 128;
    }
  }
  EXPECT_GT(drawn, 20000);         // the band and the spikes are drawn
  EXPECT_LT(differ, drawn / 100);  // and look the same (antialiased edges may differ)
}

// Paths (Fig. 5) keep every point up to the threshold; above it, the points drawn are those at
// least 1/4000 of the extent apart, with the first and the last.
TEST(Plot, PathPointsToDrawAreWithinACellOfEveryPoint) {
  auto spiral = [](std::size_t n) {
    std::vector<double> x(n), y(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double t = 1e-4 * static_cast<double>(i);
      x[i] = t * std::cos(t), y[i] = t * std::sin(t);
    }
    return std::make_pair(x, y);
  };
  const auto [xs, ys] = spiral(Plot::kDecimateAbove);
  EXPECT_EQ(
      pathPointsToDraw(
          xs.size(), [&](std::size_t i) { return xs[i]; }, [&](std::size_t i) { return ys[i]; })
          .size(),
      xs.size());
  const auto [x, y] = spiral(10 * Plot::kDecimateAbove);
  const auto keep = pathPointsToDraw(
      x.size(), [&](std::size_t i) { return x[i]; }, [&](std::size_t i) { return y[i]; });
  ASSERT_GE(keep.size(), 2u);
  EXPECT_LT(keep.size(), x.size() / 2);
  EXPECT_EQ(keep.front(), 0u);
  EXPECT_EQ(keep.back(), x.size() - 1);
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (std::size_t i = 0; i < x.size(); ++i)
    x0 = std::min(x0, x[i]), x1 = std::max(x1, x[i]), y0 = std::min(y0, y[i]),
    y1 = std::max(y1, y[i]);
  const double cell = std::max(x1 - x0, y1 - y0) / 4000.0;
  std::size_t k = 0, far = 0;  // every point is within a cell of the last point kept before it
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (k + 1 < keep.size() && keep[k + 1] == i) ++k;
    far += std::fabs(x[i] - x[keep[k]]) >= cell || std::fabs(y[i] - y[keep[k]]) >= cell;
  }
  EXPECT_EQ(far, 0u);
}

}  // namespace
}  // namespace wheelchair::visualization
