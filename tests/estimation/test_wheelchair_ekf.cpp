// Behaviour of the wheelchair filters on synthetic and simulated recordings.
#include "SyntheticDrive.h"

#include "libwheelchair/estimation/DeadReckoning.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/estimation/WheelchairEkf.h"

#include <gtest/gtest.h>

#include <mrpt/config/CConfigFileMemory.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <random>

using namespace wheelchair;
using namespace wheelchair::estimation;
using namespace wheelchair::estimation::test;

TEST(WheelchairEkf, CovarianceStaysSymmetricPositiveDefiniteOverALongDrive) {
  SynthOptions so = curvyDrive(120.0);
  so.currents = curvyCurrents(1.1, 2.0, 0.6);
  so.pozyx = true;
  const SynthRun sr = synthesize(nominal(), so, 7);
  for (auto form : {ObstacleFormOption::Cartesian, ObstacleFormOption::Polar}) {
    EkfOptions opt;
    opt.obstacle_form = form;
    opt.use_pozyx = true;
    opt.output_rate_hz = 5;
    const EstimationResult res = runEstimator(sr.rec, nominal(), opt);
    ASSERT_GT(res.estimates.size(), 500u);
    double min_eig = 1e300, max_asym = 0;
    for (const auto& e : res.estimates) {
      max_asym = std::max(max_asym, (e.P - e.P.transpose()).cwiseAbs().maxCoeff());
      min_eig =
          std::min(min_eig, Eigen::SelfAdjointEigenSolver<CanonicalCov>(e.P).eigenvalues()(0));
      ASSERT_TRUE(e.x.allFinite());
    }
    EXPECT_EQ(max_asym, 0.0);
    EXPECT_GT(min_eig, 0.0);
    // The full 9-state covariance at the end as well (accumulators PSD).
    const auto& last = res.final();
    EXPECT_NEAR(last.t_s, sr.truth.back().t_s, 0.2);
    const Eigen::Matrix<double, 7, 1> truth = sr.canonical(last.t_s, so.obstacle_world);
    EXPECT_LT(std::hypot(last.x(2) - truth(2), last.x(3) - truth(3)), 0.3);  // Pozyx-aided
    std::printf("[long drive %s] min eigenvalue of P %.3g, final position error %.3f m\n",
                form == ObstacleFormOption::Polar ? "polar" : "cartesian", min_eig,
                std::hypot(last.x(2) - truth(2), last.x(3) - truth(3)));
  }
}

TEST(WheelchairEkf, SonarZerosAreDropoutsAndTheObstacleRecovers) {
  SynthOptions so = curvyDrive(8.0);
  so.currents = curvyCurrents(0.0, 1.2, 0.0);  // straight towards the obstacle
  so.obstacle_world = Eigen::Vector2d(3.5, 0.1);
  // Fig. 8: the sonar fails 3 times between 2 s and 4 s and 3 times between 5 and 6 s.
  so.forced_sonar_zeros = {20, 21, 27, 32, 33, 34, 50, 51, 55, 56, 57, 58};
  const SynthRun sr = synthesize(nominal(), so, 3);
  EkfOptions opt;
  const EstimationResult res = runEstimator(sr.rec, nominal(), opt);
  const SensorStats& st = res.stats(Sensor::Sonar);
  long zeros = 0;
  for (const auto& s : sr.rec.sonar) zeros += s.range_m == 0.0;
  EXPECT_EQ(st.dropouts, zeros);
  EXPECT_GE(zeros, static_cast<long>(so.forced_sonar_zeros.size()));
  EXPECT_EQ(st.rejected, 0);
  double worst_during = 0, worst_after = 0;
  for (const auto& e : res.estimates) {
    if (!e.obstacle_initialised) continue;
    const Eigen::Matrix<double, 7, 1> tr = sr.canonical(e.t_s, so.obstacle_world);
    const double d_true = tr.segment<2>(5).norm();
    const double err = std::fabs(e.obstacle_distance_m - d_true);
    const double ts = e.t_s - sr.t_start;
    EXPECT_GT(e.obstacle_distance_m, 0.5 * d_true) << "dragged towards 0 at t=" << ts;
    if (ts > 2.0 && ts < 6.0) worst_during = std::max(worst_during, err);
    if (ts > 6.5) worst_after = std::max(worst_after, err);
  }
  std::printf(
      "[sonar dropouts] %ld zeros counted as dropouts; worst distance error %.3f m "
      "during the failures, %.3f m after recovery\n",
      st.dropouts, worst_during, worst_after);
  EXPECT_LT(worst_during, 0.15);
  EXPECT_LT(worst_after, 0.05);
}

