// Stage 1's rows (kinematicRows) are made without corrected copies of the encoder times and the
// gyro and without a stored cumulative gyro integral: the integral is summed as the windows
// move forward and its sums behind them released (memory, docs/benchmarks.md, "Ninth round,
// stage 1"). On a bundled drive imported as a rawlog (the CLI's read), with every sensor
// correction non-trivial and with gaps in both streams, the rows must be those of the stored
// computation (the code before, kept here as the reference) bit for bit, the stage 1 fit on
// them the same, and the whole-stream join that consumes its parts must give what the join of
// kept parts gives.
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/diagnosis/Stages.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/sensors/Filtering.h"

#include "../common/TestUtil.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace {

using namespace wheelchair;
using test::cli;
using test::sourcePath;

/// The stored cumulative trapezoid of the corrected gyro (the code before the change).
struct StoredIntegral {
  const std::vector<double>* t = nullptr;
  std::vector<double> x, C;
  double shift = 0;
  double value(double tq) const {
    const double q = tq + shift;
    const auto& T = *t;
    if (q <= T.front()) return x.front();
    if (q >= T.back()) return x.back();
    const size_t k = std::upper_bound(T.begin(), T.end(), q) - T.begin();
    const double a = (q - T[k - 1]) / (T[k] - T[k - 1]);
    return x[k - 1] + a * (x[k] - x[k - 1]);
  }
  double F(double tq) const {
    const double q = tq + shift;
    const auto& T = *t;
    if (q <= T.front()) return 0.0;
    if (q >= T.back()) return C.back();
    const size_t k = std::upper_bound(T.begin(), T.end(), q) - T.begin();
    return C[k - 1] + 0.5 * (x[k - 1] + value(tq)) * (q - T[k - 1]);
  }
  double integral(double a, double b) const { return F(b) - F(a); }
  double maxGap(double a, double b) const {
    const auto& T = *t;
    const double qa = a + shift, qb = b + shift;
    if (qa < T.front() || qb > T.back()) return 1e300;
    const size_t i = std::upper_bound(T.begin(), T.end(), qa) - T.begin();
    const size_t j = std::lower_bound(T.begin(), T.end(), qb) - T.begin();
    double g = 0;
    for (size_t k = std::max<size_t>(i, 1); k <= j && k < T.size(); ++k)
      g = std::max(g, T[k] - T[k - 1]);
    return g;
  }
};

