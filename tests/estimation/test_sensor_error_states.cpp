// Sensor-error states of the physics CD-EKF (encoder scales k_s, k_d and gyro bias b_g;
// WheelchairEkf.h, docs/estimation.md "Sensor-error states"): Jacobians against finite
// differences, a faulty encoder estimated on a drive that excites it, and no invented scale
// on drives that cannot excite it.
#include "SyntheticDrive.h"

#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/estimation/WheelchairEkf.h"

#include <gtest/gtest.h>

#include <array>

#include <Eigen/Cholesky>

#include <cmath>

using namespace wheelchair;
using namespace wheelchair::estimation;
using namespace wheelchair::estimation::test;

namespace {

/// The scale states OPEN from the start (what is tested here is the states themselves; the
/// shipped detection-first mode, closed until an alarm, is tested at the end).
EkfOptions withScales() {
  EkfOptions opt;
  opt.estimate_encoder_scales = true;
  opt.open_sensor_errors_on_alarm = false;
  opt.output_rate_hz = 5;
  return opt;
}

const char* priorName(EncoderFaultPrior p) {
  return p == EncoderFaultPrior::Either  ? "either"
         : p == EncoderFaultPrior::Short ? "short"
                                         : "none";
}

/// Distance (m) of the filter's final position from the truth at that time.
double finalPositionError(const SynthRun& sr, const EstimationResult& r) {
  const TruthPoint& t = sr.at(r.final().t_s);
  return std::hypot(r.final().x(2) - t.x, r.final().x(3) - t.y);
}

void printScales(const char* label, const SensorErrorEstimate& e) {
  std::printf("[%s] k_R = %.4f +- %.4f, k_L = %.4f +- %.4f\n", label, e.encoder_scale_right,
              e.encoder_scale_right_sd, e.encoder_scale_left, e.encoder_scale_left_sd);
}

/// The drives that cannot excite the common scale k_s (observable only while turning): 20 s
/// straight (equal currents: only the ratio k_R / k_L is observable, and it is 1) and 20 s
/// standing still (nothing is). No process noise in the truth: the generator's white
/// accelerations would make the chair turn and so excite the scales.
struct UnexcitingDrive {
  bool standing;
  SynthOptions so;
};
std::array<UnexcitingDrive, 2> straightAndStanding() {
  SynthOptions straight;
  straight.q_v = straight.q_omega = 0.0;
  straight.duration_s = 20.0;
  straight.currents = curvyCurrents(0.3, 2.4, 0.0);  // i_R = i_L: no turning
  SynthOptions standing = straight;
  standing.currents = [](double) { return Eigen::Vector2d::Zero(); };
  return {UnexcitingDrive{false, straight}, UnexcitingDrive{true, standing}};
}

}  // namespace

TEST(SensorErrorStates, EncoderModelJacobiansMatchFiniteDifferences) {
  const double lw = 0.55, eps = 1e-6;
  for (const Eigen::Vector2d& a : {Eigen::Vector2d(0.7, 0.3), Eigen::Vector2d(-0.2, 0.6)}) {
    const double ks = 0.97, kd = 0.04;
    Eigen::Matrix2d dz_da, dz_dk;
    const Eigen::Vector2d z = scaledEncoderSpeeds(a, ks, kd, lw, &dz_da, &dz_dk);
    // Per-wheel definition: u_R = k_R (v + omega l/2), u_L = k_L (v - omega l/2).
    const double kR = ks + 0.5 * kd, kL = ks - 0.5 * kd;
    const double uR = kR * (a(0) + 0.5 * lw * a(1)), uL = kL * (a(0) - 0.5 * lw * a(1));
    EXPECT_NEAR(z(0), 0.5 * (uR + uL), 1e-12);
    EXPECT_NEAR(z(1), (uR - uL) / lw, 1e-12);
    for (int j = 0; j < 2; ++j) {
      Eigen::Vector2d da = Eigen::Vector2d::Zero();
      da(j) = eps;
      const Eigen::Vector2d num =
          (scaledEncoderSpeeds(a + da, ks, kd, lw) - scaledEncoderSpeeds(a - da, ks, kd, lw)) /
          (2 * eps);
      EXPECT_LT((num - dz_da.col(j)).cwiseAbs().maxCoeff(), 1e-8);
    }
    const Eigen::Vector2d num_s =
        (scaledEncoderSpeeds(a, ks + eps, kd, lw) - scaledEncoderSpeeds(a, ks - eps, kd, lw)) /
        (2 * eps);
    const Eigen::Vector2d num_d =
        (scaledEncoderSpeeds(a, ks, kd + eps, lw) - scaledEncoderSpeeds(a, ks, kd - eps, lw)) /
        (2 * eps);
    EXPECT_LT((num_s - dz_dk.col(0)).cwiseAbs().maxCoeff(), 1e-8);
    EXPECT_LT((num_d - dz_dk.col(1)).cwiseAbs().maxCoeff(), 1e-8);
  }
}