TEST(WheelchairEkf, ShuffledArrivalOrderGivesTheSameEstimate) {
  const SynthRun sr = synthesize(nominal(), curvyDrive(6.0), 11);
  io::Recording shuffled = sr.rec;
  std::mt19937 g(99);
  std::shuffle(shuffled.encoders.begin(), shuffled.encoders.end(), g);
  std::shuffle(shuffled.imu.begin(), shuffled.imu.end(), g);
  std::shuffle(shuffled.motors.begin(), shuffled.motors.end(), g);
  std::shuffle(shuffled.sonar.begin(), shuffled.sonar.end(), g);
  // A gyro sample and a sonar sample at exactly an encoder time (tie broken by priority).
  shuffled.imu.push_back({sr.rec.encoders[100].t_s, 0.01});
  shuffled.sonar.push_back({sr.rec.encoders[100].t_s, 2.0});
  io::Recording ordered = sr.rec;
  ordered.imu.push_back({sr.rec.encoders[100].t_s, 0.01});
  ordered.sonar.push_back({sr.rec.encoders[100].t_s, 2.0});
  for (auto kind : {FilterKind::Physics, FilterKind::Baseline}) {
    EkfOptions opt;
    opt.filter = kind;
    const EstimationResult a = runEstimator(ordered, nominal(), opt);
    const EstimationResult b = runEstimator(shuffled, nominal(), opt);
    ASSERT_EQ(a.estimates.size(), b.estimates.size());
    EXPECT_EQ(a.final().x, b.final().x);
    EXPECT_EQ(a.final().P, b.final().P);
  }
}

TEST(WheelchairEkf, GatingRejectsAndCountsGrossOutliers) {
  const SynthRun sr = synthesize(nominal(), curvyDrive(6.0), 5);
  io::Recording bad = sr.rec;
  const double t_gyro = bad.imu[300].t_s;
  bad.imu[300].gyro_z_rad_s += 3.0;  // 600 sigma
  std::size_t is = 30;
  while (is < bad.sonar.size() && !(bad.sonar[is].range_m > 0.5 && bad.sonar[is].range_m < 2.5))
    ++is;
  ASSERT_LT(is, bad.sonar.size());
  const double t_sonar = bad.sonar[is].t_s;
  bad.sonar[is].range_m += 1.0;  // still a valid range, 50 sigma
  EkfOptions opt;
  const EstimationResult clean = runEstimator(sr.rec, nominal(), opt);
  const EstimationResult res = runEstimator(bad, nominal(), opt);
  EXPECT_EQ(res.stats(Sensor::Gyro).rejected, clean.stats(Sensor::Gyro).rejected + 1);
  EXPECT_EQ(res.stats(Sensor::Sonar).rejected, clean.stats(Sensor::Sonar).rejected + 1);
  bool saw_gyro = false, saw_sonar = false;
  for (const auto& r : res.rejected) {
    if (r.sensor == Sensor::Gyro && r.t_s == t_gyro) {
      saw_gyro = true;
      EXPECT_GT(r.nis, 1e4);
      EXPECT_GT(r.nis, r.gate);
    }
    if (r.sensor == Sensor::Sonar && r.t_s == t_sonar) saw_sonar = true;
  }
  EXPECT_TRUE(saw_gyro);
  EXPECT_TRUE(saw_sonar);
  // The outliers did not touch the estimate: same as without those two samples (up to the
  // integrator tolerance: removing them removes two integration breakpoints).
  io::Recording without = sr.rec;
  without.imu.erase(without.imu.begin() + 300);
  without.sonar.erase(without.sonar.begin() + static_cast<long>(is));
  const EstimationResult removed = runEstimator(without, nominal(), opt);
  EXPECT_LT((res.final().x - removed.final().x).cwiseAbs().maxCoeff(), 1e-5);
  // Without gating the gyro outlier would have been applied.
  opt.gate_probability = 0;
  const EstimationResult ungated = runEstimator(bad, nominal(), opt);
  EXPECT_EQ(ungated.stats(Sensor::Gyro).rejected, 0);
  EXPECT_GT((ungated.final().x - clean.final().x).cwiseAbs().maxCoeff(), 1e-4);
}