/// kinematicRows as it was: corrected copies of te and gz, the whole cumulative integral.
diagnosis::KinRows storedKinematicRows(const std::vector<diagnosis::Streams>& recs,
                                       const diagnosis::Corrections& c,
                                       const config::WheelchairConfig& cfg,
                                       const diagnosis::DiagnosisOptions& opt) {
  diagnosis::KinRows k;
  const double lw = cfg.vehicle.geom.track_width_m;
  const auto& cols = diagnosis::kinematicColumns();
  std::vector<double> y, X;
  for (const auto& s : recs) {
    std::vector<double> te(s.te.size());
    for (size_t i = 0; i < te.size(); ++i) te[i] = s.te[i] - c.delay_enc;
    StoredIntegral G;
    G.t = &s.tg, G.shift = c.delay_imu;
    for (double g : s.gz) G.x.push_back((g - c.gyro_bias) / c.gyro_scale);
    G.C.assign(s.tg.size(), 0.0);
    for (size_t m = 1; m < s.tg.size(); ++m)
      G.C[m] = G.C[m - 1] + 0.5 * (G.x[m] + G.x[m - 1]) * (s.tg[m] - s.tg[m - 1]);
    const double dte = sensors::medianSpacing(te), dtg = sensors::medianSpacing(s.tg);
    const int step = std::max(1, static_cast<int>(std::lround(opt.window_s / dte)));
    int begin = static_cast<int>(y.size());
    for (size_t i = 0; i + step < te.size(); i += step) {
      const size_t j = i + step;
      const double t0 = te[i], t1 = te[j];
      bool gap = false;
      for (size_t m = i + 1; m <= j; ++m)
        if (te[m] - te[m - 1] > opt.max_gap_s) gap = true;
      const double dR = (s.sR[j] - s.sR[i]) / c.enc_scale[0];
      const double dL = (s.sL[j] - s.sL[i]) / c.enc_scale[1];
      const double dphi_enc = (dR - dL) / lw;
      const double phi_mid =
          0.5 * ((s.sR[i] + s.sR[j]) / c.enc_scale[0] - (s.sL[i] + s.sL[j]) / c.enc_scale[1]) / lw;
      if (gap || G.maxGap(t0, t1) > opt.max_gap_s) {
        if (static_cast<int>(y.size()) > begin)
          k.groups.push_back({begin, static_cast<int>(y.size())});
        begin = static_cast<int>(y.size());
        continue;
      }
      y.push_back(G.integral(t0, t1) - dphi_enc);
      const double h = std::max(opt.window_s, dtg);
      auto meanRate = [&](double tc) { return G.integral(tc - h, tc + h) / (2 * h); };
      const effects::KinematicWindow w{t1 - t0, dR, dL, lw, meanRate(t1) - meanRate(t0)};
      for (const auto& col : cols) X.push_back(col.value(w));
      k.t0.push_back(t0), k.t1.push_back(t1);
      k.v.push_back(0.5 * (dR + dL) / (t1 - t0));
      k.omega.push_back(dphi_enc / (t1 - t0));
      k.phi.push_back(phi_mid);
    }
    if (static_cast<int>(y.size()) > begin) k.groups.push_back({begin, static_cast<int>(y.size())});
  }
  k.y = Eigen::Map<Eigen::VectorXd>(y.data(), y.size());
  k.X = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      X.data(), y.size(), cols.size());
  return k;
}

/// The streams of a bundled drive imported through the CLI and read back from its rawlog.
diagnosis::Streams bundledStreams(const test::TempDir& tmp, const std::string& dataset,
                                  const config::WheelchairConfig& cfg) {
  const std::string out = tmp / (dataset + ".rawlog");
  const auto r = cli("import " + sourcePath("datasets/" + dataset) + " -o " + out);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  return diagnosis::makeStreams(io::readRawlog(out), cfg);
}

/// s without its samples of `col` (time column `t`) in [a, b] (a gap in that stream).
void cutGap(diagnosis::Streams& s, std::vector<double> diagnosis::Streams::*t,
            std::vector<std::vector<double> diagnosis::Streams::*> cols, double a, double b) {
  const std::vector<double> T = s.*t;
  for (auto c : cols) {
    std::vector<double> kept;
    for (size_t k = 0; k < T.size(); ++k)
      if (T[k] < a || T[k] > b) kept.push_back((s.*c)[k]);
    s.*c = kept;
  }
}

void expectSameRows(const diagnosis::KinRows& a, const diagnosis::KinRows& b) {
  ASSERT_EQ(a.y.size(), b.y.size());
  EXPECT_TRUE(a.y == b.y);
  EXPECT_TRUE(a.X == b.X);
  EXPECT_EQ(a.t0, b.t0);
  EXPECT_EQ(a.t1, b.t1);
  EXPECT_EQ(a.v, b.v);
  EXPECT_EQ(a.omega, b.omega);
  EXPECT_EQ(a.phi, b.phi);
  EXPECT_EQ(a.groups, b.groups);
}

