// Stage 2's unmodeled-term library is not stored as a matrix but made column by column from the
// rows' signals (DynRows::libColumn; docs/benchmarks.md, "Memory"): every column must be what
// dynLibNames() says it is, on the rows of a simulated drive, and the rows must stay laid out
// as before (right motor rows, then left, in groups covering both halves).
#include "DiagnoseTestUtil.h"
#include "libwheelchair/diagnosis/HeldOut.h"
#include "libwheelchair/diagnosis/Stages.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/TextFormat.h"
#include "libwheelchair/stats/LeastSquares.h"
#include "libwheelchair/util/SpilledColumns.h"

#include "../common/TestUtil.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

using namespace wheelchair;

TEST(DynRowsLibrary, EveryColumnIsTheNamedSignalOfItsRow) {
  const auto sim = diagnosis::testutil::simulateWith("excite", 3, 60.0, {});
  config::WheelchairConfig cfg;
  diagnosis::DiagnosisOptions opt;
  const auto s = diagnosis::makeStreams(sim.recording, cfg);
  const diagnosis::DynRows d = diagnosis::dynamicRows({s}, {}, cfg, opt);
  const int N = static_cast<int>(d.y.size()), nR = N / 2;
  ASSERT_GT(nR, 1000);  // 60 s at 50 Hz, minus the trimmed edges
  ASSERT_EQ(diagnosis::dynLibNames().size(), 17u);
  // Right rows first, then left; the groups cover both halves exactly.
  int covered = 0;
  for (auto [a, b] : d.groups) covered += b - a;
  EXPECT_EQ(covered, N);
  for (int k = 0; k < N; ++k) ASSERT_EQ(d.side(k), k < nR ? 0 : 1);
  // The grid signals are stored once per grid sample (row k is grid sample step(k)).
  ASSERT_EQ(d.grid.t.size(), static_cast<std::size_t>(nR));
  ASSERT_EQ(d.grid.sin_phi.size(), static_cast<std::size_t>(nR));
  std::vector<Eigen::VectorXd> L;
  for (int j = 0; j < 17; ++j) L.push_back(d.libColumn(j, 0, N));
  ASSERT_EQ(d.castor.size(), static_cast<std::size_t>(nR));
  const double lw = cfg.vehicle.geom.track_width_m;
  double max_current = 0;
  const auto& g = d.grid;
  for (int k = 0; k < N; ++k) {
    const int i = d.step(k);
    EXPECT_EQ(i, k < nR ? k : k - nR);
    EXPECT_EQ(L[0](k), 1.0);
    EXPECT_EQ(L[1](k), g.v[i]);
    EXPECT_EQ(L[2](k), g.omega[i]);
    EXPECT_EQ(L[3](k), g.vdot[i]);
    EXPECT_EQ(L[4](k), g.omegadot[i]);
    EXPECT_EQ(L[6](k), std::abs(d.u[k]));
    EXPECT_EQ(L[7](k), d.u[k] * d.u[k]);
    EXPECT_EQ(L[8](k), g.v[i] * g.omega[i]);
    EXPECT_EQ(L[9](k), g.omega[i] * g.omega[i]);
    EXPECT_EQ(L[14](k), g.v[i] * std::abs(g.v[i]));
    EXPECT_NEAR(L[15](k), std::tanh(g.omega[i] / 0.02), 1e-12);
    EXPECT_EQ(L[16](k), d.castor[i]);  // the castors' swivel moment, the same on both motors
    // u is the motor's own rim speed: v +- omega l_w / 2 (right +, left -).
    EXPECT_NEAR(d.u[k], g.v[i] + (k < nR ? 0.5 : -0.5) * lw * g.omega[i], 1e-9);
    EXPECT_LE(std::abs(L[5](k)), 1.2);  // the smoothed, filtered sign of u
    EXPECT_NEAR(L[10](k) * L[10](k) + L[11](k) * L[11](k), 1.0, 0.05);  // filtered cos/sin
    // i_other is the other motor's i_self at the same grid time.
    const int other = k < nR ? k + nR : k - nR;
    EXPECT_EQ(L[13](k), L[12](other));
    EXPECT_EQ(d.step(k), d.step(other));
    EXPECT_EQ(L[10](k), g.cos_phi[i]);
    EXPECT_EQ(L[11](k), g.sin_phi[i]);
    max_current = std::max(max_current, std::abs(L[12](k)));
  }
  EXPECT_GT(max_current, 0.5);  // the excite drive draws current
  // A window of rows is the same window of the full column.
  const Eigen::VectorXd w = d.libColumn(13, nR + 10, 100);
  EXPECT_EQ(w, L[13].segment(nR + 10, 100));
  EXPECT_THROW(d.libColumn(17, 0, 1), std::out_of_range);
}