TEST(SensorErrorStates, ProcessJacobianOfTheAugmentedModelMatchesFiniteDifferences) {
  model::FilterModelParams p;
  p.ode = model::odeCoefficients(nominal().vehicle.geom, model::lumpedTheta(nominal().vehicle));
  const model::FilterModel fm(p);
  Eigen::Matrix<double, 7, 1> q = Eigen::Matrix<double, 7, 1>::Constant(1e-3);
  const WheelchairProcessModel pm(fm, q, 1e-3, Eigen::Vector3d(1e-7, 4e-7, 1e-8));
  ASSERT_EQ(pm.stateDim(), 12);
  Eigen::VectorXd x(12);
  x << 0.6, 0.2, 1.0, -0.5, 0.3, 2.0, 0.4, 0.01, 0.002, 0.98, 0.03, 0.002;
  const Eigen::VectorXd u = Eigen::Vector2d(3.0, 2.0);
  Eigen::MatrixXd F;
  pm.F(x, u, F);
  Eigen::VectorXd fp, fm_;
  for (int j = 0; j < 12; ++j) {
    const double eps = 1e-6;
    Eigen::VectorXd xp = x, xm = x;
    xp(j) += eps;
    xm(j) -= eps;
    pm.f(xp, u, fp);
    pm.f(xm, u, fm_);
    EXPECT_LT(((fp - fm_) / (2 * eps) - F.col(j)).cwiseAbs().maxCoeff(), 1e-6) << "column " << j;
  }
  Eigen::VectorXd xd;
  pm.f(x, u, xd);
  EXPECT_EQ(xd.tail<3>(), Eigen::Vector3d::Zero());  // random walks: no drift
  Eigen::MatrixXd Q;
  pm.Q(x, u, Q);
  EXPECT_DOUBLE_EQ(Q(kIdxEncScaleS, kIdxEncScaleS), 1e-7);
  EXPECT_DOUBLE_EQ(Q(kIdxEncScaleD, kIdxEncScaleD), 4e-7);
  EXPECT_DOUBLE_EQ(Q(kIdxGyroBias, kIdxGyroBias), 1e-8);
}

TEST(SensorErrorStates, AShortLeftEncoderIsEstimatedOnACurvyDrive) {
  SynthOptions so;
  so.duration_s = 40.0;
  so.currents = curvyCurrents(0.8, 2.0, 0.6);
  so.left_encoder_scale = 0.95;
  const SynthRun sr = synthesize(nominal(), so, 31);
  const EstimationResult res = runEstimator(sr.rec, nominal(), withScales());
  const SensorErrorEstimate& e = res.sensor_errors;
  ASSERT_TRUE(e.present);
  printScales("left encoder x0.95", e);
  EXPECT_NEAR(e.encoder_scale_left, 0.95, std::max(3 * e.encoder_scale_left_sd, 0.005));
  EXPECT_NEAR(e.encoder_scale_right, 1.0, std::max(3 * e.encoder_scale_right_sd, 0.005));
  EXPECT_LT(e.encoder_scale_left_sd, 0.01);  // learnt, not the prior 0.05
  // And it pays: the final pose is better than without the states.
  EkfOptions off = withScales();
  off.estimate_encoder_scales = false;
  const EstimationResult res0 = runEstimator(sr.rec, nominal(), off);
  auto err = [&](const EstimationResult& r) { return finalPositionError(sr, r); };
  std::printf("final position error with the states %.3f m, without %.3f m\n", err(res), err(res0));
  EXPECT_LT(err(res), err(res0));
}

