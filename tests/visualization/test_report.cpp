// `wheelchair report`: every figure exists, is non-empty and has drawn pixels in its plot area;
// index.md has the metrics table and the configuration.
#include "VizTestUtil.h"

#include "libwheelchair/visualization/Report.h"

#include <filesystem>

namespace wheelchair::visualization {
namespace {

using testutil::countColour;
using testutil::countNonBackground;

TEST(Report, WritesEveryFigureWithContentAndTheIndex) {
  const std::string rawlog = testutil::SimulatedDrive::rawlog();
  test::TempDir dir;
  const std::string out = dir / "report";
  const auto r = test::cli("report " + rawlog + " -o " + out + " --at 6");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  for (const std::string f :
       {"fig5_trajectories.png", "fig6a_velocity.png", "fig6b_angular_velocity.png",
        "fig6c_motor_currents.png", "fig7_obstacle.png", "fig8_distance.png"}) {
    const std::string p = out + "/" + f;
    ASSERT_TRUE(std::filesystem::exists(p)) << p;
    EXPECT_GT(std::filesystem::file_size(p), 5000u) << p;
    const auto im = testutil::loadPng(p);
    EXPECT_GE(im.getWidth(), 800u);
    // The data area (inside the axes) is not empty: coloured curves are drawn there.
    const long drawn = countNonBackground(im, {255, 255, 255}, 0.15, 0.15, 0.7, 0.85);
    EXPECT_GT(drawn, 2000) << p;
    long coloured = 0;  // saturated pixels: data, not the grey grid or the black axes
    for (const auto& c : std::vector<testutil::Rgb>{{0, 60, 255},
                                                    {0, 170, 0},
                                                    {220, 20, 30},
                                                    {30, 80, 220},
                                                    {230, 0, 0},
                                                    {0, 190, 210},
                                                    {20, 160, 40}})
      coloured += countColour(im, c, 50, 0.1, 0.08, 0.95, 0.9);
    EXPECT_GT(coloured, 300) << p;
  }
  const std::string index = test::readFile(out + "/index.md");
  EXPECT_NE(index.find("| recording | variant |"), std::string::npos);
  EXPECT_NE(index.find("| ekf |"), std::string::npos);
  EXPECT_NE(index.find("| encoders_gyro |"), std::string::npos);
  EXPECT_NE(index.find("```ini"), std::string::npos);
  EXPECT_NE(index.find("[vehicle]"), std::string::npos);
  EXPECT_NE(index.find("fig7_obstacle.png"), std::string::npos);
}

TEST(Report, BadInputExitsWithOne) {
  test::TempDir dir;
  EXPECT_EQ(test::cli("report " + (dir / "nope.rawlog") + " -o " + (dir / "out")).exit_code, 1);
}

}  // namespace
}  // namespace wheelchair::visualization