// diagnose keeps a recording's whole streams (trajectory and Pozyx checks) only as its fit and
// held-out parts plus what lies outside them, and joins them afterwards (memory,
// docs/benchmarks.md): the join must give back the streams sample for sample, including a
// sample on the boundary of two parts.
TEST(DynRowsLibrary, JoinedCropsAreTheWholeStreams) {
  const auto sim = diagnosis::testutil::simulateWith("excite", 3, 30.0, {});
  config::WheelchairConfig cfg;
  const auto s = diagnosis::makeStreams(sim.recording, cfg);
  ASSERT_TRUE(s.hasEncoders() && s.hasGyro() && s.hasMotors());
  ASSERT_FALSE(s.pozyx.empty());
  const double tc = s.tg[s.tg.size() / 2];  // a gyro sample in both middle parts
  const double a = s.tg[10], b = s.tg[s.tg.size() - 10], inf = 1e300;
  const auto before = diagnosis::cropStreams(s, -inf, std::nextafter(a, -inf));
  const auto fit = diagnosis::cropStreams(s, a, tc), val = diagnosis::cropStreams(s, tc, b);
  const auto after = diagnosis::cropStreams(s, std::nextafter(b, inf), inf);
  ASSERT_EQ(fit.tg.back(), val.tg.front());  // the shared boundary sample
  for (bool motors : {true, false}) {
    const auto j = diagnosis::joinStreams({&before, &fit, &val, &after}, motors);
    EXPECT_EQ(j.te, s.te);
    EXPECT_EQ(j.sR, s.sR);
    EXPECT_EQ(j.sL, s.sL);
    EXPECT_EQ(j.tg, s.tg);
    EXPECT_EQ(j.gz, s.gz);
    EXPECT_EQ(j.tm, motors ? s.tm : std::vector<double>{});
    EXPECT_EQ(j.iL, motors ? s.iL : std::vector<double>{});
    ASSERT_EQ(j.pozyx.size(), s.pozyx.size());
    for (std::size_t k = 0; k < s.pozyx.size(); ++k) EXPECT_EQ(j.pozyx[k].t_s, s.pozyx[k].t_s);
    EXPECT_EQ(j.t_begin, s.t_begin);
    EXPECT_EQ(j.t_end, s.t_end);
  }
  // A part that repeats another (diagnose with --validate: the fit part is the whole recording).
  const auto j = diagnosis::joinStreams({&before, &s, &after}, true);
  EXPECT_EQ(j.tg, s.tg);
  EXPECT_EQ(j.te, s.te);
}

