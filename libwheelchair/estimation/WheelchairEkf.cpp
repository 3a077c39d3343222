#include "libwheelchair/estimation/WheelchairEkf.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/model/VehicleParams.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace wheelchair::estimation {

using model::FilterState;
using model::ObstacleForm;

// ---------------------------------------------------------------------------------------------
// Process model

WheelchairProcessModel::WheelchairProcessModel(const model::FilterModel& fm,
                                               const Eigen::Matrix<double, 7, 1>& q,
                                               double current_density,
                                               const Eigen::VectorXd& error_q,
                                               const ManoeuvreYawNoise& yaw)
    : fm_(fm), n_(kPhysicsStateDim + static_cast<int>(error_q.size())), yaw_(yaw) {
  Q_.setZero(n_, n_);
  if (error_q.size() > 0)
    Q_.bottomRightCorner(error_q.size(), error_q.size()) = error_q.asDiagonal();
  Q_.topLeftCorner<7, 7>() = q.asDiagonal();
  // Current-sensor noise enters like process noise through G = df/du.
  const model::FilterInputJacobian G = fm_.G();
  Q_.topLeftCorner<7, 7>() += current_density * G * G.transpose();
}

namespace {

// The accumulators s_v, s_omega on top of the 7-state model: sdot = (v, omega), no other
// dependence.
// The sensor-error states (if any) are random walks: zero rate, zero Jacobian rows.
void augmentRate(const Eigen::VectorXd& x, const FilterState& xd7, Eigen::VectorXd& xdot) {
  xdot.setZero(x.size());
  xdot.head<7>() = xd7;
  xdot(kIdxSv) = x(model::kIdxV);
  xdot(kIdxSomega) = x(model::kIdxOmega);
}

void augmentJacobian(int n, const model::FilterStateJacobian& F7, Eigen::MatrixXd& F) {
  F.setZero(n, n);
  F.topLeftCorner<7, 7>() = F7;
  F(kIdxSv, model::kIdxV) = 1.0;
  F(kIdxSomega, model::kIdxOmega) = 1.0;
}

}  // namespace

void WheelchairProcessModel::f(const Eigen::VectorXd& x, const Eigen::VectorXd& u,
                               Eigen::VectorXd& xdot) const {
  augmentRate(x, fm_.f(x.head<7>(), model::FilterInput(u(0), u(1))), xdot);
}

void WheelchairProcessModel::F(const Eigen::VectorXd& x, const Eigen::VectorXd& /*u*/,
                               Eigen::MatrixXd& F) const {
  augmentJacobian(n_, fm_.F(x.head<7>()), F);
}

void WheelchairProcessModel::fAndF(const Eigen::VectorXd& x, const Eigen::VectorXd& u,
                                   Eigen::VectorXd& xdot, Eigen::MatrixXd& F) const {
  FilterState xd7;
  model::FilterStateJacobian F7;
  fm_.fAndF(x.head<7>(), model::FilterInput(u(0), u(1)), xd7, F7);
  augmentRate(x, xd7, xdot);
  augmentJacobian(n_, F7, F);
}

void WheelchairProcessModel::Q(const Eigen::VectorXd& x, const Eigen::VectorXd& u,
                               Eigen::MatrixXd& Q) const {
  Q = Q_;
  if (yaw_.on) Q(model::kIdxOmega, model::kIdxOmega) = varyingQ(x, u);
}

double WheelchairProcessModel::varyingQ(const Eigen::VectorXd& x, const Eigen::VectorXd& u) const {
  return Q_(model::kIdxOmega, model::kIdxOmega) +
         yaw_.qOmega(x(model::kIdxV), x(model::kIdxOmega), u(0), u(1));
}

// ---------------------------------------------------------------------------------------------
// Canonical output