TEST(SensorErrorStates, NoScaleIsInventedOnStraightOrStandingDrives) {
  // Without the fault prior (encoder_fault_prior = none) the common scale must keep its
  // prior sd; with it (either, the default; short) it may shrink to the healthy-encoder sd the
  // prior states once the wheels are seen to agree, but not below it, and its mean must stay 1.
  for (const EncoderFaultPrior prior : {EncoderFaultPrior::None, EncoderFaultPrior::Either}) {
    const bool fault_prior = prior != EncoderFaultPrior::None;
    EkfOptions opt = withScales();
    opt.encoder_fault_prior = prior;
    const double prior_sd = opt.encoder_scale_sigma;
    // Straight (k_s must stay at its prior mean and keep about its prior sd) and standing.
    for (const auto& [is_standing, so] : straightAndStanding()) {
      const SynthRun sr = synthesize(nominal(), so, 5);
      const EstimationResult res = runEstimator(sr.rec, nominal(), opt);
      const SensorErrorEstimate& e = res.sensor_errors;
      ASSERT_TRUE(e.present);
      const double ks = 0.5 * (e.encoder_scale_right + e.encoder_scale_left);
      printScales(is_standing ? "standing" : "straight", e);
      // Within a small fraction of the prior sd: nothing was read into the common scale.
      EXPECT_NEAR(ks, 1.0, 0.1 * prior_sd);
      EXPECT_NEAR(e.encoder_scale_right, 1.0, e.encoder_scale_right_sd);
      EXPECT_NEAR(e.encoder_scale_left, 1.0, e.encoder_scale_left_sd);
      // The common scale keeps (about) its prior uncertainty: sd(k_R) >= sd(k_s) >= 0.9
      // prior/sqrt(2); with the fault prior, once moving, the healthy sd and no less.
      if (!fault_prior || is_standing)
        EXPECT_GT(e.encoder_scale_right_sd, 0.9 * prior_sd / std::sqrt(2.0));
      else
        EXPECT_GT(e.encoder_scale_right_sd, 0.9 * opt.healthy_encoder_scale_sigma);
    }
  }
}

TEST(SensorErrorStates, GyroBiasIsEstimatedAndOffMeansTheOldFilter) {
  SynthOptions so;
  so.duration_s = 20.0;
  so.currents = curvyCurrents(0.3, 2.0, 0.5);
  const SynthRun sr = synthesize(nominal(), so, 9);
  io::Recording biased = sr.rec;
  for (auto& s : biased.imu) s.gyro_z_rad_s += 0.02;
  EkfOptions opt;
  opt.estimate_gyro_bias = true;
  const EstimationResult res = runEstimator(biased, nominal(), opt);
  ASSERT_TRUE(res.sensor_errors.present);
  EXPECT_NEAR(res.sensor_errors.gyro_bias_rad_s, 0.02, 3 * res.sensor_errors.gyro_bias_sd_rad_s);
  EXPECT_LT(res.sensor_errors.gyro_bias_sd_rad_s, 0.003);
  // Everything off and nominal: the 9-state filter, bit-identical to a configuration that
  // never heard of the states.
  const EstimationResult a = runEstimator(sr.rec, nominal(), EkfOptions{});
  EXPECT_FALSE(a.sensor_errors.present);
  EkfOptions fixed;
  fixed.encoder_scale_left = 0.95;  // a configured (fixed) calibration switches the states on
  EXPECT_TRUE(fixed.sensorErrorStates());
  EXPECT_FALSE(EkfOptions{}.sensorErrorStates());
}

namespace {

/// Monte-Carlo mean position NEES (x, y: 2 dof) of the physics filter with the encoder scale
/// states: per output time the mean over `runs` seeded drives, then its mean over the times.
/// The drive goes straight for 6 s (the common scale unobservable: its uncertainty must show
/// in the pose covariance) and then turns.
double meanPositionNees(double left_scale, EncoderFaultPrior prior, int runs) {
  EkfOptions opt = withScales();
  opt.encoder_fault_prior = prior;
  opt.q_xy_m2_s = opt.q_phi_rad2_s = 1e-9;  // the truth's pose kinematics are exact
  opt.initial_sigma_xy_m = opt.initial_sigma_phi_rad = 1e-6;
  std::vector<double> sum;
  for (int run = 0; run < runs; ++run) {
    SynthOptions so;
    so.duration_s = 12.0;
    so.left_encoder_scale = left_scale;
    so.currents = [](double t) {
      return t < 6.0 ? Eigen::Vector2d(2.0, 2.0) : Eigen::Vector2d(2.4, 1.4);
    };
    const SynthRun sr = synthesize(nominal(), so, 700 + run);
    const EstimationResult res = runEstimator(sr.rec, nominal(), opt);
    if (sum.empty()) sum.assign(res.estimates.size(), 0.0);
    for (std::size_t i = 0; i < res.estimates.size() && i < sum.size(); ++i) {
      const EstimateSample& e = res.estimates[i];
      const TruthPoint& t = sr.at(e.t_s);
      const Eigen::Vector2d err(e.x(2) - t.x, e.x(3) - t.y);
      sum[i] += err.dot(e.P.block<2, 2>(2, 2).ldlt().solve(err)) / runs;
    }
  }
  double m = 0;
  int n = 0;
  for (std::size_t i = 1; i < sum.size(); ++i, ++n) m += sum[i];  // i = 0: the start
  return m / n;
}

}  // namespace