// Stage 2's catalogue fits and held-out predictions are made on designs built block of rows by
// block (fitAccepted, acceptedPrediction; memory, docs/benchmarks.md): on the rows of a
// simulated drive they give the stored design's fit and prediction up to rounding, and the
// blocked cross-validation of a design made block by block is that of the stored design.
TEST(DynRowsLibrary, BlockwiseCatalogueStatisticsEqualTheStoredDesigns) {
  const auto sim = diagnosis::testutil::simulateWith("excite", 5, 120.0, {});
  config::WheelchairConfig cfg;
  diagnosis::DiagnosisOptions opt;
  const auto s = diagnosis::makeStreams(sim.recording, cfg);
  const diagnosis::DynRows d = diagnosis::dynamicRows({s}, {}, cfg, opt);
  ASSERT_GT(d.y.size(), 2 * 2048);  // several blocks
  const auto cands =
      diagnosis::stageCandidates(effects::Stage::dynamic, {cfg.vehicle.geom.body_mass_kg, false});
  std::vector<int> acc;  // every one-column candidate of the right motor or both
  for (int c = 0; c < static_cast<int>(cands.size()); ++c)
    if (cands[c].name.find("left") == std::string::npos && acc.size() < 4) acc.push_back(c);
  ASSERT_GE(acc.size(), 2u);
  const Eigen::MatrixXd D = diagnosis::acceptedDesign(d.design(), cands, acc);
  const stats::LinearFit a = stats::fitLinear(D, d.y, d.groups, 5);
  const stats::LinearFit b = diagnosis::fitAccepted(d.design(), d.y, cands, acc, d.groups, 5);
  ASSERT_TRUE(a.ok);
  ASSERT_TRUE(b.ok);
  for (int k = 0; k < a.beta.size(); ++k) {
    EXPECT_NEAR(b.beta(k), a.beta(k), 1e-10 * std::abs(a.beta(k)) + 1e-300) << k;
    EXPECT_NEAR(b.cov(k, k), a.cov(k, k), 1e-9 * a.cov(k, k)) << k;
  }
  EXPECT_NEAR(b.rss, a.rss, 1e-12 * a.rss);
  const Eigen::VectorXd p = diagnosis::acceptedPrediction(d.design(), cands, acc, a.beta);
  EXPECT_LT((p - D * a.beta).norm(), 1e-12 * p.norm());
  const auto rows = [&](Eigen::Index r0, Eigen::Index r1) {
    return Eigen::MatrixXd(D.middleRows(r0, r1 - r0));
  };
  for (int j = 0; j < static_cast<int>(D.cols()); ++j) {
    const diagnosis::BlockedCvTerm m = diagnosis::blockedCvTerm(D, d.y, j, 10, 25);
    const diagnosis::BlockedCvTerm r =
        diagnosis::blockedCvTerm(rows, D.rows(), D.cols(), d.y, j, 10, 25);
    ASSERT_TRUE(m.testable);
    EXPECT_EQ(r.coef, m.coef);
    EXPECT_EQ(r.coef_se, m.coef_se);
    EXPECT_EQ(r.mean_gain, m.mean_gain);
    EXPECT_EQ(r.p_not_positive, m.p_not_positive);
  }
}

