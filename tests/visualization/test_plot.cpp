// The headless plotting helper (libwheelchair/visualization/Plot.h).
#include "VizTestUtil.h"

#include "libwheelchair/visualization/Plot.h"

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

}  // namespace
}  // namespace wheelchair::visualization
