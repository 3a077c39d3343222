// Stage 2's unmodeled-term library is not stored as a matrix but made column by column from the
// rows' signals (DynRows::libColumn; docs/benchmarks.md, "Memory"): every column must be what
// dynLibNames() says it is, on the rows of a simulated drive, and the rows must stay laid out
// as before (right motor rows, then left, in groups covering both halves).
#include "DiagnoseTestUtil.h"
#include "libwheelchair/diagnosis/Stages.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace wheelchair;

TEST(DynRowsLibrary, EveryColumnIsTheNamedSignalOfItsRow) {
  const auto sim = diagnosis::testutil::simulateWith("excite", 3, 60.0, {});
  config::WheelchairConfig cfg;
  diagnosis::DiagnosisOptions opt;
  const auto s = diagnosis::makeStreams(sim.recording, cfg);
  const diagnosis::DynRows d = diagnosis::dynamicRows({s}, {}, cfg, opt);
  const int N = static_cast<int>(d.y.size()), nR = N / 2;
  ASSERT_GT(nR, 1000);  // 60 s at 50 Hz, minus the trimmed edges
  ASSERT_EQ(diagnosis::dynLibNames().size(), 16u);
  // Right rows first, then left; the groups cover both halves exactly.
  int covered = 0;
  for (auto [a, b] : d.groups) covered += b - a;
  EXPECT_EQ(covered, N);
  for (int k = 0; k < N; ++k) ASSERT_EQ(d.side[k], k < nR ? 0 : 1);
  std::vector<Eigen::VectorXd> L;
  for (int j = 0; j < 16; ++j) L.push_back(d.libColumn(j, 0, N));
  const double lw = cfg.vehicle.geom.track_width_m;
  double max_current = 0;
  for (int k = 0; k < N; ++k) {
    EXPECT_EQ(L[0](k), 1.0);
    EXPECT_EQ(L[1](k), d.v[k]);
    EXPECT_EQ(L[2](k), d.omega[k]);
    EXPECT_EQ(L[3](k), d.vdot[k]);
    EXPECT_EQ(L[4](k), d.omegadot[k]);
    EXPECT_EQ(L[6](k), std::abs(d.u[k]));
    EXPECT_EQ(L[7](k), d.u[k] * d.u[k]);
    EXPECT_EQ(L[8](k), d.v[k] * d.omega[k]);
    EXPECT_EQ(L[9](k), d.omega[k] * d.omega[k]);
    EXPECT_EQ(L[14](k), d.v[k] * std::abs(d.v[k]));
    EXPECT_NEAR(L[15](k), std::tanh(d.omega[k] / 0.02), 1e-12);
    // u is the motor's own rim speed: v +- omega l_w / 2 (right +, left -).
    EXPECT_NEAR(d.u[k], d.v[k] + (k < nR ? 0.5 : -0.5) * lw * d.omega[k], 1e-9);
    EXPECT_LE(std::abs(L[5](k)), 1.2);  // the smoothed, filtered sign of u
    EXPECT_NEAR(L[10](k) * L[10](k) + L[11](k) * L[11](k), 1.0, 0.05);  // filtered cos/sin
    // i_other is the other motor's i_self at the same grid time.
    const int other = k < nR ? k + nR : k - nR;
    EXPECT_EQ(L[13](k), L[12](other));
    EXPECT_EQ(d.t[k], d.t[other]);
    max_current = std::max(max_current, std::abs(L[12](k)));
  }
  EXPECT_GT(max_current, 0.5);  // the excite drive draws current
  // A window of rows is the same window of the full column.
  const Eigen::VectorXd w = d.libColumn(13, nR + 10, 100);
  EXPECT_EQ(w, L[13].segment(nR + 10, 100));
  EXPECT_THROW(d.libColumn(16, 0, 1), std::out_of_range);
}