// Stage 2's forward selection on the catalogue design made block by block from the rows'
// signals (DynRows::design; the design is not stored, memory, docs/benchmarks.md) is the
// selection on the stored design, on a bundled drive with a motor asymmetry held out against
// its second run (the left encoder's 0.95 corrected as stage 1 finds it): the same accepted terms,
// evidence, held-out numbers, coefficients and log.
TEST(DynRowsLibrary, BlockwiseSelectionEqualsTheStoredDesignSelection) {
  const config::WheelchairConfig cfg;
  diagnosis::DiagnosisOptions opt;
  // The drive and its second run (held out, as `diagnose --validate` uses it).
  std::vector<diagnosis::DynRows> rows;
  diagnosis::Corrections c;
  c.enc_scale[1] = 0.95;
  for (const char* name : {"three_task_faulty", "three_task_faulty_b"}) {
    const io::Recording rec =
        io::readTextRecording(std::string(WHEELCHAIR_SOURCE_DIR) + "/datasets/" + name);
    rows.push_back(diagnosis::dynamicRows({diagnosis::makeStreams(rec, cfg)}, c, cfg, opt));
  }
  const diagnosis::DynRows &df = rows[0], &dv = rows[1];
  ASSERT_GT(df.y.size(), stats::kDesignBlockRows);  // more than one block in both
  ASSERT_GT(dv.y.size(), stats::kDesignBlockRows);
  const Eigen::MatrixXd Xf = df.design().matrix(), Xv = dv.design().matrix();
  ASSERT_EQ(Xf.cols(), static_cast<Eigen::Index>(diagnosis::driveColumns().size()));
  // Every block is the rows' block of the whole design, wherever the block starts.
  Eigen::MatrixXd B;
  df.design().block(777, 1000, B);
  EXPECT_EQ(B, Xf.middleRows(777, 1000));
  const int lags = static_cast<int>(std::ceil(2.0 * opt.grid_rate_hz / opt.cutoff_hz));
  const double min_rms = opt.min_relevance * cfg.motors.current_noise_A;
  const auto cands =
      diagnosis::stageCandidates(effects::Stage::dynamic, {cfg.vehicle.geom.body_mass_kg, true});
  const diagnosis::SelectionData stored{df.y, dv.y, Xf, Xv, df.groups, dv.groups, lags, min_rms};
  const diagnosis::SelectionData made{df.y,      dv.y,      df.design(), dv.design(),
                                      df.groups, dv.groups, lags,        min_rms};
  const diagnosis::Selection a = diagnosis::forwardSelect(stored, cands, opt);
  const diagnosis::Selection b = diagnosis::forwardSelect(made, cands, opt);
  bool asymmetry = false;
  for (int ci : a.accepted) asymmetry |= cands[ci].effect == "motor_asymmetry";
  EXPECT_TRUE(asymmetry);
  EXPECT_EQ(b.accepted, a.accepted);
  EXPECT_EQ(b.log, a.log);
  ASSERT_EQ(b.steps.size(), a.steps.size());
  for (std::size_t q = 0; q < a.steps.size(); ++q) {
    EXPECT_EQ(b.steps[q].candidate, a.steps[q].candidate);
    EXPECT_EQ(b.steps[q].evidence.lr, a.steps[q].evidence.lr);
    EXPECT_EQ(b.steps[q].rss1_val, a.steps[q].rss1_val);
    EXPECT_EQ(b.steps[q].lr_val_expected, a.steps[q].lr_val_expected);
    EXPECT_EQ(b.steps[q].coef, a.steps[q].coef);
  }
  EXPECT_EQ(b.fit.beta, a.fit.beta);
  EXPECT_EQ(b.fit.cov, a.fit.cov);
}

TEST(DynRowsLibrary, CastorSwivelMomentActsWhileTheCastorsTurnRound) {
  // A straight run forward (castors trailing: no swivel), then a turn on the spot to the left
  // from rest, held at 0.5 rad/s, then reversed. The castors swivel round at the start of the
  // turn and at the reversal (from their unstable balance: slowly at first), and roll without
  // swivelling otherwise.
  std::vector<double> t, v, w;
  for (int i = 0; i < 1500; ++i) {
    const double ts = 0.01 * i;
    t.push_back(ts);
    v.push_back(ts < 3 ? 0.5 : 0.0);
    w.push_back(ts < 4 ? 0.0 : (ts < 8 ? 0.5 : -0.5));
  }
  const diagnosis::CastorGeometry g;  // 0.45 m ahead, +-0.22 m, 0.08 m
  const auto m = diagnosis::castorSwivelMoment(t, v, w, g);
  ASSERT_EQ(m.size(), t.size());
  auto absMax = [&](double a, double b) {
    double x = 0;
    for (std::size_t i = 0; i < t.size(); ++i)
      if (t[i] >= a && t[i] < b) x = std::max(x, std::abs(m[i]));
    return x;
  };
  EXPECT_LT(absMax(0.5, 3.0), 1e-6);  // straight: aligned castors do not swivel
  EXPECT_LT(absMax(3.0, 4.0), 1e-6);  // standing
  // Turn start: both castors swivel with a lever ~ x / d = 5.6 each.
  EXPECT_GT(absMax(4.0, 4.5), 5.0);
  EXPECT_LT(absMax(6.0, 8.0), 0.05);  // steady turn: aligned again
  EXPECT_GT(absMax(8.0, 11.0), 5.0);  // the reversal swivels them round again
  EXPECT_LT(absMax(13.0, 15.0), 0.05);
  // At the turn start and at the reversal the castors swivel in opposite senses.
  double s_start = 0, s_rev = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (t[i] >= 4.0 && t[i] < 4.5) s_start += m[i];
    if (t[i] >= 8.0 && t[i] < 11.0) s_rev += m[i];
  }
  EXPECT_LT(s_start * s_rev, 0);  // opposite swivels at the start and the reversal
  // No castors modelled (relaxation 0): no column.
  diagnosis::CastorGeometry none;
  none.relaxation_m = 0;
  for (double x : diagnosis::castorSwivelMoment(t, v, w, none)) EXPECT_EQ(x, 0.0);
}