TEST(SensorErrorStates, PoseCovarianceStaysHonestOnCleanAndFaultyDrives) {
  // Consistent: NEES ~ 2. Over-confident (the pose not knowing that it was driven at an
  // unknown scale) would be >> 2: it was ~200 on the faulty three-task drive before the
  // scale's correlation with the pose was kept. Pessimistic is allowed on the clean drive
  // (the prior says a scale MAY be off by the healthy encoder's 0.5 %).
  constexpr int kRuns = 8;
  // The left encoder reading 5 % LONG too: the either-side prior assumes no direction.
  for (const EncoderFaultPrior prior : {EncoderFaultPrior::None, EncoderFaultPrior::Either})
    for (const double left : {1.0, 0.95, 1.05}) {
      const double nees = meanPositionNees(left, prior, kRuns);
      std::printf("[left scale %.2f, fault prior %s] mean position NEES %.2f (2 dof)\n", left,
                  priorName(prior), nees);
      EXPECT_LT(nees, 4.0);
      EXPECT_GT(nees, 0.02);
    }
}

// Fault detection and isolation (open_sensor_errors_on_alarm, the default): the states are
// closed until their sensor's CUSUM alarms.

TEST(SensorErrorStates, ClosedStatesGiveTheStatesOffEstimatesOnACleanDrive) {
  SynthOptions so;
  so.duration_s = 20.0;
  so.currents = curvyCurrents(0.8, 2.0, 0.6);
  const SynthRun sr = synthesize(nominal(), so, 31);
  EkfOptions on;  // detection first: both groups closed until an alarm
  on.estimate_encoder_scales = on.estimate_gyro_bias = true;
  on.closed_encoder_scale_sigma = 0.0;  // held exactly (no consider variance)
  on.output_rate_hz = 5;
  on.cvode.rel_tol = 1e-9;  // tight: the difference below is then the filters', not CVODE's
  on.cvode.abs_tol_state = on.cvode.abs_tol_cov = 1e-12;
  ASSERT_TRUE(on.open_sensor_errors_on_alarm);
  EkfOptions off = on;
  off.estimate_encoder_scales = off.estimate_gyro_bias = false;
  const EstimationResult a = runEstimator(sr.rec, nominal(), on);
  const EstimationResult b = runEstimator(sr.rec, nominal(), off);
  ASSERT_TRUE(a.sensor_errors.present);
  EXPECT_FALSE(b.sensor_errors.present);
  for (const HealthEvent& h : a.health) EXPECT_EQ(h.sensor, "sonar") << h.text;  // no alarm
  // Held at the prior: exactly 1 and 0 with zero sd.
  EXPECT_EQ(a.sensor_errors.encoder_scale_left, 1.0);
  EXPECT_EQ(a.sensor_errors.encoder_scale_left_sd, 0.0);
  EXPECT_EQ(a.sensor_errors.gyro_bias_sd_rad_s, 0.0);
  // The 12-state filter with closed states is the 9-state one, to CVODE's tolerance (its
  // error control sees three more components: at the default rel_tol 1e-4 the estimates differ
  // by up to 8e-5, at 1e-9 by 2e-7).
  ASSERT_EQ(a.estimates.size(), b.estimates.size());
  Eigen::Matrix<double, 7, 1> dmax = Eigen::Matrix<double, 7, 1>::Zero();
  for (std::size_t i = 0; i < a.estimates.size(); ++i)
    dmax = dmax.cwiseMax((a.estimates[i].x - b.estimates[i].x).cwiseAbs());
  std::printf("closed states: largest difference to the states-off filter, v omega x y phi px py:");
  for (int j = 0; j < 7; ++j) std::printf(" %.1e", dmax(j));
  std::printf("\n");
  EXPECT_LT(dmax.maxCoeff(), 1e-6);
}

