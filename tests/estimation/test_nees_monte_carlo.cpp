// Monte-Carlo consistency of the SHIPPED noise model (config/wheelchair.ini [estimator], the
// process noise derived in docs/estimation.md, "Process noise from physics") on clean and on
// faulty drives: 24 seeded 12 s synthetic drives each (SyntheticDrive.h: the truth has the
// physics the noise model claims: white model error on vdot / omegadot, white wheel slip on the
// rim speeds, NO noise on the pose kinematics), mean position NEES (2 dof) and pose NEES
// (x, y, phi: 3 dof) against the 95 % chi-square band of a 24-run mean, NIS per sensor against
// the band of its mean. Faulty: the paper's left encoder 5 % short, with the encoder-scale
// states on. With the states, the truth's rolling radii are drawn from the filter's own prior
// (a Monte-Carlo over chairs, not one chair): only then is the prior's share of the covariance
// realised.
#include "SyntheticDrive.h"

#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/stats/Distributions.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

using namespace wheelchair;
using namespace wheelchair::estimation;
using namespace wheelchair::estimation::test;

namespace {

constexpr int kRuns = 24;

/// The shipped [estimator] options; the obstacle prior as in the synthetic truth.
EkfOptions shippedOptions() {
  const auto cfg =
      config::WheelchairConfig::load(std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini");
  EkfOptions o;
  o.loadFromConfig(cfg.ini());
  o.output_rate_hz = 5;
  setPriorsOfTheTruth(o, {1.5, 2.5});
  return o;
}

struct Case {
  const char* name;
  bool scale_states = false;
  double left_fault = 1.0;          ///< left ticks x this (the paper's fault: 0.95)
  bool draw_scales = false;         ///< truth scales ~ N(1, encoder_scale_sigma) per run
  double encoder_scale_sigma = -1;  ///< < 0: shipped
  /// The shipped fault detection: states closed until an alarm (consider states while closed),
  /// gyro bias as shipped; truth radii ~ N(1, closed_encoder_scale_sigma) per wheel.
  bool closed_until_alarm = false;
  double closed_encoder_scale_sigma = -1;  ///< < 0: shipped
  double truth_scale_sigma = -1;           ///< < 0: the filter's closed prior
  /// Slip of the truth and of the filter (encoder_extra_noise_m_s, m/s); < 0: shipped.
  double slip_m_s = -1;
  bool quantisation_carry = true;  ///< encoder_quantisation_carry
  /// initial_sigma_xy_m and initial_sigma_phi_rad (m, rad); < 0: shipped. The truth always
  /// starts exactly at the start frame's origin.
  double initial_pose_sigma = -1;
  /// The truth's model error on omegadot: white density (rad^2/s^3; < 0: the filter's
  /// q_omega_rad2_s3) and a slowly varying yaw acceleration of this amplitude (rad/s^2).
  double truth_q_omega = -1;
  double yaw_accel_error_rad_s2 = 0;
  double filter_q_omega = -1;  ///< q_omega_rad2_s3 of the filter; < 0: shipped
  /// The truth's yaw acceleration following the manoeuvre, -kappa v omega (1/m; 0: none), and
  /// the filter's yaw noise following it (yaw_noise_from_manoeuvre, shipped parameters).
  double truth_kappa_1_m = 0;
  bool manoeuvre_yaw_noise = false;
  double sum_mean_A = 1.6, diff_amp_A = 0.4;  ///< curvyCurrents of the drives
  double draw_sigma_closed(const EkfOptions& o) const {
    return truth_scale_sigma >= 0 ? truth_scale_sigma : o.closed_encoder_scale_sigma;
  }
};

struct McNees {
  double position = 0, pose = 0;  ///< mean over times of the run-averaged NEES
  double heading = 0;             ///< the same for phi alone (1 dof)
  std::pair<double, double> band2, band3;
  double nis_encoders = 0, nis_gyro = 0;
  std::pair<double, double> nis_band_encoders, nis_band_gyro;
};

McNees monteCarlo(const Case& c) {
  EkfOptions opt = shippedOptions();
  opt.estimate_encoder_scales = c.scale_states;
  opt.encoder_fault_prior = EncoderFaultPrior::None;  // a prior on WHICH wheel fails: not sampled
  // The states as estimated from the start (not held until an alarm) and no gyro bias: this
  // checks the noise model of the pose and the scales, not the alarm's timing.
  if (!c.closed_until_alarm) {
    opt.open_sensor_errors_on_alarm = false;
    opt.estimate_gyro_bias = false;
  }
  if (c.encoder_scale_sigma > 0) opt.encoder_scale_sigma = c.encoder_scale_sigma;
  if (c.slip_m_s >= 0) opt.encoder_extra_noise_m_s = c.slip_m_s;
  if (c.slip_m_s >= 0) opt.q_xy_m2_s = 0;  // the truth has no lateral creep either
  opt.encoder_quantisation_carry = c.quantisation_carry;
  if (c.initial_pose_sigma >= 0)
    opt.initial_sigma_xy_m = opt.initial_sigma_phi_rad = c.initial_pose_sigma;
  if (c.filter_q_omega > 0) opt.q_omega_rad2_s3 = c.filter_q_omega;
  opt.yaw_noise_from_manoeuvre = c.manoeuvre_yaw_noise;
  if (c.closed_encoder_scale_sigma >= 0)
    opt.closed_encoder_scale_sigma = c.closed_encoder_scale_sigma;
  // The healthy chair's radii spread: the closed states' (consider) prior, or the open prior.
  const double draw_sigma =
      c.closed_until_alarm ? c.draw_sigma_closed(opt) : opt.encoder_scale_sigma;
  std::mt19937_64 rng(4242);
  std::normal_distribution<double> N01(0.0, 1.0);
  std::vector<double> sum2, sum3, sum_phi;
  long nis_n[2] = {0, 0};
  double nis_sum[2] = {0, 0};
  for (int run = 0; run < kRuns; ++run) {
    SynthOptions so;
    so.duration_s = 12.0;
    so.start_pause_s = 0.0;
    so.q_v = opt.q_v_m2_s3;
    so.q_omega = c.truth_q_omega >= 0 ? c.truth_q_omega : opt.q_omega_rad2_s3;
    so.yaw_accel_error_rad_s2 = c.yaw_accel_error_rad_s2;
    so.yaw_error_phase = 1.1 * run;
    so.yaw_accel_per_v_omega_1_m = c.truth_kappa_1_m;
    so.encoder_extra_noise_m_s = opt.encoder_extra_noise_m_s;
    so.obstacle_world = {1.5, 2.5};
    so.currents = curvyCurrents(0.37 * run, c.sum_mean_A, c.diff_amp_A);
    so.left_encoder_scale = c.left_fault;
    if (c.draw_scales) {
      so.right_encoder_scale = 1.0 + draw_sigma * N01(rng);
      so.left_encoder_scale *= 1.0 + draw_sigma * N01(rng);
    }
    const SynthRun sr = synthesize(nominal(), so, 5000 + run);
    const EstimationResult res = runEstimator(sr.rec, nominal(), opt);
    if (sum2.empty()) sum2.assign(res.estimates.size(), 0.0), sum3 = sum_phi = sum2;
    for (std::size_t i = 0; i < res.estimates.size() && i < sum2.size(); ++i) {
      const EstimateSample& e = res.estimates[i];
      const TruthPoint& t = sr.at(e.t_s);
      Eigen::Vector3d err(e.x(2) - t.x, e.x(3) - t.y, model::wrapAngle(e.x(4) - t.phi));
      sum2[i] += err.head<2>().dot(e.P.block<2, 2>(2, 2).ldlt().solve(err.head<2>())) / kRuns;
      sum3[i] += err.dot(e.P.block<3, 3>(2, 2).ldlt().solve(err)) / kRuns;
      sum_phi[i] += err(2) * err(2) / e.P(4, 4) / kRuns;
    }
    for (int s : {0, 1}) {
      const SensorStats& st = res.sensors[s == 0 ? int(Sensor::Encoders) : int(Sensor::Gyro)];
      nis_sum[s] += st.nis_sum;
      nis_n[s] += st.nis_count;
    }
  }
  McNees r;
  for (std::size_t i = 1; i < sum2.size(); ++i) {  // i = 0: the start, error 0
    r.position += sum2[i] / double(sum2.size() - 1);
    r.pose += sum3[i] / double(sum3.size() - 1);
    r.heading += sum_phi[i] / double(sum_phi.size() - 1);
  }
  r.band2 = stats::chi2MeanBand(0.95, 2, kRuns);
  r.band3 = stats::chi2MeanBand(0.95, 3, kRuns);
  r.nis_encoders = nis_sum[0] / nis_n[0];
  r.nis_gyro = nis_sum[1] / nis_n[1];
  r.nis_band_encoders = stats::chi2MeanBand(0.95, 2, double(nis_n[0]));
  r.nis_band_gyro = stats::chi2MeanBand(0.95, 1, double(nis_n[1]));
  std::printf(
      "[%s] %d runs x 12 s: position NEES %.2f (band %.2f..%.2f), pose NEES %.2f (band "
      "%.2f..%.2f), heading %.2f; NIS encoders %.3f (%.3f..%.3f), gyro %.3f (%.3f..%.3f)\n",
      c.name, kRuns, r.position, r.band2.first, r.band2.second, r.pose, r.band3.first,
      r.band3.second, r.heading, r.nis_encoders, r.nis_band_encoders.first,
      r.nis_band_encoders.second, r.nis_gyro, r.nis_band_gyro.first, r.nis_band_gyro.second);
  return r;
}

void expectConsistent(const McNees& r) {
  EXPECT_GT(r.position, r.band2.first);
  EXPECT_LT(r.position, r.band2.second);
  EXPECT_GT(r.pose, r.band3.first);
  EXPECT_LT(r.pose, r.band3.second);
  // Over ~14000 encoder / 29000 gyro updates the NIS band is narrow (the uniform quantisation
  // is Gaussian-approximated), so 10 % either side.
  EXPECT_NEAR(r.nis_encoders, 2.0, 0.2);
  EXPECT_NEAR(r.nis_gyro, 1.0, 0.1);
}

}  // namespace

TEST(NeesMonteCarlo, ShippedNoiseModelIsConsistentOnCleanDrives) {
  expectConsistent(monteCarlo({"clean, states off"}));
}

TEST(NeesMonteCarlo, ShippedNoiseModelIsConsistentWithScaleStatesOverDrawnChairs) {
  // Rolling radii drawn from a healthy chair's prior (0.5 %), the states estimate them.
  expectConsistent(monteCarlo({"clean, states on, radii ~ N(1, 0.5 %)", true, 1.0, true, 0.005}));
}

TEST(NeesMonteCarlo, CovarianceStaysHonestOnTheFaultyEncoderDrive) {
  // The paper's fault (left encoder 5 % short) on chairs drawn from the shipped prior: the
  // scale states (shipped prior sd) must absorb the fault without becoming over-confident.
  expectConsistent(monteCarlo({"left encoder x0.95, states on", true, 0.95, true}));
}

TEST(NeesMonteCarlo, ClosedScaleStatesCarryAHealthyChairsRadiusUncertainty) {
  // The shipped fault detection: the scale states closed until an alarm. Closed, they are
  // consider states with a healthy wheel's prior (closed_encoder_scale_sigma = 0.5 %), and the
  // truth's rolling radii are drawn from it: the pose covariance must carry what the radius
  // does to the pose (before: held with zero variance, position NEES over-confident).
  expectConsistent(
      monteCarlo({"closed until alarm, radii ~ N(1, 0.5 %)", true, 1.0, true, -1, true}));
}

TEST(NeesMonteCarlo, HeldScaleStatesWithoutConsiderVarianceAreOverconfident) {
  // The same drives with the closed states held at zero variance (the previous behaviour):
  // the radius error is in no covariance and the position NEES leaves its band upwards. The
  // difference to the test above is the consider variance alone.
  const McNees r = monteCarlo(
      {"held with zero variance, radii ~ N(1, 0.5 %)", true, 1.0, true, -1, true, 0.0, 0.005});
  EXPECT_GT(r.position, r.band2.second);
}

namespace {
/// A chair with little slip (0.5 mm/s, the filter told so): the tick quantisation dominates
/// the encoder error, and its errors telescope over consecutive intervals.
Case slipFreeChair(const char* name, bool carry) {
  Case c{name};
  c.slip_m_s = 0.0005;
  c.quantisation_carry = carry;
  return c;
}
}  // namespace

TEST(NeesMonteCarlo, CarriedQuantisationIsConsistentWhereTheTicksDominate) {
  // encoder_quantisation_carry: each count's error enters once (the accumulators restart at
  // minus it), so the covariance of the integrated distance and heading stays bounded as the
  // truth's does; the position NEES and the encoder NIS are in their bands.
  expectConsistent(monteCarlo(slipFreeChair("slip 0.5 mm/s, quantisation carried", true)));
}

TEST(NeesMonteCarlo, WhiteQuantisationIsConservativeWhereTheTicksDominate) {
  // The same drives with the quantisation treated as white (tick^2 / 6 / dt^2 per interval):
  // the filter's distance and heading variance grow as a random walk while the truth's error
  // is bounded by a tick, so the position NEES falls below its band.
  const McNees r = monteCarlo(slipFreeChair("slip 0.5 mm/s, quantisation white", false));
  EXPECT_LT(r.position, r.band2.first);
}

TEST(NeesMonteCarlo, AnInitialPoseAllowanceTheTruthDoesNotHaveIsConservative) {
  // The estimates are in the start frame, which IS the pose at t0: its error there is zero by
  // definition, and the shipped initial pose sd (1e-6) says so (the clean test above uses it).
  // The former 1e-3 (1 mm, 1 mrad: 12 mm across the 12 m drive) puts the position NEES below
  // its band on the same drives.
  Case c{"clean, states off, initial pose sd 1e-3"};
  c.initial_pose_sigma = 1e-3;
  const McNees r = monteCarlo(c);
  EXPECT_LT(r.position, r.band2.first);
}

namespace {
/// The white density on omegadot that covers a sustained yaw-acceleration error a (rad/s^2) of
/// the model with a gyro of white noise sigma_g (rad/s) at rate_hz: q = a^(4/3) r^(1/3), r =
/// sigma_g^2 / rate_hz. A filter whose omega follows the gyro with gain K = sqrt(q / r) lags a
/// sustained a by a / K; that lag equals its own omega sd (q r)^(1/4) at this q
/// (docs/estimation.md, "Error budget of the three-task NEES").
double yawNoiseFor(double a_rad_s2, double gyro_sigma_rad_s = 0.005, double rate_hz = 100) {
  const double r = gyro_sigma_rad_s * gyro_sigma_rad_s / rate_hz;
  return std::pow(a_rad_s2, 4.0 / 3.0) * std::cbrt(r);
}

/// Truth without white yaw noise but with a sustained, slowly varying yaw acceleration that (6)
/// does not have (a sin(0.23 t + phase), period 27 s, amplitude a): the kind of model error the
/// campaign's faulty chair (right gearbox 30 % stiffer: ~0.15 rad/s^2 from its gyro NIS) and
/// the MuJoCo chair (centre of mass ahead of the axle, ~0.17 rad/s^2) realise.
Case sustainedYawMoment(const char* name, double a_rad_s2, double filter_q_omega) {
  Case c{name};
  c.truth_q_omega = 0;
  c.yaw_accel_error_rad_s2 = a_rad_s2;
  c.filter_q_omega = filter_q_omega;
  return c;
}
}  // namespace

TEST(NeesMonteCarlo, YawNoiseSizedForASustainedYawMomentCoversIt) {
  // q_omega = yawNoiseFor(0.25) = 1.0e-3: on drives with that yaw moment the gyro innovations,
  // the heading and the pose are consistent (gyro NIS 0.997, heading 1.09, pose 2.92).
  const McNees r = monteCarlo(
      sustainedYawMoment("yaw moment 0.25 rad/s^2, q sized for it", 0.25, yawNoiseFor(0.25)));
  const auto band1 = stats::chi2MeanBand(0.95, 1, kRuns);
  EXPECT_NEAR(yawNoiseFor(0.25), 1.0e-3, 0.02e-3);
  EXPECT_NEAR(r.nis_gyro, 1.0, 0.1);
  EXPECT_LT(r.heading, band1.second);
  EXPECT_GT(r.heading, band1.first);
  EXPECT_LT(r.position, r.band2.second);
  EXPECT_LT(r.pose, r.band3.second);
}

TEST(NeesMonteCarlo, AYawMomentTwiceTheOneTheYawNoiseIsSizedForIsNotCovered) {
  // The same q with twice the yaw moment: the lag grows as a, the sd does not, and the filter
  // is over-confident in omega and heading (gyro NIS 1.87, heading 1.50 against 1.08 when q is
  // sized for the moment; with the former 5 mm/s slip the position NEES was 11, with the
  // shipped 2.5 mm/s the encoders hold the position: 1.74): a q below the drive's yaw moment
  // is worse than a q above it.
  const McNees r = monteCarlo(
      sustainedYawMoment("yaw moment 0.5 rad/s^2, q sized for 0.25", 0.5, yawNoiseFor(0.25)));
  EXPECT_GT(r.nis_gyro, r.nis_band_gyro.second + 0.5);
  EXPECT_GT(r.heading, 1.3);
}

TEST(NeesMonteCarlo, TheShippedYawNoiseIsNotOverConfidentAtTheCentreOfMassMoment) {
  // The yaw moment (6) leaves out at the driver's limits from the centre of mass ahead of the
  // axle alone, a = m d v omega / I_z = 130 kg x 0.07 m x 0.8 m/s x 0.6 rad/s / 8 kg m^2 = 0.55
  // rad/s^2, would be covered by yawNoiseFor(0.55) = 0.0028. The shipped q_omega is sized for
  // 2.4 rad/s^2 (castor swivel torques on a real chair; 0.003 made position worse:
  // docs/estimation.md, "Error budget of the three-task NEES"): on drives with the centre-of-mass
  // moment the shipped filter is conservative, never over-confident.
  const EkfOptions shipped = shippedOptions();
  const double a_max = 130.0 * 0.07 * 0.8 * 0.6 / 8.0;
  EXPECT_NEAR(yawNoiseFor(a_max), 0.0028, 0.0001);
  EXPECT_NEAR(shipped.q_omega_rad2_s3, yawNoiseFor(2.4), 0.1 * shipped.q_omega_rad2_s3);
  const McNees r =
      monteCarlo(sustainedYawMoment("shipped q_omega, yaw moment 0.55 rad/s^2", a_max, -1));
  const auto band1 = stats::chi2MeanBand(0.95, 1, kRuns);
  EXPECT_LT(r.nis_gyro, 1.0);
  EXPECT_LT(r.heading, band1.second);
  EXPECT_LT(r.position, r.band2.second);
  EXPECT_LT(r.pose, r.band3.second);
}

TEST(NeesMonteCarlo, TheShippedYawNoiseIsTenTimesTheSimulatorsYawMoment) {
  // The shipped q_omega = 0.02 covers yawNoiseFor^-1(0.02) = 2.4 rad/s^2: on a 0.25 rad/s^2
  // moment it lets omega wander by sqrt(q dt) = 14 mrad/s between 10 ms gyro samples, which no
  // slowly varying moment does: gyro NIS 0.20 (the campaigns' 0.19) and a heading NEES of 0.67
  // (the campaigns' 0.53-0.55), the conservatism the error budget found.
  const McNees r =
      monteCarlo(sustainedYawMoment("q_omega 0.02, yaw moment 0.25 rad/s^2", 0.25, 0.02));
  EXPECT_LT(r.nis_gyro, 0.5);
  EXPECT_LT(r.heading, 0.8);
}

namespace {
/// The centre of mass ahead of the axle of the shipped chair (yaw_noise_com_ahead_m, [vehicle]
/// body_mass_kg, yaw_inertia_kg_m2): kappa = m_b d / I_z = 130 x 0.07 / 8 = 1.14 1/m.
double shippedKappa() {
  const EkfOptions o = shippedOptions();
  return nominal().vehicle.geom.body_mass_kg * o.yaw_noise_com_ahead_m /
         nominal().vehicle.yaw_inertia_kg_m2;
}
/// Truth with the centre-of-mass yaw moment -kappa v omega and no white yaw noise; the
/// filter's yaw noise follows the manoeuvre (the shipped parameters of that option).
Case manoeuvreYawMoment(const char* name, double kappa_1_m, double sum_mean_A, double diff_amp_A) {
  Case c{name};
  c.truth_q_omega = 0;
  c.truth_kappa_1_m = kappa_1_m;
  c.manoeuvre_yaw_noise = true;
  c.sum_mean_A = sum_mean_A;
  c.diff_amp_A = diff_amp_A;
  return c;
}
}  // namespace

TEST(NeesMonteCarlo, ManoeuvreScaledYawNoiseIsConsistentWhereTheYawMomentFollowsTheManoeuvre) {
  // yaw_noise_from_manoeuvre: q_omega(t) = a(t)^(4/3) r^(1/3) with a(t) = a_0 + kappa |v omega|
  // + epsilon |omegadot|, on drives whose truth has the centre-of-mass moment kappa v omega
  // (and no white yaw noise): the yaw noise is small where the moment is, and the gyro
  // innovations, the heading and the pose are consistent.
  const McNees r = monteCarlo(
      manoeuvreYawMoment("yaw moment kappa v omega, manoeuvre-scaled q", shippedKappa(), 1.6, 0.4));
  const auto band1 = stats::chi2MeanBand(0.95, 1, kRuns);
  EXPECT_NEAR(shippedKappa(), 1.14, 0.01);
  EXPECT_GT(r.heading, band1.first);
  EXPECT_LT(r.heading, band1.second);
  EXPECT_GT(r.position, r.band2.first);
  EXPECT_LT(r.position, r.band2.second);
  EXPECT_GT(r.pose, r.band3.first);
  EXPECT_LT(r.pose, r.band3.second);
  EXPECT_GT(r.nis_gyro, 0.5);
  EXPECT_LT(r.nis_gyro, r.nis_band_gyro.second);
}

TEST(NeesMonteCarlo, ManoeuvreScaledYawNoiseIsNotOverConfidentAtTheDriversLimits) {
  // Twice the currents of the test above (faster and sharper turns) and the centre of mass
  // 1.5 times further ahead than the filter assumes: the noise grows with the manoeuvre and
  // with the currents, so the filter stays inside or below its bands (heading 1.05, gyro NIS
  // 0.62; a constant q for straight driving: the test below).
  const McNees r = monteCarlo(
      manoeuvreYawMoment("yaw moment 1.5 kappa v omega at the limits, manoeuvre-scaled q",
                         1.5 * shippedKappa(), 3.2, 0.8));
  const auto band1 = stats::chi2MeanBand(0.95, 1, kRuns);
  EXPECT_LT(r.heading, band1.second);
  EXPECT_LT(r.position, r.band2.second);
  EXPECT_LT(r.pose, r.band3.second);
  EXPECT_LT(r.nis_gyro, r.nis_band_gyro.second);
}

TEST(NeesMonteCarlo, AConstantYawNoiseSizedForStraightDrivingIsOverConfidentInTurns) {
  // The counter-check: the manoeuvre-scaled noise's floor alone (a constant q for a_0 =
  // 0.05 rad/s^2) on the drives of the test above is over-confident in omega (gyro NIS 1.29,
  // heading 1.20 against 0.62 and 1.05 with the manoeuvre-scaled noise).
  Case c = manoeuvreYawMoment("yaw moment 1.5 kappa v omega at the limits, q for a_0 only",
                              1.5 * shippedKappa(), 3.2, 0.8);
  c.manoeuvre_yaw_noise = false;
  c.filter_q_omega = yawNoiseFor(shippedOptions().yaw_noise_floor_rad_s2);
  const McNees r = monteCarlo(c);
  EXPECT_GT(r.nis_gyro, r.nis_band_gyro.second + 0.2);
}