// diagnose sets the streams aside on a temporary file while stage 2 does not read them
// (util::SpilledColumns; docs/benchmarks.md, "Tenth round"): each recording's encoders and
// motor currents go to the file as soon as dynamicRows has copied them (its `copied`). On a
// bundled drive imported through the CLI, with sensor corrections, the rows made so must be the
// rows of streams held in memory bit for bit, and the streams read back must be the same.
TEST(DynRowsLibrary, RowsWithTheStreamsSetAsideEqualTheRowsOfHeldStreams) {
  test::TempDir tmp;
  const config::WheelchairConfig cfg;
  const diagnosis::DiagnosisOptions opt;
  const std::string out = tmp / "faulty.rawlog";
  const auto r =
      test::cli("import " + test::sourcePath("datasets/three_task_faulty") + " -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const diagnosis::Streams s = diagnosis::makeStreams(io::readRawlog(out), cfg);
  ASSERT_TRUE(s.hasEncoders() && s.hasMotors());
  ASSERT_FALSE(s.pozyx.empty());
  diagnosis::Corrections c;
  c.enc_scale[0] = 1.02, c.enc_scale[1] = 0.97, c.delay_enc = 0.013, c.delay_motors = 0.021;
  const std::vector<diagnosis::Streams> held{s, s};  // two recordings
  std::vector<diagnosis::Streams> parts{s, s};
  util::SpilledColumns sp("test: the streams");
  for (auto& p : parts) sp.spill(p.pozyx), sp.spill(p.gt), sp.spill(p.gz);  // never read
  std::vector<std::size_t> seen;
  const diagnosis::DynRows a = diagnosis::dynamicRows(held, c, cfg, opt);
  const diagnosis::DynRows b = diagnosis::dynamicRows(parts, c, cfg, opt, [&](std::size_t k) {
    seen.push_back(k);
    for (auto* v :
         {&parts[k].te, &parts[k].sR, &parts[k].sL, &parts[k].tm, &parts[k].iR, &parts[k].iL})
      sp.spill(*v);
  });
  EXPECT_EQ(seen, (std::vector<std::size_t>{0, 1}));
  EXPECT_TRUE(parts[0].te.empty() && parts[1].iL.empty() && parts[1].pozyx.empty());
  ASSERT_GT(a.y.size(), 1000);
  EXPECT_TRUE(a.y == b.y);
  for (auto f : {&diagnosis::DynRows::u, &diagnosis::DynRows::sgn_u, &diagnosis::DynRows::current,
                 &diagnosis::DynRows::dcurrent_model, &diagnosis::DynRows::castor})
    EXPECT_TRUE(a.*f == b.*f);
  using G = diagnosis::DynRows::Grid;
  for (auto f :
       {&G::t, &G::v, &G::omega, &G::vdot, &G::omegadot, &G::phi, &G::cos_phi, &G::sin_phi})
    EXPECT_TRUE(a.grid.*f == b.grid.*f);
  EXPECT_EQ(a.groups, b.groups);
  EXPECT_EQ(a.noise_var, b.noise_var);
  sp.restore();
  EXPECT_EQ(sp.spilled(), 0u);
  for (const auto& p : parts) {
    for (auto f : {&diagnosis::Streams::te, &diagnosis::Streams::sR, &diagnosis::Streams::sL,
                   &diagnosis::Streams::tm, &diagnosis::Streams::iR, &diagnosis::Streams::iL,
                   &diagnosis::Streams::tg, &diagnosis::Streams::gz})
      EXPECT_TRUE(p.*f == s.*f);
    ASSERT_EQ(p.pozyx.size(), s.pozyx.size());
    for (std::size_t k = 0; k < s.pozyx.size(); ++k) {
      const io::PozyxSample &x = p.pozyx[k], &y = s.pozyx[k];
      EXPECT_TRUE(x.t_s == y.t_s && x.x_m == y.x_m && x.y_m == y.y_m && x.has_z == y.has_z &&
                  x.z_m == y.z_m);
    }
    ASSERT_EQ(p.gt.size(), s.gt.size());
  }
}

// Stage 2 makes products of the accepted catalogue design D (n x k, a few columns) by the
// coefficients b for some rows only (memory, docs/benchmarks.md "Tenth round"): each motor's
// residual y - D b from its own rows (jointDynamicFit) and a finding's contribution D_a b block
// by block of rows, the last block taking the rest (its active segments). Both rely on Eigen's
// matrix-vector product giving every row the same doubles whichever rows it is given: on the
// rows of a simulated drive they must equal the rows of the whole product bit for bit.
TEST(DynRowsLibrary, ProductsOverSomeRowsEqualTheRowsOfTheWholeProduct) {
  const auto sim = diagnosis::testutil::simulateWith("excite", 3, 150.0, {});
  config::WheelchairConfig cfg;
  diagnosis::DiagnosisOptions opt;
  const diagnosis::DynRows d =
      diagnosis::dynamicRows({diagnosis::makeStreams(sim.recording, cfg)}, {}, cfg, opt);
  const diagnosis::CatalogueDesign design = d.design();
  const long n = design.rows(), p = design.cols();
  ASSERT_GT(n, 4 * stats::kDesignBlockRows);  // several blocks and a merged tail
  for (const long k : {1L, 3L, std::min(p, 7L)}) {
    SCOPED_TRACE("columns " + std::to_string(k));
    Eigen::MatrixXd S = Eigen::MatrixXd::Zero(p, k);
    for (long c = 0; c < k; ++c) S((c * 5) % p, c) = 1.0;
    const Eigen::MatrixXd D = design.times(S);
    Eigen::VectorXd b(k);
    for (long c = 0; c < k; ++c) b(c) = (c % 2 ? -1.0 : 1.0) * (0.37 + c) / 3.0;
    const Eigen::VectorXd whole = d.y - D * b, contrib = D * b;
    const Eigen::Index nR = n / 2;
    for (int s2 = 0; s2 < 2; ++s2) {  // jointDynamicFit's residuals of motor s2
      Eigen::VectorXd r = D.middleRows(s2 * nR, nR) * b;
      r = d.y.segment(s2 * nR, nR) - r;
      ASSERT_EQ(r.size(), nR);
      EXPECT_EQ(std::memcmp(r.data(), whole.data() + s2 * nR, sizeof(double) * nR), 0)
          << "motor " << s2;
    }
    Eigen::VectorXd blocks(n);  // the findings' contributions
    for (Eigen::Index r0 = 0, nb = 0; r0 < n; r0 += nb) {
      nb = n - r0 < 2 * stats::kDesignBlockRows ? n - r0 : stats::kDesignBlockRows;
      blocks.segment(r0, nb) = D.middleRows(r0, nb) * b;
    }
    EXPECT_EQ(std::memcmp(blocks.data(), contrib.data(), sizeof(double) * n), 0);
  }
}