EstimateSample canonicalFromFilterState(double t, const Eigen::VectorXd& x,
                                        const Eigen::MatrixXd& P, ObstacleForm form, bool init) {
  EstimateSample s;
  s.t_s = t;
  s.obstacle_initialised = init;
  s.x = x.head<7>();
  CanonicalCov Pc = P.topLeftCorner<7, 7>();
  if (form == ObstacleForm::Polar) {
    // T P T' with T = identity but for the 2x2 Jacobian J of (d, beta) -> (px, py) on the
    // obstacle rows/columns: rows 5-6 become J P, then columns 5-6 (. ) J'.
    const double d = x(model::kIdxO1), b = x(model::kIdxO2), c = std::cos(b), sn = std::sin(b);
    s.x(model::kIdxO1) = d * c;
    s.x(model::kIdxO2) = d * sn;
    Eigen::Matrix2d J;
    J << c, -d * sn, sn, d * c;
    const Eigen::Matrix<double, 2, 7> rows = J * Pc.middleRows<2>(5);
    Pc.middleRows<2>(5) = rows;
    const Eigen::Matrix<double, 7, 2> cols = Pc.middleCols<2>(5) * J.transpose();
    Pc.middleCols<2>(5) = cols;
  }
  s.P = 0.5 * (Pc + Pc.transpose());
  s.sd = s.P.diagonal().cwiseMax(0.0).cwiseSqrt();
  // d_o^M and theta_o^M with first-order standard deviations.
  const Eigen::Vector2d p = s.x.segment<2>(5);
  const Eigen::Matrix2d Pp = s.P.block<2, 2>(5, 5);
  const double d = p.norm();
  s.obstacle_distance_m = d;
  s.obstacle_bearing_rad = std::atan2(p.y(), p.x());
  if (d > 0) {
    const Eigen::RowVector2d jd = p.transpose() / d;
    const Eigen::RowVector2d jb(-p.y() / (d * d), p.x() / (d * d));
    s.obstacle_distance_sd_m = std::sqrt(std::max(0.0, double(jd * Pp * jd.transpose())));
    s.obstacle_bearing_sd_rad = std::sqrt(std::max(0.0, double(jb * Pp * jb.transpose())));
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// Filter

namespace {

model::FilterModel makeFilterModel(const config::WheelchairConfig& cfg, const EkfOptions& opt) {
  model::FilterModelParams p;
  p.ode = model::odeCoefficients(cfg.vehicle.geom, model::lumpedTheta(cfg.vehicle));
  p.form = opt.obstacle_form == ObstacleFormOption::Polar ? ObstacleForm::Polar
                                                          : ObstacleForm::Cartesian;
  p.sonar_offset_m = Eigen::Vector2d(cfg.sonar.x_m, cfg.sonar.y_m);
  p.pozyx_lever_arm_m = Eigen::Vector2d(cfg.pozyx.lever_x_m, cfg.pozyx.lever_y_m);
  return model::FilterModel(p);
}

Eigen::Matrix<double, 7, 1> processNoiseDiag(const EkfOptions& o) {
  const bool polar = o.obstacle_form == ObstacleFormOption::Polar;
  Eigen::Matrix<double, 7, 1> q;
  // With the manoeuvre-scaled yaw noise q_omega_rad2_s3 is replaced (manoeuvreYawNoise).
  q << o.q_v_m2_s3, o.yaw_noise_from_manoeuvre ? 0.0 : o.q_omega_rad2_s3, o.q_xy_m2_s, o.q_xy_m2_s,
      o.q_phi_rad2_s, o.q_obstacle_m2_s, polar ? o.q_obstacle_bearing_rad2_s : o.q_obstacle_m2_s;
  return q;
}

/// Random-walk densities of (k_R, k_L, b_g) (empty: no sensor-error states); a group that is
/// not estimated gets 0 (it stays at its prior mean). With open_sensor_errors_on_alarm all are
/// 0 here: a group's walk starts when it opens, added by WheelchairEkf::addErrorNoise.
Eigen::VectorXd errorStateNoise(const EkfOptions& o) {
  if (!o.sensorErrorStates()) return {};
  if (o.open_sensor_errors_on_alarm) return Eigen::Vector3d::Zero();
  const double qk = o.estimate_encoder_scales ? o.q_encoder_scale_1_s : 0.0;
  // Independent walks of k_R, k_L of density q: k_s gets q / 2, k_d 2 q, uncorrelated.
  return Eigen::Vector3d(0.5 * qk, 2.0 * qk, o.estimate_gyro_bias ? o.q_gyro_bias_rad2_s3 : 0.0);
}

/// The manoeuvre-scaled yaw noise of [estimator] (off unless yaw_noise_from_manoeuvre):
/// kappa = m_b d / I_z, a2, a4 / l_w from [vehicle], r = gyro variance / [imu] rate_hz.
ManoeuvreYawNoise manoeuvreYawNoise(const config::WheelchairConfig& cfg, const EkfOptions& o) {
  ManoeuvreYawNoise y;
  y.on = o.yaw_noise_from_manoeuvre;
  y.floor_rad_s2 = o.yaw_noise_floor_rad_s2;
  y.kappa_1_m =
      cfg.vehicle.geom.body_mass_kg * o.yaw_noise_com_ahead_m / cfg.vehicle.yaw_inertia_kg_m2;
  y.side_fraction = o.yaw_noise_side_fraction;
  const model::OdeCoefficients a =
      model::odeCoefficients(cfg.vehicle.geom, model::lumpedTheta(cfg.vehicle));
  y.a2_rad_s2_A = std::fabs(a.a2);
  y.a4_per_track_1_ms = std::fabs(a.a4) / cfg.vehicle.geom.track_width_m;
  y.half_track_m = 0.5 * cfg.vehicle.geom.track_width_m;
  y.cbrt_r = std::cbrt(o.gyro_noise_rad_s * o.gyro_noise_rad_s / std::max(cfg.imu.rate_hz, 1e-9));
  return y;
}

}  // namespace

Eigen::Vector2d scaledEncoderSpeeds(const Eigen::Vector2d& a, double k_s, double k_d, double lw,
                                    Eigen::Matrix2d* dz_da, Eigen::Matrix2d* dz_dk) {
  if (dz_da) *dz_da << k_s, 0.25 * lw * k_d, k_d / lw, k_s;
  if (dz_dk) *dz_dk << a(0), 0.25 * lw * a(1), a(1), a(0) / lw;
  return {k_s * a(0) + 0.25 * lw * k_d * a(1), k_d / lw * a(0) + k_s * a(1)};
}

WheelchairEkf::WheelchairEkf(const config::WheelchairConfig& cfg, const EkfOptions& opt,
                             const InputSignal* input)
    : Estimator(cfg, opt),
      input_(input),
      zero_input_(opt.input_interpolation),
      pm_(makeFilterModel(cfg, opt_), processNoiseDiag(opt_), opt_.current_noise_density_A2_s,
          errorStateNoise(opt_), manoeuvreYawNoise(cfg, opt_)),
      ekf_(pm_, opt_.cvode) {
  if (!input_) input_ = &zero_input_;
  u_in_.signal = input_;
  const int n = pm_.stateDim();
  xs_.resize(n);
  da_.setZero(2, n);
  enc_m_ = Measurement(Sensor::Encoders, 2, n);
  gyro_m_ = Measurement(Sensor::Gyro, 1, n);
  sonar_m_ = Measurement(Sensor::Sonar, 1, n);
  pozyx_m_ = Measurement(Sensor::Pozyx, 2, n);
  Pw_.resize(n, n);
  Hg_.resize(2, n);
}

FilterState WheelchairEkf::head() const {
  return ekf_.x().head<7>();
}

void WheelchairEkf::start(double t0) {
  const int n = pm_.stateDim();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(n, n);
  if (n > kPhysicsStateDim) {
    // Independent priors N(k_R, s^2), N(k_L, s^2) are independent in (k_s, k_d) too:
    // var k_s = s^2 / 2, var k_d = 2 s^2.
    x(kIdxEncScaleS) = 0.5 * (opt_.encoder_scale_right + opt_.encoder_scale_left);
    x(kIdxEncScaleD) = opt_.encoder_scale_right - opt_.encoder_scale_left;
    x(kIdxGyroBias) = opt_.gyro_bias_rad_s;
    // Closed groups (open_sensor_errors_on_alarm) start as consider states: the healthy
    // sensor's variance (closed_*_sigma; 0: held exactly), not learned until they open.
    const bool open = !opt_.open_sensor_errors_on_alarm;
    const double sk = !opt_.estimate_encoder_scales ? 0.0
                      : open                        ? opt_.encoder_scale_sigma
                                                    : opt_.closed_encoder_scale_sigma;
    const double sb = !opt_.estimate_gyro_bias ? 0.0
                      : open                   ? opt_.gyro_bias_sigma_rad_s
                                               : opt_.closed_gyro_bias_sigma_rad_s;
    P(kIdxEncScaleS, kIdxEncScaleS) = 0.5 * sk * sk;
    P(kIdxEncScaleD, kIdxEncScaleD) = 2.0 * sk * sk;
    P(kIdxGyroBias, kIdxGyroBias) = sb * sb;
  }
  P(model::kIdxV, model::kIdxV) = opt_.initial_sigma_v_m_s * opt_.initial_sigma_v_m_s;
  P(model::kIdxOmega, model::kIdxOmega) =
      opt_.initial_sigma_omega_rad_s * opt_.initial_sigma_omega_rad_s;
  P(model::kIdxX, model::kIdxX) = opt_.initial_sigma_xy_m * opt_.initial_sigma_xy_m;
  P(model::kIdxY, model::kIdxY) = opt_.initial_sigma_xy_m * opt_.initial_sigma_xy_m;
  P(model::kIdxPhi, model::kIdxPhi) = opt_.initial_sigma_phi_rad * opt_.initial_sigma_phi_rad;
  ekf_.reset(t0, x, P);
  // open_sensor_errors_on_alarm: the sensor-error states have no rate, no F rows or columns
  // (f does not depend on them) and no Q (errorStateNoise: the walk of an open group is added
  // at the updates, addErrorNoise), so CVODE integrates only the 9 physics states, closed or
  // open, and their cross-covariance with the rest is carried by the physics states'
  // transition matrix (CdEkf::setHeldTail, consider tail).
  ekf_.setHeldTail(
      n > kPhysicsStateDim && opt_.open_sensor_errors_on_alarm ? n - kPhysicsStateDim : 0, true);
  health_ = HealthMonitor(t0);
  fault_prior_applied_ = false;
  model_v_[0] = model_v_[1] = 0;
  model_t_s_ = t0;
  dir_decided_ = false;
  encoders_standstill_ = false;
  encoder_scales_open_ = false;
  gyro_bias_open_ = false;
  // A healthy chair's scales learned before the alarm (learn_healthy_encoder_scales).
  const bool learn =
      n > kPhysicsStateDim && opt_.open_sensor_errors_on_alarm && opt_.estimate_encoder_scales;
  const HealthyScaleLearning hl = opt_.learn_healthy_encoder_scales;
  scale_difference_open_ = learn && hl != HealthyScaleLearning::None;
  common_scale_learned_ = learn && hl == HealthyScaleLearning::Both;
  encoder_noise_t_s_ = t0;
  // Obstacle at its most likely place: configured position (also the placeholder until the
  // first valid sonar reading in first_sonar mode).
  setObstacle(configObstacle(), configObstacleCov());
  obstacle_initialised_ = opt_.initial_obstacle == ObstacleInit::Config;
  acc_valid_ = false;
  slip_var_m2_s2_ = opt_.encoder_extra_noise_m_s * opt_.encoder_extra_noise_m_s;
}

void WheelchairEkf::setObstacle(const Eigen::Vector2d& p, const Eigen::Matrix2d& cov) {
  Eigen::VectorXd x = ekf_.x();
  Eigen::MatrixXd P = ekf_.P();
  Eigen::Vector2d o = p;
  Eigen::Matrix2d C = cov;
  if (filterModel().form() == ObstacleForm::Polar) {
    const double d = std::max(p.norm(), 1e-6);
    o = model::cartesianToPolar(p);
    // d(d, beta)/d(px, py)
    Eigen::Matrix2d J;
    J << p.x() / d, p.y() / d, -p.y() / (d * d), p.x() / (d * d);
    C = J * cov * J.transpose();
  }
  x.segment<2>(model::kIdxO1) = o;
  P.middleRows<2>(model::kIdxO1).setZero();
  P.middleCols<2>(model::kIdxO1).setZero();
  P.block<2, 2>(model::kIdxO1, model::kIdxO1) = C;
  ekf_.setState(x);
  ekf_.setCovariance(P);
}

void WheelchairEkf::initObstacleFromSonar(double range) {
  setObstacle(sonarPointBody(range), sonarPointCovBody(range));
  obstacle_initialised_ = true;
}

void WheelchairEkf::inflatePositionCovariance(double var) {
  Eigen::MatrixXd P = ekf_.P();
  P(model::kIdxX, model::kIdxX) += var;
  P(model::kIdxY, model::kIdxY) += var;
  ekf_.setCovariance(P);
}

void WheelchairEkf::predictTo(double t) {
  double ta = ekf_.time();
  if (t <= ta) return;
  const bool linear = input_->mode() == InputInterpolation::Linear;
  if (linear && !opt_.cvode.restart_at_input_samples) {
    // Piecewise-linear u(t) is continuous: one integration to t; the samples are kinks of u
    // that CVODE's error control steps through (docs/estimation.md, "CVODE settings").
    u_in_.hold = false;
    ekf_.propagate(t, u_in_, true);
    return;
  }
  // Restart at every input sample strictly inside (ta, t): u jumps there (hold) or has a kink
  // (linear, restart_at_input_samples). Between samples u is exact for both modes.
  u_in_.hold = !linear;
  for (;;) {
    const double tb = std::min(input_->nextSampleAfter(ta), t);
    if (!linear) u_in_.held = input_->at(ta);
    ekf_.propagate(tb, u_in_, !input_->isSampleTime(ta));
    if (tb >= t) break;
    ta = tb;
  }
}

void WheelchairEkf::wrap() {
  const double phi = ekf_.x()(model::kIdxPhi);
  const double o2 = ekf_.x()(model::kIdxO2);
  const bool polar = filterModel().form() == ObstacleForm::Polar;
  if (phi > -M_PI && phi <= M_PI && (!polar || (o2 > -M_PI && o2 <= M_PI))) return;  // no-op
  xs_ = ekf_.x();
  xs_.head<7>() = filterModel().wrapAngles(xs_.head<7>());
  ekf_.setState(xs_);
}

void WheelchairEkf::resetAccumulators(double t) {
  xs_ = ekf_.x();
  xs_(kIdxSv) = 0;
  xs_(kIdxSomega) = 0;
  ekf_.setState(xs_);
  ekf_.zeroCovarianceRowsCols(kIdxSv, 2);
  const double q = tickVarianceM2();
  if (quantisationCarried() && q > 0) {
    // s = -e, e the count's error per wheel (uniform, tick^2 / 12): s_v = -(e_R + e_L) / 2,
    // s_omega = -(e_R - e_L) / l_w.
    Pw_ = ekf_.P();
    Pw_.block<2, 2>(kIdxSv, kIdxSv) = wheelSpeedNoise(q);  // (the block was zeroed above)
    ekf_.setCovariance(Pw_);
  }
  acc_start_s_ = t;
  acc_valid_ = true;
}

bool WheelchairEkf::quantisationCarried() const {
  return opt_.encoder_quantisation_carry && opt_.encoder_model == EncoderMeasurementModel::Mean;
}

double WheelchairEkf::tickVarianceM2() const {
  if (!opt_.encoder_quantisation) return 0.0;
  const double tick_m = wheel_radius_m_ * wheel_rad_per_tick_;
  return tick_m * tick_m / 12.0;
}

Eigen::Matrix2d WheelchairEkf::encoderIntervalNoise(double dt) const {
  // Per-wheel rim-speed variance: quantisation + slip. Carried (telescoping), each count's
  // error e_k enters once, through the accumulators' restart value (-e_{k-1}, in P) and the
  // new count (+e_k, here): tick^2 / 12 / dt^2. White: both, tick^2 / 6 / dt^2
  // (Estimator::encoderNoise, the baseline's model).
  return wheelSpeedNoise((quantisationCarried() ? 1.0 : 2.0) * tickVarianceM2() / (dt * dt) +
                         slip_var_m2_s2_);
}

void WheelchairEkf::nextEncoderInterval(const Eigen::Vector2d& z, double dt, double t, bool carry) {
  // The accumulators s(t) = (true distance since t_{k-1}) - M^-1 e_{k-1}, so the count
  // difference is z dt = M s(t_k) + v_k with v_k = e_k + slip_k dt white (M = dz/da, I
  // without scales). The new interval starts at s' = -M^-1 e_k. Both parts of v_k are
  // Gaussian-approximated, independent and in the same proportion on both rows, so
  // e_k = alpha v_k + u, alpha = q / (q + slip dt^2), u independent of v_k with variance
  // (1 - alpha) q; and v_k = z dt - M s(t_k). Hence the linear map
  //   s' = alpha (s - dt M^-1 z) - M^-1 u,
  // P' = G P G' + var(M^-1 u), G = I except the s rows (alpha, and d s' / d k with the scales).
  // alpha = 1 (no slip): the exact telescoping; alpha = 0: the white model's restart at 0.
  const double q = tickVarianceM2();
  if (!carry || q <= 0 || !quantisationCarried()) {
    resetAccumulators(t);
    return;
  }
  const double alpha = q / (q + slip_var_m2_s2_ * dt * dt);
  const int n = pm_.stateDim();
  const Eigen::VectorXd& x = ekf_.x();
  Eigen::Matrix2d Minv = Eigen::Matrix2d::Identity();
  Eigen::Matrix2d dsdk = Eigen::Matrix2d::Zero();
  if (n > kPhysicsStateDim) {
    Eigen::Matrix2d M, dz_dk;
    scaledEncoderSpeeds(Eigen::Vector2d::Zero(), x(kIdxEncScaleS), x(kIdxEncScaleD), track_width_m_,
                        &M);
    Minv << M(1, 1), -M(0, 1), -M(1, 0), M(0, 0);  // 2 x 2 inverse
    Minv /= M(0, 0) * M(1, 1) - M(0, 1) * M(1, 0);
    scaledEncoderSpeeds(Minv * z, x(kIdxEncScaleS), x(kIdxEncScaleD), track_width_m_, nullptr,
                        &dz_dk);
    dsdk = alpha * dt * Minv * dz_dk;  // d(-alpha dt M^-1 z)/dk = alpha dt M^-1 dM/dk M^-1 z
  }
  xs_ = x;
  xs_.segment<2>(kIdxSv) = alpha * (x.segment<2>(kIdxSv) - dt * Minv * z);
  ekf_.setState(xs_);
  // G P G' with G = I + E, E nonzero only in the s rows: s rows <- alpha s rows + dsdk k rows.
  // In place in the scratch Pw_ (no allocation per interval): the k rows and columns read by
  // the second term are not among the s rows and columns scaled by the first.
  Pw_ = ekf_.P();
  Pw_.middleRows<2>(kIdxSv) *= alpha;
  if (n > kPhysicsStateDim) Pw_.middleRows<2>(kIdxSv) += dsdk * Pw_.middleRows<2>(kIdxEncScaleS);
  Pw_.middleCols<2>(kIdxSv) *= alpha;
  if (n > kPhysicsStateDim)
    Pw_.middleCols<2>(kIdxSv) += Pw_.middleCols<2>(kIdxEncScaleS) * dsdk.transpose();
  const double lw2 = track_width_m_ * track_width_m_;
  const Eigen::Matrix2d Qu = (1.0 - alpha) * q * Eigen::Vector2d(0.5, 2.0 / lw2).asDiagonal();
  Pw_.block<2, 2>(kIdxSv, kIdxSv) += Minv * Qu * Minv.transpose();
  ekf_.setCovariance(Pw_);  // (which symmetrises it)
  acc_start_s_ = t;
  acc_valid_ = true;
}

void WheelchairEkf::adaptSlipVariance(const UpdateResult& r, const Eigen::Matrix2d& R, double dt) {
  // Innovation-based estimate (Mehra 1970): E[y y'] = H P H' + R, so per update
  //   R_hat = y y' - (S - R),   var_u_hat = (R_hat_vv / 0.5 + R_hat_ww l_w^2 / 2) / 2
  // (the rows' per-wheel variances, averaged), and the slip sample is var_u_hat minus the
  // quantisation part. An exponential mean over encoder_noise_adapt_window_s of driving, kept
  // in [0, encoder_extra_noise_m_s^2]: a chair that slips keeps (up to) the allowance, one
  // that does not is trusted down to the quantisation floor.
  const double window = opt_.encoder_noise_adapt_window_s;
  if (!(window > 0) || !r.accepted || r.S.rows() != 2) return;
  const double lw2 = track_width_m_ * track_width_m_;
  const double rv = r.innovation(0) * r.innovation(0) - (r.S(0, 0) - R(0, 0));
  const double rw = r.innovation(1) * r.innovation(1) - (r.S(1, 1) - R(1, 1));
  const double quant = 2.0 * R(0, 0) - slip_var_m2_s2_;  // R_vv = var_u / 2
  const double sample = 0.5 * (rv / 0.5 + rw * lw2 / 2.0) - quant;
  const double cap = opt_.encoder_extra_noise_m_s * opt_.encoder_extra_noise_m_s;
  const double w = std::min(1.0, dt / window);
  slip_var_m2_s2_ = std::clamp(slip_var_m2_s2_ + w * (sample - slip_var_m2_s2_), 0.0, cap);
}

void WheelchairEkf::reopenEncoderScales() {
  // A step k <- k + j, j ~ N(0, prior) independent of everything: its variance is ADDED and
  // the cross-covariances of k with the pose are kept (the pose error accumulated so far is
  // still correlated with the old scale, hence with the new one).
  // Topped up to the prior, not beyond: repeated alarms (a gross mismatch, e.g. a wrong
  // ticks-per-revolution, alarms every few tenths of a second) would otherwise add the prior
  // again and again and let the scales wander far outside it.
  addErrorNoise();  // the walk up to now, if open
  Pw_ = ekf_.P();
  const double s2 = opt_.encoder_scale_sigma * opt_.encoder_scale_sigma;
  Pw_(kIdxEncScaleS, kIdxEncScaleS) += std::max(0.0, 0.5 * s2 - Pw_(kIdxEncScaleS, kIdxEncScaleS));
  Pw_(kIdxEncScaleD, kIdxEncScaleD) += std::max(0.0, 2.0 * s2 - Pw_(kIdxEncScaleD, kIdxEncScaleD));
  ekf_.setCovariance(Pw_);
  fault_prior_applied_ = false;
  if (!encoder_scales_open_) encoder_scales_open_ = true, encoder_noise_t_s_ = ekf_.time();
}

void WheelchairEkf::addErrorNoise() {
  // The random walks of the OPEN groups (open_sensor_errors_on_alarm), added at the update
  // times instead of in the Riccati equation: the sensor-error rows of F are 0 and f does not
  // depend on them, so dP_kk/dt = q is all the propagation does to them (exact at updates).
  // k_d alone while only it is learned (learn_healthy_encoder_scales = difference).
  const bool enc_walk = encoder_scales_open_ || scale_difference_open_;
  if (!opt_.open_sensor_errors_on_alarm || !(enc_walk || gyro_bias_open_)) return;
  const double t = ekf_.time();
  Pw_ = ekf_.P();
  if (enc_walk && t > encoder_noise_t_s_) {
    const double qdt = opt_.q_encoder_scale_1_s * (t - encoder_noise_t_s_);
    if (encoder_scales_open_ || common_scale_learned_)
      Pw_(kIdxEncScaleS, kIdxEncScaleS) += 0.5 * qdt;  // (k_R + k_L) / 2
    Pw_(kIdxEncScaleD, kIdxEncScaleD) += 2.0 * qdt;    // k_d = k_R - k_L
    encoder_noise_t_s_ = t;
  }
  if (gyro_bias_open_ && t > gyro_noise_t_s_) {
    Pw_(kIdxGyroBias, kIdxGyroBias) += opt_.q_gyro_bias_rad2_s3 * (t - gyro_noise_t_s_);
    gyro_noise_t_s_ = t;
  }
  ekf_.setCovariance(Pw_);
}

void WheelchairEkf::encoderFaultPrior() {
  // The fault prior: one wheel at a time fails, the other stays healthy (scale 1 +- sigma).
  // Once the two wheels are known to disagree (the ratio k_R / k_L, observable from straight
  // driving against the gyro) and before the common scale is (first turn), one
  // pseudo-measurement of k_s. Either side (default): k_s is 1 - |k_d| / 2 (the wheel reading
  // more is healthy: the other reads short) or 1 + |k_d| / 2 (the other reads long) with
  // equal odds; straight driving cannot tell them apart (both give the same ratio), so k_s =
  // 1 +- sqrt((k_d / 2)^2 + var(k_d) / 4 + sigma^2), the moment-matched pair, and the turn
  // decides. Short: the wheel that reads MORE is taken as healthy, max(k_R, k_L) = 1 +- sigma,
  // i.e. k_s + |k_d| / 2 = 1 (right only for an encoder that loses counts). Full update: the
  // pose driven so far at the old k_s is corrected along its correlation with k_s.
  if (!opt_.estimate_encoder_scales || opt_.encoder_fault_prior == EncoderFaultPrior::None ||
      fault_prior_applied_ || scalesClosed())
    return;
  const Eigen::VectorXd& x = ekf_.x();
  const Eigen::MatrixXd& P = ekf_.P();
  const double kd = x(kIdxEncScaleD),
               sd_d = std::sqrt(std::max(0.0, P(kIdxEncScaleD, kIdxEncScaleD)));
  const double s2_prior = 0.5 * opt_.encoder_scale_sigma * opt_.encoder_scale_sigma;
  // Ratio known to 0.5 %; k_s still near its prior (no turn yet since the last re-opening).
  if (!(sd_d < 0.005)) return;
  if (!(P(kIdxEncScaleS, kIdxEncScaleS) > 0.25 * s2_prior)) return;
  // The wheels disagree (by more than 1 % and 3 sd): the faster is healthy; else both are.
  const bool disagree = std::fabs(kd) > std::max(0.01, 3 * sd_d);
  const double sh = opt_.healthy_encoder_scale_sigma;
  const bool shorter = disagree && opt_.encoder_fault_prior == EncoderFaultPrior::Short;
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, pm_.stateDim());
  H(0, kIdxEncScaleS) = 1.0;
  H(0, kIdxEncScaleD) = shorter ? (kd > 0 ? 0.5 : -0.5) : 0.0;
  Eigen::VectorXd y(1);
  y(0) = 1.0 - (x(kIdxEncScaleS) + (shorter ? 0.5 * std::fabs(kd) : 0.0));
  const double r = shorter || !disagree ? sh * sh : 0.25 * (kd * kd + sd_d * sd_d) + sh * sh;
  ekf_.update(y, H, Eigen::MatrixXd::Constant(1, 1, r), 0.0);
  fault_prior_applied_ = true;
  // A new direction question (encoderFaultDirection) when the wheels disagree and the side is
  // open.
  dir_decided_ = !disagree || shorter;
  dir_res_[0][0] = dir_res_[0][1] = dir_res_[1][0] = dir_res_[1][1] = dir_v_sum_ = 0;
  dir_n_ = dir_hold_ = 0;
}

void WheelchairEkf::encoderFaultDirection(const sensors::WheelSpeedInterval& iv) {
  // Which side (encoder_fault_prior = either). Straight driving gives only the ratio k_R / k_L:
  // the wheel reading less reads short (k_s = 1 - |k_d| / 2) or the other reads long
  // (k_s = 1 + |k_d| / 2), i.e. the true speed is z_v / k_s with one of the two. The motor
  // model (6) predicts the speed from the measured currents, but a gearbox friction fault on
  // one side puts it off by far more than the 5 % that separate the two (the faulty three-task
  // chair's right gearbox x1.3: +11 %). Driving straight, each wheel's steady current depends
  // only on v and its own gearbox (the chassis force splits equally), so a chair driven by the
  // HEALTHY side's current on both sides moves at the true speed. Either gearbox may be the
  // healthy one: two model speeds v_M (right current, left current on both sides), integrated
  // from the start by the model (6) itself. Of the four pairs (encoder hypothesis, healthy
  // gearbox) the true one matches: mean(z_v / k_s - v_M) ~ 0. Decided after >= 1 s of straight
  // driving above 0.3 m/s when the best pair is within kMatch and the best pair of the other
  // encoder hypothesis is kSeparation further off (relative to the mean speed); until then (or
  // when the model fits neither) the symmetric prior stays and the turn or the sonar decides.
  constexpr double kMatch = 0.02, kSeparation = 0.025, kMinSpeed = 0.3, kMaxTurn = 0.05;
  constexpr double kWindow_s = 0.5;  // time constant of the residual means (s)
  constexpr int kMinSamples = 50;    // straight-driving intervals before the first test
  constexpr int kHoldSamples = 100;  // consecutive intervals the decision has to hold
  const double t1 = iv.t1_s;
  // The two model chairs: vdot = a3 v + a1 (i + i), exactly over steps of at most 20 ms with
  // the step's mid current.
  const model::OdeCoefficients& c = filterModel().params().ode;
  while (model_t_s_ < t1) {
    const double h = std::min(0.02, t1 - model_t_s_);
    const Eigen::Vector2d u = input_->at(model_t_s_ + 0.5 * h);  // (i_R, i_L)
    const double e = std::exp(c.a3 * h), g = c.a3 != 0 ? (e - 1) / c.a3 : h;
    for (int side = 0; side < 2; ++side)
      model_v_[side] = e * model_v_[side] + g * c.a1 * 2 * u(side);
    model_t_s_ += h;
  }
  if (dir_decided_ || !fault_prior_applied_ || !encoder_scales_open_) return;
  const Eigen::VectorXd& x = ekf_.x();
  const Eigen::MatrixXd& P = ekf_.P();
  const double s2_prior = 0.5 * opt_.encoder_scale_sigma * opt_.encoder_scale_sigma;
  // A turn (or the sonar) has decided: sd(k_s) below a quarter of its prior sd.
  if (!(P(kIdxEncScaleS, kIdxEncScaleS) > s2_prior / 16)) {
    dir_decided_ = true;
    return;
  }
  // (The encoders' own omega is not a test of straight driving: it carries k_d a_v / l_w.)
  if (std::fabs(x(model::kIdxOmega)) > kMaxTurn || !(std::fabs(iv.v_m_s) > kMinSpeed)) {
    dir_hold_ = 0;
    return;
  }
  // Residuals as exponential means over ~kWindow_s of straight driving (the model's own
  // transient errors and a speed-dependent model error, e.g. dry friction, change with the
  // speed: the true pair has to fit all the time, not on average).
  const double a = std::min(1.0, iv.dt() / kWindow_s);
  const double kd = std::fabs(x(kIdxEncScaleD));
  const double ks[2] = {1.0 - 0.5 * kd, 1.0 + 0.5 * kd};  // short, long
  for (int e = 0; e < 2; ++e)
    for (int m = 0; m < 2; ++m)
      dir_res_[e][m] += a * (iv.v_m_s / ks[e] - model_v_[m] - dir_res_[e][m]);
  dir_v_sum_ += a * (std::fabs(iv.v_m_s) - dir_v_sum_);
  if (++dir_n_ < kMinSamples) return;
  double fit[2];
  for (int e = 0; e < 2; ++e)
    fit[e] = std::min(std::fabs(dir_res_[e][0]), std::fabs(dir_res_[e][1])) / dir_v_sum_;
  const int best = fit[0] <= fit[1] ? 0 : 1;
  const bool clear = fit[best] < kMatch && fit[1 - best] - fit[best] > kSeparation;
  dir_hold_ = clear && (dir_hold_ == 0 || best == dir_best_) ? dir_hold_ + 1 : 0;
  dir_best_ = best;
  if (dir_hold_ < kHoldSamples) return;
  // The chosen side's prior: the healthy wheel (the one reading more when the other reads
  // short, less when the other reads long) has scale 1 +- healthy sigma. A full update: the
  // pose driven so far at the symmetric k_s is corrected along its correlation with k_s.
  const double sign = x(kIdxEncScaleD) > 0 ? 1.0 : -1.0;  // k_d > 0: the right wheel reads more
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, pm_.stateDim());
  H(0, kIdxEncScaleS) = 1.0;
  H(0, kIdxEncScaleD) = (best == 0 ? 0.5 : -0.5) * sign;
  Eigen::VectorXd y(1);
  y(0) = 1.0 - (x(kIdxEncScaleS) + H(0, kIdxEncScaleD) * x(kIdxEncScaleD));
  const double sh = opt_.healthy_encoder_scale_sigma;
  ekf_.update(y, H, Eigen::MatrixXd::Constant(1, 1, sh * sh), 0.0);
  dir_decided_ = true;
}

