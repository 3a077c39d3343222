// `wheelchair report`: every figure exists, is non-empty and has drawn pixels in its plot area;
// index.md has the metrics table and the configuration.
#include "VizTestUtil.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/visualization/DriveData.h"
#include "libwheelchair/visualization/Plot.h"
#include "libwheelchair/visualization/Report.h"

#include <cmath>
#include <filesystem>
#include <limits>
#include <tuple>

namespace wheelchair::visualization {
namespace {

using testutil::countColour;
using testutil::countNonBackground;

/// `b`'s metrics rows are `a`'s: variant, error, estimate count and ATE (NaN as NaN).
void expectSameMetricRows(const DriveData& b, const DriveData& a) {
  ASSERT_EQ(b.metrics.rows.size(), a.metrics.rows.size());
  for (std::size_t i = 0; i < a.metrics.rows.size(); ++i) {
    const auto &ra = a.metrics.rows[i], &rb = b.metrics.rows[i];
    EXPECT_EQ(rb.variant, ra.variant);
    EXPECT_EQ(rb.error, ra.error);
    EXPECT_EQ(rb.n_estimates, ra.n_estimates);
    const double x = ra.metrics.ate_rmse_m, y = rb.metrics.ate_rmse_m;
    EXPECT_TRUE(x == y || (std::isnan(x) && std::isnan(y))) << ra.variant;
  }
}

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

// `report` loads lean (DriveLoadOptions::keep_estimates false: the filters stream into the
// trace, the recording keeps only its sonar): what the figures draw must be what the full load
// (`view`, the diagnosis figures) gives, estimate for estimate.
TEST(Report, LeanLoadKeepsWhatTheFiguresDraw) {
  const std::string rawlog = testutil::SimulatedDrive::rawlog();
  const config::WheelchairConfig cfg;
  const evaluation::MetricOptions mo;
  const DriveData full = loadDrive(rawlog, cfg, mo);
  DriveLoadOptions lo;
  lo.keep_estimates = false;
  const DriveData lean = loadDrive(io::readRawlog(rawlog), rawlog, cfg, mo, "", lo);
  ASSERT_GT(full.ekf_trace.size(), 100u);
  ASSERT_EQ(lean.ekf_trace.size(), full.ekf_trace.size());
  for (std::size_t i = 0; i < full.ekf_trace.size(); ++i) {
    const auto &a = full.ekf_trace[i], &b = lean.ekf_trace[i];
    ASSERT_EQ(a.t_s, b.t_s);
    ASSERT_EQ(a.v_m_s, b.v_m_s);
    ASSERT_EQ(a.omega_rad_s, b.omega_rad_s);
    ASSERT_EQ(a.obstacle, b.obstacle);
    ASSERT_EQ(a.range_m, b.range_m);
    ASSERT_EQ(a.range_sd_m, b.range_sd_m);
  }
  EXPECT_TRUE(full.est.ekf.estimates.size() > 2 && lean.est.ekf.estimates.size() <= 2);
  EXPECT_EQ(lean.rec.imu.size(), 0u);  // only the sonar is kept
  EXPECT_EQ(lean.rec.sonar.size(), full.rec.sonar.size());
  EXPECT_EQ(lean.counts.imu, full.rec.imu.size());
  EXPECT_EQ(lean.gyro.size(), full.rec.imu.size());
  EXPECT_EQ(lean.t0_s, full.t0_s);
  EXPECT_EQ(lean.t1_s, full.t1_s);
  // Fig. 7's estimate: the one at the default time, and at `--at`.
  const double t_at = defaultObstacleTime(full);
  EXPECT_EQ(defaultObstacleTime(lean), t_at);
  ASSERT_NE(lean.ekfAt(t_at), nullptr);
  EXPECT_EQ(lean.ekfAt(t_at)->t_s, full.ekfAt(t_at)->t_s);
  EXPECT_EQ(lean.ekfAt(t_at)->P, full.ekfAt(t_at)->P);
  lo.snapshot_since_start_s = 6;
  const DriveData at6 = loadDrive(io::readRawlog(rawlog), rawlog, cfg, mo, "", lo);
  EXPECT_EQ(at6.ekfAt(at6.t0_s + 6)->x, full.ekfAt(full.t0_s + 6)->x);
  // Same trajectories (a 20 s drive is below the drawing threshold) and metrics.
  ASSERT_EQ(lean.trajectories.size(), full.trajectories.size());
  for (const auto& [v, t] : full.trajectories) {
    ASSERT_EQ(lean.trajectories.at(v).size(), t.size()) << v;
    EXPECT_EQ(lean.trajectories.at(v).back().x_m, t.back().x_m) << v;
  }
  expectSameMetricRows(lean, full);
  for (int s = 0; s < estimation::kNumSensors; ++s)
    EXPECT_EQ(lean.est.ekf.sensors[s].used, full.est.ekf.sensors[s].used);
}

// `report` reads the rawlog as a stream (loadDriveStreamed: the recording is never loaded, the
// variants are scored one by one as they run): the same DriveData as the loaded lean path, bit
// for bit, with and without `--at`.
TEST(Report, StreamedLoadEqualsTheLoadedOne) {
  const std::string rawlog = testutil::SimulatedDrive::rawlog();
  const config::WheelchairConfig cfg;
  const evaluation::MetricOptions mo;
  for (const double at : {std::numeric_limits<double>::quiet_NaN(), 6.0}) {
    DriveLoadOptions lo;
    lo.keep_estimates = false;
    lo.snapshot_since_start_s = at;
    const DriveData a = loadDrive(io::readRawlog(rawlog), rawlog, cfg, mo, "", lo);
    const DriveData b = loadDriveStreamed(rawlog, io::scanRawlog(rawlog), cfg, mo, "", at);
    ASSERT_GT(a.ekf_trace.size(), 100u);
    ASSERT_EQ(b.ekf_trace.size(), a.ekf_trace.size());
    for (std::size_t i = 0; i < a.ekf_trace.size(); ++i) {
      ASSERT_EQ(a.ekf_trace[i].t_s, b.ekf_trace[i].t_s);
      ASSERT_EQ(a.ekf_trace[i].omega_rad_s, b.ekf_trace[i].omega_rad_s);
      ASSERT_EQ(a.ekf_trace[i].range_sd_m, b.ekf_trace[i].range_sd_m);
    }
    ASSERT_EQ(b.gyro.size(), a.gyro.size());
    EXPECT_EQ(b.gyro.back().gyro_z_rad_s, a.gyro.back().gyro_z_rad_s);
    ASSERT_EQ(b.currents.size(), a.currents.size());
    EXPECT_EQ(b.currents.back().current_left_A, a.currents.back().current_left_A);
    ASSERT_EQ(b.encoder_speeds.size(), a.encoder_speeds.size());
    EXPECT_EQ(b.encoder_speeds.back().v_m_s, a.encoder_speeds.back().v_m_s);
    ASSERT_EQ(b.phase_speeds.size(), a.phase_speeds.size());
    EXPECT_EQ(b.phase_speeds.back().omega_rad_s, a.phase_speeds.back().omega_rad_s);
    EXPECT_EQ(b.counts.imu, a.counts.imu);
    EXPECT_EQ(b.counts.encoders, a.counts.encoders);
    EXPECT_EQ(b.rec.sonar.size(), a.rec.sonar.size());
    EXPECT_EQ(b.t0_s, a.t0_s);
    EXPECT_EQ(b.t1_s, a.t1_s);
    ASSERT_EQ(b.est.ekf.estimates.size(), a.est.ekf.estimates.size());
    EXPECT_EQ(b.est.ekf.estimates.back().P, a.est.ekf.estimates.back().P);
    for (int s = 0; s < estimation::kNumSensors; ++s)
      EXPECT_EQ(b.est.ekf.sensors[s].rejected, a.est.ekf.sensors[s].rejected);
    ASSERT_EQ(b.trajectories.size(), a.trajectories.size());
    for (const auto& [v, t] : a.trajectories) {
      ASSERT_EQ(b.trajectories.at(v).size(), t.size()) << v;
      EXPECT_EQ(b.trajectories.at(v).back().y_m, t.back().y_m) << v;
    }
    expectSameMetricRows(b, a);
    EXPECT_EQ(b.metrics.failed_recordings, a.metrics.failed_recordings);
    ASSERT_EQ(b.gt_start.size(), a.gt_start.size());
    ASSERT_FALSE(a.gt_start.empty());
    EXPECT_EQ(b.gt_start.back().x_m, a.gt_start.back().x_m);
    EXPECT_EQ(b.gt_frame_note, a.gt_frame_note);
  }
}

// A drive long enough for the figures' thinning (more than Plot::kDecimateAbove samples per
// series): the streamed load keeps its time series thinned as they come (SeriesThinner), with
// the same span, extremes, motion phases and obstacle span as every sample, and the same metrics.
TEST(Report, LongDriveSeriesAreThinnedKeepingWhatIsDrawn) {
  test::TempDir dir;
  const std::string rawlog = dir / "long.rawlog";
  const auto sim = test::cli("simulate --scenario excite --duration 240 --seed 3 -o " + rawlog);
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const config::WheelchairConfig cfg;
  const evaluation::MetricOptions mo;
  DriveLoadOptions lo;
  lo.keep_estimates = false;
  const DriveData a = loadDrive(io::readRawlog(rawlog), rawlog, cfg, mo, "", lo);
  const DriveData b = loadDriveStreamed(rawlog, io::scanRawlog(rawlog), cfg, mo);
  ASSERT_GT(a.gyro.size(), Plot::kDecimateAbove);
  ASSERT_GT(a.ekf_trace.size(), Plot::kDecimateAbove);
  // (at most first, last, lowest and highest per 1/8192 of the span: a 240 s drive has ~3 gyro
  // samples per bin, a one-hour drive ~44)
  EXPECT_LT(b.gyro.size(), a.gyro.size());
  EXPECT_LT(b.currents.size(), a.currents.size());
  EXPECT_LT(b.ekf_trace.size(), a.ekf_trace.size());
  EXPECT_LE(b.phase_speeds.size(), a.phase_speeds.size());
  auto extremes = [](const auto& v, auto value) {
    double lo = INFINITY, hi = -INFINITY;
    for (const auto& x : v) lo = std::min(lo, value(x)), hi = std::max(hi, value(x));
    return std::make_pair(lo, hi);
  };
  auto gz = [](const GyroPoint& g) { return g.gyro_z_rad_s; };
  auto il = [](const CurrentPoint& c) { return c.current_left_A; };
  auto ew = [](const EkfTracePoint& e) { return e.omega_rad_s; };
  auto ev = [](const SpeedPoint& e) { return e.v_m_s; };
  EXPECT_EQ(extremes(b.gyro, gz), extremes(a.gyro, gz));
  EXPECT_EQ(extremes(b.currents, il), extremes(a.currents, il));
  EXPECT_EQ(extremes(b.ekf_trace, ew), extremes(a.ekf_trace, ew));
  EXPECT_EQ(extremes(b.encoder_speeds, ev), extremes(a.encoder_speeds, ev));
  EXPECT_EQ(b.gyro.front().t_s, a.gyro.front().t_s);
  EXPECT_EQ(b.gyro.back().t_s, a.gyro.back().t_s);
  EXPECT_EQ(b.t0_s, a.t0_s);
  EXPECT_EQ(b.t1_s, a.t1_s);
  EXPECT_EQ(defaultObstacleTime(b), defaultObstacleTime(a));
  // The shaded phases: the runs of equal motionKind, first and last time of each.
  auto runs = [](const std::vector<SpeedPoint>& v) {
    std::vector<std::tuple<int, double, double>> r;
    for (const auto& s : v)
      if (r.empty() || std::get<0>(r.back()) != motionKind(s))
        r.emplace_back(motionKind(s), s.t_s, s.t_s);
      else
        std::get<2>(r.back()) = s.t_s;
    return r;
  };
  EXPECT_EQ(runs(b.phase_speeds), runs(a.phase_speeds));
  ASSERT_EQ(b.metrics.rows.size(), a.metrics.rows.size());
  for (std::size_t i = 0; i < a.metrics.rows.size(); ++i) {
    EXPECT_EQ(b.metrics.rows[i].n_estimates, a.metrics.rows[i].n_estimates);
    EXPECT_EQ(b.metrics.rows[i].metrics.ate_rmse_m, a.metrics.rows[i].metrics.ate_rmse_m);
  }
  for (const auto& [v, t] : a.trajectories) EXPECT_EQ(b.trajectories.at(v).size(), t.size()) << v;
}

TEST(Report, BadInputExitsWithOne) {
  test::TempDir dir;
  EXPECT_EQ(test::cli("report " + (dir / "nope.rawlog") + " -o " + (dir / "out")).exit_code, 1);
}

}  // namespace
}  // namespace wheelchair::visualization