TEST(SensorErrorStates, ClosedStatesAreConsideredNotLearned) {
  // The shipped closed states are consider (Schmidt) states: their means never move and their
  // variance stays the healthy prior (0.5 % per wheel), but the pose's covariance carries
  // them: its sd grows with the distance driven at an uncertain scale, above that of the
  // filter without the states, while the estimates stay within millimetres of it.
  SynthOptions so;
  so.duration_s = 20.0;
  so.currents = curvyCurrents(0.8, 2.0, 0.6);
  const SynthRun sr = synthesize(nominal(), so, 31);
  EkfOptions on;
  on.estimate_encoder_scales = on.estimate_gyro_bias = true;
  on.output_rate_hz = 5;
  ASSERT_TRUE(on.open_sensor_errors_on_alarm);
  ASSERT_EQ(on.closed_encoder_scale_sigma, 0.005);
  EkfOptions off = on;
  off.estimate_encoder_scales = off.estimate_gyro_bias = false;
  const EstimationResult a = runEstimator(sr.rec, nominal(), on);
  const EstimationResult b = runEstimator(sr.rec, nominal(), off);
  for (const HealthEvent& h : a.health) EXPECT_EQ(h.sensor, "sonar") << h.text;  // no alarm
  EXPECT_EQ(a.sensor_errors.encoder_scale_left, 1.0);
  EXPECT_EQ(a.sensor_errors.encoder_scale_right, 1.0);
  EXPECT_NEAR(a.sensor_errors.encoder_scale_left_sd, 0.005, 1e-12);
  EXPECT_EQ(a.sensor_errors.gyro_bias_sd_rad_s, 0.0);
  ASSERT_EQ(a.estimates.size(), b.estimates.size());
  double dmax = 0;
  for (std::size_t i = 0; i < a.estimates.size(); ++i)
    dmax = std::max(dmax, (a.estimates[i].x.segment<2>(2) - b.estimates[i].x.segment<2>(2)).norm());
  // A common scale error with the heading from the gyro scales the track about its start:
  // position error = dk_s (p - p0), so its sd is 0.35 % (0.5 % / sqrt 2) of the displacement.
  const TruthPoint& end = sr.at(a.final().t_s);
  const double disp_m = std::hypot(end.x - sr.truth.front().x, end.y - sr.truth.front().y);
  const double sd_on = std::sqrt(a.final().P(2, 2) + a.final().P(3, 3));
  const double sd_off = std::sqrt(b.final().P(2, 2) + b.final().P(3, 3));
  std::printf(
      "consider states: displacement %.2f m, final position sd %.4f m (states off "
      "%.4f m), largest position difference %.4f m\n",
      disp_m, sd_on, sd_off, dmax);
  EXPECT_LT(dmax, 0.005);
  // The scale's share, in quadrature with the states-off sd: at least 80 % of it.
  EXPECT_GT(sd_on * sd_on, sd_off * sd_off + std::pow(0.8 * 0.0035 * disp_m, 2));
}

TEST(SensorErrorStates, AnEncoderFaultOpensTheScalesShortOrLong) {
  // No assumption about the direction: a left encoder 5 % short and one 5 % long are both
  // detected (the alarm opens the scales), estimated and corrected.
  SynthOptions so;
  so.duration_s = 40.0;
  so.currents = curvyCurrents(0.8, 2.0, 0.6);
  EkfOptions on;
  on.estimate_encoder_scales = true;
  on.output_rate_hz = 5;
  EkfOptions off = on;
  off.estimate_encoder_scales = false;
  for (const double left : {0.95, 1.05}) {
    so.left_encoder_scale = left;
    const SynthRun sr = synthesize(nominal(), so, 31);
    const EstimationResult res = runEstimator(sr.rec, nominal(), on);
    const EstimationResult res0 = runEstimator(sr.rec, nominal(), off);
    const SensorErrorEstimate& e = res.sensor_errors;
    ASSERT_FALSE(res.health.empty());
    EXPECT_EQ(res.health.front().kind, "inconsistent");
    EXPECT_EQ(res.health.front().sensor, "encoders");
    EXPECT_NEAR(e.encoder_scale_left, left, std::max(3 * e.encoder_scale_left_sd, 0.005));
    EXPECT_NEAR(e.encoder_scale_right, 1.0, std::max(3 * e.encoder_scale_right_sd, 0.005));
    auto err = [&](const EstimationResult& r) { return finalPositionError(sr, r); };
    std::printf("[left x%.2f] k_L = %.4f +- %.4f; final position error %.3f m (states off %.3f)\n",
                left, e.encoder_scale_left, e.encoder_scale_left_sd, err(res), err(res0));
    EXPECT_LT(err(res), 0.5 * err(res0));
  }
}