void WheelchairEkf::encoderStart(double t) {
  if (!opt_.use_encoders) return;
  resetAccumulators(t);
}

void WheelchairEkf::encoderInterval(const sensors::WheelSpeedInterval& iv) {
  SensorStats& st = stats(Sensor::Encoders);
  if (!opt_.use_encoders) {
    ++st.skipped;
    return;
  }
  const double dt = iv.dt();
  // Same encoder sample: the stamps are equal (an absolute tolerance: a tolerance relative to
  // |t| would be 1.7 s for UNIX stamps).
  const bool aligned = acc_valid_ && std::fabs(acc_start_s_ - iv.t0_s) <= 1e-9;
  if (!(dt > 0) || dt > opt_.max_encoder_interval_s || !std::isfinite(iv.v_m_s) ||
      !std::isfinite(iv.omega_rad_s) ||
      (opt_.encoder_model == EncoderMeasurementModel::Mean && !aligned)) {
    ++st.dropouts;
    encoders_standstill_ = false;
    resetAccumulators(iv.t1_s);
    return;
  }
  const bool still = iv.v_m_s == 0.0 && iv.omega_rad_s == 0.0;  // no tick on either wheel
  if (still && !encoders_standstill_) standstill_since_s_ = iv.t0_s;
  encoders_standstill_ = still;
  const int n = pm_.stateDim();
  addErrorNoise();
  const Eigen::VectorXd& x = ekf_.x();
  // a = the true mean speeds the encoders see and d a / d x.
  Eigen::Vector2d a;
  Eigen::Matrix<double, 2, Eigen::Dynamic>& da = da_;
  da.setZero();
  if (opt_.encoder_model == EncoderMeasurementModel::Mean) {
    a << x(kIdxSv) / dt, x(kIdxSomega) / dt;
    da(0, kIdxSv) = 1.0 / dt;
    da(1, kIdxSomega) = 1.0 / dt;
  } else {
    a << model::FilterModel::hV(x.head<7>()), model::FilterModel::hOmega(x.head<7>());
    da.block<1, 7>(0, 0) = model::FilterModel::HV();
    da.block<1, 7>(1, 0) = model::FilterModel::HOmega();
  }
  const double g = gate(2);
  Measurement& m = enc_m_;
  m.z << iv.v_m_s, iv.omega_rad_s;
  const Eigen::Matrix2d R = encoderIntervalNoise(dt);
  m.R = R;
  UpdateResult r;
  if (n > kPhysicsStateDim) {
    Eigen::Matrix2d dz_da, dz_dk;
    m.h =
        scaledEncoderSpeeds(a, x(kIdxEncScaleS), x(kIdxEncScaleD), track_width_m_, &dz_da, &dz_dk);
    m.H = dz_da * da;
    m.H.block<2, 2>(0, kIdxEncScaleS) = dz_dk;  // the true Jacobian: the covariance's
    Eigen::MatrixXd& Hg = Hg_;  // the gain's model (preallocated: no allocation per update)
    Hg = m.H;
    Eigen::Matrix2d Rg = R;
    const Eigen::Matrix2d learn = learnableScaleColumns(da, a, Hg, Rg);
    r = scaleConsiderUpdate(m.z - m.h, m.H, R, Hg, Rg, learn, g);
  } else {
    m.h = a;
    m.H = da;
    r = ekf_.correct(m, g);
  }
  record(Sensor::Encoders, iv.t1_s, r, g);
  if (n > kPhysicsStateDim && opt_.estimate_encoder_scales) {
    // Health monitor: CUSUM on the z_omega innovation (accepted or gated); an alarm re-opens
    // the scales, so the next updates estimate the fault instead of rejecting the encoders.
    // (Not at standstill: there omega = 0 is exact and a disagreement is the gyro's.)
    if (!encoders_standstill_ && r.S.rows() == 2 && r.S(1, 1) > 0 &&
        health_.encoderInnovation(iv.t1_s, r.innovation(1) / std::sqrt(r.S(1, 1))))
      reopenEncoderScales();
    encoderFaultPrior();
    if (opt_.encoder_fault_prior == EncoderFaultPrior::Either) encoderFaultDirection(iv);
    // A scale is a FAULT estimate only while the fault group is open (an alarm, or
    // open_sensor_errors_on_alarm off). Before the alarm the states hold the healthy
    // hypothesis (learn_healthy_encoder_scales: a healthy chair's radii, closed prior 0.5 %
    // per wheel, k_s split symmetrically): a fault present from the start that k_d has
    // partly absorbed would be reported unsided on both wheels ("right reads 1.3 % long"
    // for a left wheel 5 % short) and then reported back. At the alarm the learned k_d is
    // handed to the fault group as its starting value (reopenEncoderScales) and the side is
    // decided by the fault prior, the motor currents or the turn, as without learning.
    if (!scalesClosed()) health_.scales(iv.t1_s, sensorErrors());
  }
  wrap();
  if (!still) adaptSlipVariance(r, R, dt);
  nextEncoderInterval(Eigen::Vector2d(iv.v_m_s, iv.omega_rad_s), dt, iv.t1_s, r.accepted && !still);
}

