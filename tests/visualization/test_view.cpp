// `wheelchair view --screenshot`: under Xvfb (window; falls back to offscreen rendering of the
// same scene when the window's framebuffer reads back blank) and without any display
// (offscreen). The frame must show every trajectory colour.
#include "VizTestUtil.h"

#include "libwheelchair/visualization/Scene3D.h"

namespace wheelchair::visualization {
namespace {

using testutil::countColour;

void expectTrajectoryColours(const std::string& png) {
  const auto im = testutil::loadPng(png);
  ASSERT_GT(im.getWidth(), 0u);
  auto rgb = [](Color c) { return testutil::Rgb{c.r, c.g, c.b}; };
  // Below the legend text (top 40 %) so the legend's coloured labels do not count.
  EXPECT_GT(countColour(im, rgb(variantColor("encoders")), 40, 0, 0.4, 1, 1), 50)
      << "encoders (blue)";
  EXPECT_GT(countColour(im, rgb(variantColor("encoders_gyro")), 40, 0, 0.4, 1, 1), 50)
      << "encoders+gyro (green)";
  EXPECT_GT(countColour(im, rgb(variantColor("baseline")), 40, 0, 0.4, 1, 1), 20)
      << "baseline (purple)";
  EXPECT_GT(countColour(im, rgb(variantColor("ekf")), 30, 0, 0.4, 1, 1), 50) << "EKF (black)";
  EXPECT_GT(countColour(im, rgb(variantColor("gt")), 40, 0, 0.4, 1, 1), 20) << "ground truth (red)";
}

TEST(View, ScreenshotUnderXvfb) {
  if (test::run("command -v xvfb-run").exit_code != 0) GTEST_SKIP() << "xvfb-run not installed";
  const std::string rawlog = testutil::SimulatedDrive::rawlog();
  test::TempDir dir;
  const std::string png = dir / "view.png";
  const auto r = test::run("timeout 120 xvfb-run -a -s '-screen 0 1600x1200x24' " +
                           std::string(WHEELCHAIR_CLI) + " view " + rawlog + " --screenshot " +
                           png + " --at 8");
  if (r.exit_code != 0 && r.out.find("GLX") != std::string::npos)
    GTEST_SKIP() << "no GLX under Xvfb here: " << r.out;
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::cout << r.out;
  expectTrajectoryColours(png);
}

TEST(View, ScreenshotWithoutDisplayRendersOffscreen) {
  const std::string rawlog = testutil::SimulatedDrive::rawlog();
  test::TempDir dir;
  const std::string png = dir / "view.png";
  const auto r = test::run("env -u DISPLAY " + std::string(WHEELCHAIR_CLI) + " view " + rawlog +
                           " --screenshot " + png + " --at 8");
  if (r.exit_code != 0 && r.out.find("offscreen OpenGL rendering failed") != std::string::npos)
    GTEST_SKIP() << "no EGL context here: " << r.out;
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("offscreen"), std::string::npos) << r.out;
  expectTrajectoryColours(png);
}

TEST(View, WithoutDisplayAndWithoutScreenshotFailsCleanly) {
  const std::string rawlog = testutil::SimulatedDrive::rawlog();
  const auto r = test::run("env -u DISPLAY " + std::string(WHEELCHAIR_CLI) + " view " + rawlog);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("no display"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace wheelchair::visualization