TEST(SensorErrorStates, AHealthyChairsRadiiAreLearnedBeforeAnyAlarm) {
  // learn_healthy_encoder_scales = both: the wheels' radii of a healthy chair (0.4 % long
  // right, 0.3 % short left: below any alarm) are learned from the gyro while the chair moves
  // and turns (k_d from z_omega - omega = k_d a_v / l_w, k_s from k_s a_omega), without an
  // alarm; with none they stay consider states at 1 until the encoders' CUSUM alarms on the
  // 0.7 % difference, and the pose pays for the radii until then.
  SynthOptions so;
  so.duration_s = 40.0;
  so.currents = curvyCurrents(0.8, 2.0, 0.6);
  so.right_encoder_scale = 1.004;
  so.left_encoder_scale = 0.997;
  const SynthRun sr = synthesize(nominal(), so, 31);
  EkfOptions on;  // the shipped alarm mode
  on.estimate_encoder_scales = on.estimate_gyro_bias = true;
  on.output_rate_hz = 5;
  ASSERT_TRUE(on.open_sensor_errors_on_alarm);
  EkfOptions off = on;
  on.learn_healthy_encoder_scales = HealthyScaleLearning::Both;
  const EstimationResult a = runEstimator(sr.rec, nominal(), on);
  const EstimationResult b = runEstimator(sr.rec, nominal(), off);
  for (const HealthEvent& h : a.health) EXPECT_EQ(h.sensor, "sonar") << h.text;  // no alarm
  const SensorErrorEstimate& e = a.sensor_errors;
  printScales("healthy radii learned", e);
  EXPECT_NEAR(e.encoder_scale_right, 1.004, 3 * e.encoder_scale_right_sd);
  EXPECT_NEAR(e.encoder_scale_left, 0.997, 3 * e.encoder_scale_left_sd);
  // Learned: well below the closed prior's 0.5 % per wheel.
  EXPECT_LT(e.encoder_scale_right_sd, 0.5 * on.closed_encoder_scale_sigma);
  EXPECT_LT(e.encoder_scale_left_sd, 0.5 * on.closed_encoder_scale_sigma);
  auto err = [&](const EstimationResult& r) { return finalPositionError(sr, r); };
  std::printf("final position error learned %.4f m, consider states %.4f m\n", err(a), err(b));
  EXPECT_LT(err(a), err(b));
}

TEST(SensorErrorStates, LearningAHealthyChairsRadiiInventsNoScaleOnStraightOrStandingDrives) {
  // learn_healthy_encoder_scales = both on a nominal chair: driving straight excites k_d only
  // (it must stay at 0), standing excites nothing, and the common scale k_s, observable only
  // while turning, must keep its mean 1 and its prior sd (0.5 % / sqrt 2) on both.
  EkfOptions opt;
  opt.estimate_encoder_scales = true;
  opt.output_rate_hz = 5;
  opt.learn_healthy_encoder_scales = HealthyScaleLearning::Both;
  ASSERT_TRUE(opt.open_sensor_errors_on_alarm);
  const double ks_prior_sd = opt.closed_encoder_scale_sigma / std::sqrt(2.0);
  for (const auto& [is_standing, so] : straightAndStanding()) {
    const SynthRun sr = synthesize(nominal(), so, 5);
    const EstimationResult res = runEstimator(sr.rec, nominal(), opt);
    const SensorErrorEstimate& e = res.sensor_errors;
    ASSERT_TRUE(e.present);
    for (const HealthEvent& h : res.health) EXPECT_EQ(h.sensor, "sonar") << h.text;
    const double ks = 0.5 * (e.encoder_scale_right + e.encoder_scale_left);
    const double kd = e.encoder_scale_right - e.encoder_scale_left;
    // Each wheel's sd is at least the common scale's (k_R, k_L = k_s +- k_d / 2).
    printScales(is_standing ? "standing, learning" : "straight, learning", e);
    EXPECT_NEAR(ks, 1.0, 0.1 * ks_prior_sd);
    EXPECT_NEAR(kd, 0.0, 0.2 * opt.closed_encoder_scale_sigma);
    EXPECT_GT(e.encoder_scale_right_sd, 0.9 * ks_prior_sd);
    EXPECT_GT(e.encoder_scale_left_sd, 0.9 * ks_prior_sd);
  }
}