TEST(KinematicRowsStreamed, RowsAndFitEqualTheStoredIntegralsOnABundledDrive) {
  test::TempDir tmp;
  const config::WheelchairConfig cfg;
  diagnosis::DiagnosisOptions opt;
  const diagnosis::Streams clean = bundledStreams(tmp, "three_task_faulty", cfg);
  ASSERT_TRUE(clean.hasEncoders() && clean.hasGyro());
  // The same drive with a 1.5 s gyro gap and a 0.8 s encoder gap (rows split into groups).
  diagnosis::Streams gappy = clean;
  const double t_mid = 0.5 * (clean.t_begin + clean.t_end);
  cutGap(gappy, &diagnosis::Streams::tg, {&diagnosis::Streams::tg, &diagnosis::Streams::gz},
         t_mid - 20, t_mid - 18.5);
  cutGap(gappy, &diagnosis::Streams::te,
         {&diagnosis::Streams::te, &diagnosis::Streams::sR, &diagnosis::Streams::sL}, t_mid + 10,
         t_mid + 10.8);
  diagnosis::Corrections none, c;
  c.gyro_bias = 0.0031, c.gyro_scale = 1.021, c.delay_imu = 0.037;
  c.enc_scale[0] = 1.013, c.enc_scale[1] = 0.991, c.delay_enc = 0.011;
  diagnosis::Corrections imu_late;  // the stage's delay refit: delay_imu only
  imu_late.delay_imu = -0.024;
  for (const auto& corr : {none, c, imu_late}) {
    const std::vector<diagnosis::Streams> recs{clean, gappy};
    const diagnosis::KinRows got = diagnosis::kinematicRows(recs, corr, cfg, opt);
    const diagnosis::KinRows want = storedKinematicRows(recs, corr, cfg, opt);
    ASSERT_GT(got.y.size(), 400);      // two 43 s drives of 0.2 s windows
    EXPECT_GE(got.groups.size(), 4u);  // both recordings, each gap splits one
    expectSameRows(got, want);
    // the stage 1 fit on them: every catalogue term but the left encoder's (it and the right
    // one span the gyro scale's column)
    const auto cands = diagnosis::stageCandidates(effects::Stage::kinematic, {0.0, true});
    std::vector<int> all;
    for (size_t i = 0; i < cands.size(); ++i)
      if (cands[i].name != "encoder_scale/left") all.push_back(static_cast<int>(i));
    ASSERT_GE(all.size(), 3u);
    const auto a = diagnosis::fitAccepted(got.X, got.y, cands, all, got.groups, 5);
    const auto b = diagnosis::fitAccepted(want.X, want.y, cands, all, want.groups, 5);
    ASSERT_TRUE(a.ok);
    EXPECT_TRUE(a.beta == b.beta);
    EXPECT_TRUE(a.cov == b.cov);
  }
}

TEST(KinematicRowsStreamed, ConsumingJoinEqualsTheJoinOfKeptParts) {
  test::TempDir tmp;
  const config::WheelchairConfig cfg;
  const diagnosis::Streams s = bundledStreams(tmp, "excite", cfg);
  const double tc = s.tg[s.tg.size() / 2], a = s.tg[10], b = s.tg[s.tg.size() - 10];
  const double inf = 1e300;
  const std::vector<std::pair<double, double>> ranges{
      {-inf, std::nextafter(a, -inf)}, {a, tc}, {tc, b}, {std::nextafter(b, inf), inf}};
  std::vector<diagnosis::Streams> parts = diagnosis::cropStreams(diagnosis::Streams(s), ranges);
  ASSERT_EQ(parts[1].tg.back(), parts[2].tg.front());  // a shared boundary sample
  const diagnosis::Streams kept =
      diagnosis::joinStreams({&parts[0], &parts[1], &parts[2], &parts[3]}, false);
  const diagnosis::Streams joined = diagnosis::joinStreams(std::move(parts), false);
  EXPECT_TRUE(parts.empty());
  EXPECT_EQ(joined.te, s.te);
  EXPECT_EQ(joined.sR, s.sR);
  EXPECT_EQ(joined.sL, s.sL);
  EXPECT_EQ(joined.tg, s.tg);
  EXPECT_EQ(joined.gz, s.gz);
  EXPECT_TRUE(joined.tm.empty() && joined.iR.empty());
  EXPECT_EQ(joined.te, kept.te);
  ASSERT_EQ(joined.pozyx.size(), s.pozyx.size());
  for (size_t k = 0; k < s.pozyx.size(); ++k) EXPECT_EQ(joined.pozyx[k].t_s, s.pozyx[k].t_s);
  EXPECT_EQ(joined.t_begin, s.t_begin);
  EXPECT_EQ(joined.t_end, s.t_end);
}

}  // namespace