TEST(WheelchairEkf, ExactEncoderModelBeatsTheNaiveOne) {
  // Strong accelerations make the interval mean differ from the speed at its end. Gyro off:
  // omega comes from the encoders too.
  SynthOptions so = curvyDrive(10.0);
  so.q_v = 0.5;
  so.q_omega = 0.5;
  so.start_pause_s = 0.0;
  double nis[2], rms_v[2], rms_w[2];
  for (int k = 0; k < 2; ++k) {
    EkfOptions opt;
    opt.q_v_m2_s3 = 0.5;
    opt.q_omega_rad2_s3 = 0.5;
    opt.use_gyro = false;
    opt.gate_probability = 0;
    opt.encoder_model = k == 0 ? EncoderMeasurementModel::Mean : EncoderMeasurementModel::Instant;
    double sum = 0, ev = 0, ew = 0;
    long n = 0, ne = 0;
    for (int run = 0; run < 5; ++run) {
      const SynthRun sr = synthesize(nominal(), so, 50 + run);
      const EstimationResult res = runEstimator(sr.rec, nominal(), opt);
      sum += res.stats(Sensor::Encoders).nis_sum;
      n += res.stats(Sensor::Encoders).nis_count;
      for (const auto& e : res.estimates) {
        const TruthPoint& t = sr.at(e.t_s);
        ev += std::pow(e.x(0) - t.v, 2);
        ew += std::pow(e.x(1) - t.omega, 2);
        ++ne;
      }
    }
    nis[k] = sum / n;
    rms_v[k] = std::sqrt(ev / ne);
    rms_w[k] = std::sqrt(ew / ne);
  }
  std::printf(
      "[encoder model] exact mean model: encoder NIS %.3f (2 dof), RMS error v %.4f m/s, "
      "omega %.4f rad/s; naive end-of-interval model: NIS %.3f, RMS v %.4f, omega %.4f\n",
      nis[0], rms_v[0], rms_w[0], nis[1], rms_v[1], rms_w[1]);
  EXPECT_NEAR(nis[0], 2.0, 0.15);
  EXPECT_LT(rms_v[0], rms_v[1]);
  EXPECT_LT(rms_w[0], rms_w[1]);
}

TEST(Baseline, RunsAndIsWorseThanThePhysicsEkfWithAFaultyEncoder) {
  // The paper's fault (IV.A): a mis-scaled left encoder. (The project simulator is not linked
  // into test_estimation - tests link their own module only - so the synthetic generator is
  // used, with the fault on the left ticks.)
  SynthOptions so = curvyDrive(40.0);
  so.currents = curvyCurrents(0.8, 2.0, 0.5);
  so.left_encoder_scale = 0.9;
  const SynthRun sr = synthesize(nominal(), so, 21);
  auto posError = [&](const EstimateSample& e) {
    const TruthPoint& t = sr.at(e.t_s);
    return std::hypot(e.x(2) - t.x, e.x(3) - t.y);
  };
  auto rmsError = [&](const EstimationResult& r) {
    double s = 0;
    for (const auto& e : r.estimates) s += std::pow(posError(e), 2);
    return std::sqrt(s / r.estimates.size());
  };
  EkfOptions opt;
  opt.output_rate_hz = 10;
  const EstimationResult phys = runEstimator(sr.rec, nominal(), opt);
  opt.filter = FilterKind::Baseline;
  const EstimationResult base = runEstimator(sr.rec, nominal(), opt);
  ASSERT_FALSE(base.estimates.empty());
  EXPECT_EQ(base.filter, "baseline");
  const auto dr =
      deadReckoningEncoders(sr.rec.encoders, nominal().encoders.params, nominal().vehicle.geom);
  const auto eg = deadReckoningEncoderGyro(sr.rec.encoders, sr.rec.imu, nominal().encoders.params,
                                           nominal().vehicle.geom);
  const TruthPoint& tl = sr.truth.back();
  const double e_phys = posError(phys.final()), e_base = posError(base.final());
  std::printf(
      "[faulty left encoder x0.9, %.0f s drive, %.1f m path] final position error: "
      "physics EKF %.3f m, baseline %.3f m, encoders only %.3f m, encoder v + gyro "
      "%.3f m; RMS position error physics %.3f m, baseline %.3f m; encoder updates "
      "rejected physics %ld/%ld, baseline %ld/%ld\n",
      so.duration_s, pathLength(eg), e_phys, e_base,
      std::hypot(dr.back().x_m - tl.x, dr.back().y_m - tl.y),
      std::hypot(eg.back().x_m - tl.x, eg.back().y_m - tl.y), rmsError(phys), rmsError(base),
      phys.stats(Sensor::Encoders).rejected,
      phys.stats(Sensor::Encoders).rejected + phys.stats(Sensor::Encoders).used,
      base.stats(Sensor::Encoders).rejected,
      base.stats(Sensor::Encoders).rejected + base.stats(Sensor::Encoders).used);
  EXPECT_LT(rmsError(phys), rmsError(base));
  EXPECT_LT(e_phys, e_base);
  // With healthy encoders the baseline is a sensible filter too.
  so.left_encoder_scale = 1.0;
  const SynthRun ok = synthesize(nominal(), so, 21);
  const EstimationResult base_ok = runEstimator(ok.rec, nominal(), opt);
  const TruthPoint& to = ok.at(base_ok.final().t_s);
  EXPECT_LT(std::hypot(base_ok.final().x(2) - to.x, base_ok.final().x(3) - to.y), 0.3);
}