Eigen::Matrix2d WheelchairEkf::learnableScaleColumns(
    const Eigen::Matrix<double, 2, Eigen::Dynamic>& da, const Eigen::Vector2d& a,
    Eigen::MatrixXd& H, Eigen::Matrix2d& R) const {
  // Rows z_v, z_omega; scale columns dz/d(k_s, k_d) = [[a_v, l_w a_omega / 4],
  // [a_omega, a_v / l_w]] (header). A scale LEARNS from an entry only through an excited
  // regressor, |a_j| > kExcitationSigmas sd(a_j): else the filter reads the regressor's own
  // noise as a scale (errors-in-variables shrinkage of k towards 0, e.g. gyro noise against the
  // encoders' exact 0 at standstill). An unexcited entry is CONSIDERED: zero in H, its
  // variance added to R. k_s never learns from z_v, whose regressor a_v is known only through
  // the motor model (6): its errors (~9 % at cruise speed on the simulator's drives) would
  // become a scale; and z_v treats k_s as known (no inflation of R), else the motor model
  // would take v over from the encoders. The absolute scale comes from z_omega against the
  // gyro while turning (docs/estimation.md, "Sensor-error states").
  constexpr double kExcitationSigmas = 5.0;
  const Eigen::MatrixXd& P = ekf_.P();
  const Eigen::Matrix2d Paa = da * P * da.transpose();
  const bool v_excited = std::fabs(a(0)) > kExcitationSigmas * std::sqrt(std::max(0.0, Paa(0, 0)));
  const bool w_excited = std::fabs(a(1)) > kExcitationSigmas * std::sqrt(std::max(0.0, Paa(1, 1)));
  Eigen::Matrix2d learn;  // rows z_v, z_omega; columns k_s, k_d
  learn << 0.0, w_excited ? 1.0 : 0.0, w_excited ? 1.0 : 0.0, v_excited ? 1.0 : 0.0;
  const Eigen::Matrix2d Hk = H.block<2, 2>(0, kIdxEncScaleS);
  Eigen::Matrix2d Hc = Hk - Hk.cwiseProduct(learn);  // considered entries
  Hc(0, 0) = 0.0;                                    // k_s in z_v: taken as known
  R += Hc * P.block<2, 2>(kIdxEncScaleS, kIdxEncScaleS) * Hc.transpose();
  H.block<2, 2>(0, kIdxEncScaleS) = Hk.cwiseProduct(learn);
  return learn;
}