TEST(DeadReckoning, ArcIntegrationIsExactForConstantSpeeds) {
  // Constant v, omega: encoder ticks of an exact circle; the arc formula reproduces it.
  const auto& cfg = nominal();
  const double v = 0.5, om = 0.3, r = cfg.vehicle.geom.wheel_radius_m,
               lw = cfg.vehicle.geom.track_width_m;
  std::vector<io::EncoderSample> enc;
  for (int k = 0; k <= 500; ++k) {
    const double t = 0.02 * k;
    auto ticks = [&](double u) {
      return static_cast<int32_t>(std::llround(u * t / r / cfg.encoders.params.wheelRadPerTick()));
    };
    enc.push_back({t, ticks(v + 0.5 * lw * om), ticks(v - 0.5 * lw * om)});
  }
  const auto dr = deadReckoningEncoders(enc, cfg.encoders.params, cfg.vehicle.geom);
  const double T = 10.0;
  const Eigen::Vector3d exact((v / om) * std::sin(om * T), (v / om) * (1 - std::cos(om * T)),
                              om * T);
  EXPECT_NEAR(dr.back().x_m, exact(0), 2e-3);
  EXPECT_NEAR(dr.back().y_m, exact(1), 2e-3);
  EXPECT_NEAR(dr.back().phi_rad, exact(2), 2e-3);
  // Encoder v + a perfect gyro gives the same circle.
  std::vector<io::ImuSample> imu;
  for (int k = 0; k <= 1000; ++k) imu.push_back({0.01 * k + 0.005, om});
  const auto eg = deadReckoningEncoderGyro(enc, imu, cfg.encoders.params, cfg.vehicle.geom);
  EXPECT_NEAR(eg.back().x_m, exact(0), 2e-3);
  EXPECT_NEAR(eg.back().y_m, exact(1), 2e-3);
  EXPECT_NEAR(pathLength(dr), v * T, 2e-3);
}

TEST(EkfOptions, ConfigRoundTripAndErrors) {
  EkfOptions a;
  a.filter = FilterKind::Baseline;
  a.obstacle_form = ObstacleFormOption::Polar;
  a.cvode.method = CvodeOptions::Method::Bdf;
  a.q_v_m2_s3 = 0.123;
  a.use_pozyx = true;
  mrpt::config::CConfigFileMemory ini;
  a.saveToConfig(ini);
  EkfOptions b;
  b.loadFromConfig(ini);
  EXPECT_EQ(b.filter, FilterKind::Baseline);
  EXPECT_EQ(b.obstacle_form, ObstacleFormOption::Polar);
  EXPECT_EQ(b.cvode.method, CvodeOptions::Method::Bdf);
  EXPECT_DOUBLE_EQ(b.q_v_m2_s3, 0.123);
  EXPECT_TRUE(b.use_pozyx);
  mrpt::config::CConfigFileMemory bad;
  bad.write("estimator", "obstacle_form", "spherical");
  EXPECT_THROW(b.loadFromConfig(bad), std::runtime_error);
  mrpt::config::CConfigFileMemory neg;
  neg.write("estimator", "q_v_m2_s3", "-1");
  EXPECT_THROW(b.loadFromConfig(neg), std::runtime_error);
}

TEST(EkfOptions, TheShippedConfigurationLoads) {
  const auto cfg =
      config::WheelchairConfig::load(std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini");
  EkfOptions o;
  o.loadFromConfig(cfg.ini());
  EXPECT_EQ(o.filter, FilterKind::Physics);
  EXPECT_FALSE(o.use_pozyx);
}

// The estimates' allocator: big blocks 2 MiB-aligned (huge-page candidates), small ones
// ordinary; both usable to their last byte and released (ASan/valgrind would flag misuse).
TEST(LargeBufferAllocator, BigBlocksAreHugePageAlignedAndSmallOnesOrdinary) {
  const std::size_t big = (std::size_t(9) << 20) + 123;
  auto* p = static_cast<unsigned char*>(allocateLargeBuffer(big));
  ASSERT_NE(p, nullptr);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(p) % (std::size_t(2) << 20), 0u);
  p[0] = 1;
  p[big - 1] = 2;
  EXPECT_EQ(p[0] + p[big - 1], 3);
  freeLargeBuffer(p);
  auto* q = static_cast<unsigned char*>(allocateLargeBuffer(100));
  ASSERT_NE(q, nullptr);
  q[99] = 7;
  freeLargeBuffer(q);
  // A result vector grows through it like any std::vector.
  EstimateSeries v;
  for (int i = 0; i < 20000; ++i) {
    EstimateSample s;
    s.t_s = i;
    v.push_back(s);
  }
  EXPECT_EQ(v.size(), 20000u);
  EXPECT_EQ(v.back().t_s, 19999);
  EXPECT_GE(v.capacity() * sizeof(EstimateSample), std::size_t(4) << 20);
}