namespace {
/// The covariance after x += K y for ANY gain K (first order, exact for a linear h):
/// the Joseph form (I - K H) P (I - K H)' + K R K', without n x n x n products:
/// A = P - K (P H')', then A - (A H') K' + K R K'.
template <int N, int M>
Eigen::Matrix<double, N, N> josephAnyGain(const Eigen::Matrix<double, N, N>& P,
                                          const Eigen::Matrix<double, N, M>& K,
                                          const Eigen::Matrix<double, N, M>& PHt,
                                          const Eigen::Matrix<double, M, N>& Ht,
                                          const Eigen::Matrix<double, M, M>& R) {
  Eigen::Matrix<double, N, N> Pn = P;
  // Coefficient-based products: at N = 12 Eigen would take its blocked GEMM (N + N + M > 20).
  Pn.noalias() -= K.lazyProduct(PHt.transpose());
  const Eigen::Matrix<double, N, M> AHt = Pn.lazyProduct(Ht.transpose());
  Pn.noalias() -= AHt.lazyProduct(K.transpose());
  const Eigen::Matrix<double, N, M> KR = K * R;
  Pn.noalias() += KR.lazyProduct(K.transpose());
  return Pn;
}

Eigen::Matrix2d inverse2(const Eigen::Matrix2d& S, double det) {
  Eigen::Matrix2d inv;
  inv << S(1, 1), -S(0, 1), -S(1, 0), S(0, 0);
  return inv / det;
}
}  // namespace

UpdateResult WheelchairEkf::scaleConsiderUpdate(const Eigen::Vector2d& y, const Eigen::MatrixXd& H,
                                                const Eigen::Matrix2d& R, const Eigen::MatrixXd& Hg,
                                                const Eigen::Matrix2d& Rg,
                                                const Eigen::Matrix2d& learn, double gate) {
  // Gain from the gain model (Hg, Rg: the learnable scale entries, docs/estimation.md), the
  // scale rows of the gain restricted to the entries they may learn from; covariance by the
  // Joseph form with the TRUE Jacobian H and noise R, which is the exact (first-order)
  // covariance of x + K y for ANY gain K: the pose keeps its correlation with the scales it
  // was not allowed to learn (the common scale before the first turn), so its sd grows with the
  // distance driven at an unknown scale and a later scale update corrects the pose as well.
  constexpr int N = kPhysicsStateDim + kNumSensorErrorStates;
  using MatN = Eigen::Matrix<double, N, N>;
  using MatN2 = Eigen::Matrix<double, N, 2>;
  using Mat2N = Eigen::Matrix<double, 2, N>;
  UpdateResult r;
  r.dof = 2;
  r.innovation = y;
  const MatN P = ekf_.P();
  const Mat2N Ht = H, Hgt = Hg;
  const MatN2 PHt = P.lazyProduct(Ht.transpose());
  Eigen::Matrix2d S = Ht * PHt + R;
  S = 0.5 * (S + S.transpose());
  r.S = S;
  const double det = S(0, 0) * S(1, 1) - S(0, 1) * S(1, 0);
  if (!(S(0, 0) > 0) || !(det > 0) || !std::isfinite(det)) {
    r.nis = std::numeric_limits<double>::infinity();
    return r;
  }
  r.nis = y.dot(inverse2(S, det) * y);
  if (gate > 0 && !(r.nis <= gate)) return r;
  // Gain of every state but k_s: computed as if k_s were known, from the covariance
  // conditional on k_s, Pc = P - D P(k_s, .) with D = P(., k_s) / P(k_s, k_s) the pose's (and
  // every state's) sensitivity to k_s. Without this the encoder innovation would be read as
  // news about k_s (hence about the pose through D) whenever the motor model (6) claims to
  // know v: its ~9 % friction error would move the pose.
  MatN Pc = P;
  Eigen::Matrix<double, N, 1> D = Eigen::Matrix<double, N, 1>::Zero();
  const double pkk = P(kIdxEncScaleS, kIdxEncScaleS);
  if (pkk > 0) {
    D = P.col(kIdxEncScaleS) / pkk;
    Pc -= D * P.row(kIdxEncScaleS);
  }
  const MatN2 PHg = Pc * Hgt.transpose();
  Eigen::Matrix2d Sg = Hgt * PHg + Rg;
  Sg = 0.5 * (Sg + Sg.transpose());
  MatN2 K = PHg * inverse2(Sg, Sg(0, 0) * Sg(1, 1) - Sg(0, 1) * Sg(1, 0));
  // k_d learns from its allowed rows (conditional gain); k_s only from z_omega while turning,
  // with the unconditional gain of that row, and every other state follows k_s's step along
  // its sensitivity D (the pose driven at the old scale is corrected: x += D dk_s).
  {
    constexpr int c = 1, i = kIdxEncScaleD;
    const bool l0 = learn(0, c) != 0, l1 = learn(1, c) != 0;
    if (!(l0 && l1)) {
      K(i, 0) = l0 ? PHg(i, 0) / Sg(0, 0) : 0.0;
      K(i, 1) = l1 ? PHg(i, 1) / Sg(1, 1) : 0.0;
    }
  }
  K.row(kIdxEncScaleS).setZero();
  if (learn(1, 0) != 0 && pkk > 0 && (!scalesClosed() || common_scale_learned_)) {
    const double kks = PHt(kIdxEncScaleS, 1) / S(1, 1);
    for (int j = 0; j < N; ++j)
      if (j != kIdxEncScaleS) K(j, 1) += D(j) * kks;
    K(kIdxEncScaleS, 1) = kks;
  }
  zeroClosedGainRows(K);                         // closed groups are consider states: not learned
  const Eigen::Matrix<double, N, 1> dx = K * y;  // (Ref binds it without a copy)
  applyGain(dx, josephAnyGain<N, 2>(P, K, PHt, Ht, R));
  r.accepted = true;
  return r;
}

Measurement& WheelchairEkf::gyroModel(const Eigen::VectorXd& x, double z, double R) {
  Measurement& m = gyro_m_;
  m.H.setZero();
  m.H.block<1, 7>(0, 0) = model::FilterModel::HOmega();
  m.z(0) = z;
  m.h(0) = model::FilterModel::hOmega(x.head<7>());
  if (pm_.stateDim() > kPhysicsStateDim) {  // z = omega + b_g
    m.H(0, kIdxGyroBias) = 1.0;
    m.h(0) += x(kIdxGyroBias);
  }
  m.R(0, 0) = R;
  return m;
}

Measurement& WheelchairEkf::sonarModel(const Eigen::VectorXd& x, double z, double R) {
  const FilterState x7 = x.head<7>();
  Measurement& m = sonar_m_;
  m.H.setZero();
  m.H.block<1, 7>(0, 0) = filterModel().HSonar(x7);
  m.z(0) = z;
  m.h(0) = filterModel().hSonar(x7);
  m.R(0, 0) = R;
  return m;
}

Measurement& WheelchairEkf::pozyxModel(const Eigen::VectorXd& x, const Eigen::Vector2d& z,
                                       const Eigen::Matrix2d& R) {
  const FilterState x7 = x.head<7>();
  Measurement& m = pozyx_m_;
  m.H.setZero();
  m.H.block<2, 7>(0, 0) = filterModel().HPozyx(x7);
  m.z = z;
  m.h = filterModel().hPozyx(x7);
  m.R = R;
  return m;
}

UpdateResult WheelchairEkf::correct(Measurement& m, double g) {
  const bool error_states = pm_.stateDim() > kPhysicsStateDim;
  // With the sensor-error states, the gyro does not teach the common encoder scale k_s
  // (scaleKnownUpdate; docs/estimation.md "Sensor-error states"); Pozyx does, and the sonar
  // (range rate to the static obstacle: the absolute speed) once the health monitor has found
  // an encoder fault (open_sensor_errors_on_alarm): until the first turn it is the only data
  // that tells a wheel reading short from the other reading long. Not on an alarm-free drive
  // (the scales are closed there) nor with the scales open from the start (it moved a clean
  // drive's pose by 20 cm when the obstacle came into view: range-only bearing ambiguity).
  const bool sonar_teaches = opt_.open_sensor_errors_on_alarm && encoder_scales_open_;
  const bool scale_known =
      error_states && m.dim() == 1 &&
      (m.sensor == Sensor::Gyro || (m.sensor == Sensor::Sonar && !sonar_teaches));
  if (error_states) addErrorNoise();
  const UpdateResult r = scale_known        ? scaleKnownUpdate(m.z(0) - m.h(0), m.H, m.R(0, 0), g)
                         : closedVariance() ? schmidtUpdate(m, g)
                                            : ekf_.correct(m, g);
  if (error_states && m.sensor == Sensor::Gyro) gyroHealth(m.z(0), m.R(0, 0));
  wrap();
  return r;
}

void WheelchairEkf::gyroHealth(double z_rad_s, double R) {
  // Health monitor: the gyro against the encoders' standstill (HealthMonitor.h); an alarm
  // opens the bias state (a step: variance topped up to the prior, cross-covariances kept).
  // At standstill the gyro is compared with the KNOWN omega = 0 (not with the filter's
  // omega, which follows the more precise gyro): nu = (z - b_g) / sqrt(R + var b_g + var_w).
  // "Known" to a tick: no tick on either wheel for T seconds bounds the mean |omega| over them
  // by w_max = 2 tick_m / (l_w T) (each rim moved less than a tick); var_w = w_max^2 / 3
  // (uniform). Without it the chair's last sub-tick creep when stopping (or first, when
  // starting) was read as a gyro bias: false alarms on clean three-task drives at 20.8 s.
  const double t = ekf_.time();
  const double var_b = std::max(0.0, ekf_.P()(kIdxGyroBias, kIdxGyroBias));
  const double still_s = std::max(t - standstill_since_s_, 1e-3);
  const double w_max = 2.0 * wheel_radius_m_ * wheel_rad_per_tick_ / (track_width_m_ * still_s);
  const double nu = (z_rad_s - ekf_.x()(kIdxGyroBias)) / std::sqrt(R + var_b + w_max * w_max / 3.0);
  // A standstill is a run of tick-free encoder intervals lasting kMinStandstill_s: a single
  // tick-free interval is also what a wheel passing through zero speed gives while the chair
  // turns (reversing, turning about one wheel), where the chair is not still and the
  // readings share the sign of the turn. On the one-hour excite drive 1080 of its 1193
  // "standstill" gyro readings were such zero crossings (runs < 0.1 s, mean nu -0.10), and
  // their CUSUM, summed over crossings tens of seconds apart, alarmed at 1786 s (a false
  // bias). A real stop lasts seconds.
  constexpr double kMinStandstill_s = 0.25;
  const bool standing = encoders_standstill_ && t - standstill_since_s_ >= kMinStandstill_s;
  if (standing && health_.gyroInnovation(t, nu, opt_.estimate_gyro_bias) &&
      opt_.estimate_gyro_bias) {
    Pw_ = ekf_.P();
    const double s2 = opt_.gyro_bias_sigma_rad_s * opt_.gyro_bias_sigma_rad_s;
    Pw_(kIdxGyroBias, kIdxGyroBias) += std::max(0.0, s2 - Pw_(kIdxGyroBias, kIdxGyroBias));
    ekf_.setCovariance(Pw_);
    if (!gyro_bias_open_) gyro_bias_open_ = true, gyro_noise_t_s_ = t;
  }
  if (opt_.estimate_gyro_bias)
    health_.gyroBias(t, ekf_.x()(kIdxGyroBias),
                     std::sqrt(std::max(0.0, ekf_.P()(kIdxGyroBias, kIdxGyroBias))));
}

bool WheelchairEkf::scalesClosed() const {
  return opt_.open_sensor_errors_on_alarm && !encoder_scales_open_;
}

bool WheelchairEkf::closedVariance() const {
  if (pm_.stateDim() <= kPhysicsStateDim || !opt_.open_sensor_errors_on_alarm) return false;
  const Eigen::MatrixXd& P = ekf_.P();
  return (!encoder_scales_open_ &&
          (P(kIdxEncScaleS, kIdxEncScaleS) > 0 || P(kIdxEncScaleD, kIdxEncScaleD) > 0)) ||
         (!gyro_bias_open_ && P(kIdxGyroBias, kIdxGyroBias) > 0);
}

void WheelchairEkf::zeroClosedGainRows(Eigen::Ref<Eigen::MatrixXd> K) const {
  if (!opt_.open_sensor_errors_on_alarm || K.rows() <= kPhysicsStateDim) return;
  if (!encoder_scales_open_ && !common_scale_learned_) K.row(kIdxEncScaleS).setZero();
  if (!encoder_scales_open_ && !scale_difference_open_) K.row(kIdxEncScaleD).setZero();
  if (!gyro_bias_open_) K.row(kIdxGyroBias).setZero();
}

namespace {
/// Schmidt-Kalman update of an M-dimensional reading: the Kalman gain K = P H' S^-1 with the
/// rows of the consider states zeroed by `zero_rows`, covariance by the Joseph form (exact for
/// any gain). Returns false (r: NIS, S) when S is not positive definite or the gate rejects.
template <int M, class ZeroRows>
bool schmidtGain(const Eigen::MatrixXd& P_in, const Eigen::MatrixXd& H_in,
                 const Eigen::MatrixXd& R_in, const Eigen::VectorXd& y_in, double gate,
                 const ZeroRows& zero_rows, UpdateResult& r,
                 Eigen::Matrix<double, kPhysicsStateDim + kNumSensorErrorStates, 1>& dx,
                 Eigen::Matrix<double, kPhysicsStateDim + kNumSensorErrorStates,
                               kPhysicsStateDim + kNumSensorErrorStates>& P_new) {
  constexpr int N = kPhysicsStateDim + kNumSensorErrorStates;
  using MatN = Eigen::Matrix<double, N, N>;
  using MatNM = Eigen::Matrix<double, N, M>;
  using MatM = Eigen::Matrix<double, M, M>;
  const MatN P = P_in;
  const Eigen::Matrix<double, M, N> H = H_in;
  const MatM R = R_in;
  const Eigen::Matrix<double, M, 1> y = y_in;
  r.dof = M;
  r.innovation = y_in;
  const MatNM PHt = P.lazyProduct(H.transpose());
  MatM S = H * PHt + R;
  S = 0.5 * (S + S.transpose());
  r.S = S;
  const Eigen::LLT<MatM> llt(S);
  if (llt.info() != Eigen::Success || !std::isfinite(S.sum())) {
    r.nis = std::numeric_limits<double>::infinity();
    return false;
  }
  r.nis = y.dot(llt.solve(y));
  if (gate > 0 && !(r.nis <= gate)) return false;
  MatNM K = llt.solve(PHt.transpose()).transpose();
  zero_rows(K);
  dx = K * y;
  P_new = josephAnyGain<N, M>(P, K, PHt, H, R);
  return true;
}
}  // namespace

UpdateResult WheelchairEkf::schmidtUpdate(Measurement& m, double gate) {
  // A reading while a sensor-error group is closed but carries its consider variance: the
  // other states get the Schmidt gain (the x rows of the Kalman gain with the full P, which
  // accounts for the consider states' uncertainty and their correlation with x), the closed
  // states none; P_cc stays, P_xc <- (I - K_x H_x) P_xc - K_x H_c P_cc (Joseph form).
  constexpr int N = kPhysicsStateDim + kNumSensorErrorStates;
  UpdateResult r;
  Eigen::Matrix<double, N, 1> dx;
  Eigen::Matrix<double, N, N> Pn;
  const auto zero = [this](auto& K) { zeroClosedGainRows(K); };
  const Eigen::VectorXd& y = m.innovation();
  const bool ok = m.dim() == 1 ? schmidtGain<1>(ekf_.P(), m.H, m.R, y, gate, zero, r, dx, Pn)
                               : schmidtGain<2>(ekf_.P(), m.H, m.R, y, gate, zero, r, dx, Pn);
  if (!ok) return r;
  applyGain(dx, Pn);
  r.accepted = true;
  return r;
}

void WheelchairEkf::applyGain(const Eigen::Ref<const Eigen::VectorXd>& dx,
                              const Eigen::Ref<const Eigen::MatrixXd>& P_new) {
  xs_ = ekf_.x();
  xs_ += dx;
  Pw_ = P_new;
  ekf_.setState(xs_);
  ekf_.setCovariance(Pw_);
}

UpdateResult WheelchairEkf::scaleKnownUpdate(double y, const Eigen::MatrixXd& H, double R,
                                             double gate) {
  // A scalar update that does not learn the common encoder scale k_s: gain from the
  // covariance conditional on k_s (as in scaleConsiderUpdate), covariance by the Joseph form.
  constexpr int N = kPhysicsStateDim + kNumSensorErrorStates;
  using MatN = Eigen::Matrix<double, N, N>;
  using VecN = Eigen::Matrix<double, N, 1>;
  UpdateResult r;
  r.dof = 1;
  r.innovation = Eigen::VectorXd::Constant(1, y);
  const MatN P = ekf_.P();
  const Eigen::Matrix<double, 1, N> Ht = H;
  const VecN PHt = P * Ht.transpose();
  const double S = Ht.dot(PHt) + R;
  r.S = Eigen::MatrixXd::Constant(1, 1, S);
  if (!(S > 0) || !std::isfinite(S)) {
    r.nis = std::numeric_limits<double>::infinity();
    return r;
  }
  r.nis = y * y / S;
  if (gate > 0 && !(r.nis <= gate)) return r;
  VecN PcHt = PHt;
  const double pkk = P(kIdxEncScaleS, kIdxEncScaleS);
  if (pkk > 0) PcHt -= P.col(kIdxEncScaleS) * (PHt(kIdxEncScaleS) / pkk);
  const double Sc = Ht.dot(PcHt) + R;
  VecN K = PcHt / Sc;
  K(kIdxEncScaleS) = 0.0;
  zeroClosedGainRows(K);
  const VecN dx = K * y;
  applyGain(dx, josephAnyGain<N, 1>(P, K, PHt, Ht, Eigen::Matrix<double, 1, 1>::Constant(R)));
  r.accepted = true;
  return r;
}

SensorErrorEstimate WheelchairEkf::sensorErrors() const {
  SensorErrorEstimate e;
  if (pm_.stateDim() <= kPhysicsStateDim) return e;
  const Eigen::VectorXd& x = ekf_.x();
  const Eigen::MatrixXd& P = ekf_.P();
  auto sd = [&](int i) { return std::sqrt(std::max(0.0, P(i, i))); };
  e.present = true;
  e.t_s = ekf_.time();
  // k_R = k_s + k_d / 2, k_L = k_s - k_d / 2.
  const double vs = P(kIdxEncScaleS, kIdxEncScaleS), vd = P(kIdxEncScaleD, kIdxEncScaleD);
  const double c = P(kIdxEncScaleS, kIdxEncScaleD);
  e.encoder_scale_right = x(kIdxEncScaleS) + 0.5 * x(kIdxEncScaleD);
  e.encoder_scale_right_sd = std::sqrt(std::max(0.0, vs + 0.25 * vd + c));
  e.encoder_scale_left = x(kIdxEncScaleS) - 0.5 * x(kIdxEncScaleD);
  e.encoder_scale_left_sd = std::sqrt(std::max(0.0, vs + 0.25 * vd - c));
  // k_R / k_L = (k_s + k_d / 2) / (k_s - k_d / 2): gradient (-k_d, 2 k_s) / (k_s - k_d / 2)^2.
  const double ks = x(kIdxEncScaleS), kd = x(kIdxEncScaleD), den = ks - 0.5 * kd;
  const Eigen::Vector2d gr(-kd / (den * den), ks / (den * den));
  e.encoder_scale_ratio = (ks + 0.5 * kd) / den;
  e.encoder_scale_ratio_sd = std::sqrt(
      std::max(0.0, double(gr.transpose() * P.block<2, 2>(kIdxEncScaleS, kIdxEncScaleS) * gr)));
  e.gyro_bias_rad_s = x(kIdxGyroBias);
  e.gyro_bias_sd_rad_s = sd(kIdxGyroBias);
  return e;
}

EstimateSample WheelchairEkf::estimate() const {
  return canonicalFromFilterState(ekf_.time(), ekf_.x(), ekf_.P(), filterModel().form(),
                                  obstacle_initialised_);
}

}  // namespace wheelchair::estimation
