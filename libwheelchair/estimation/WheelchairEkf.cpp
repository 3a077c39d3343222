#include "libwheelchair/estimation/WheelchairEkf.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/model/VehicleParams.h"

#include <cmath>

namespace wheelchair::estimation {

using model::FilterState;
using model::ObstacleForm;

// ---------------------------------------------------------------------------------------------
// Process model

WheelchairProcessModel::WheelchairProcessModel(const model::FilterModel& fm,
                                               const Eigen::Matrix<double, 7, 1>& q,
                                               double current_density)
    : fm_(fm) {
  Q_.setZero();
  Q_.topLeftCorner<7, 7>() = q.asDiagonal();
  // Current-sensor noise enters like process noise through G = df/du.
  const model::FilterInputJacobian G = fm_.G();
  Q_.topLeftCorner<7, 7>() += current_density * G * G.transpose();
}

namespace {

// The accumulators s_v, s_omega on top of the 7-state model: sdot = (v, omega), no other
// dependence.
void augmentRate(const Eigen::VectorXd& x, const FilterState& xd7, Eigen::VectorXd& xdot) {
  xdot.resize(kPhysicsStateDim);
  xdot.head<7>() = xd7;
  xdot(kIdxSv) = x(model::kIdxV);
  xdot(kIdxSomega) = x(model::kIdxOmega);
}

void augmentJacobian(const model::FilterStateJacobian& F7, Eigen::MatrixXd& F) {
  F.setZero(kPhysicsStateDim, kPhysicsStateDim);
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
  augmentJacobian(fm_.F(x.head<7>()), F);
}

void WheelchairProcessModel::fAndF(const Eigen::VectorXd& x, const Eigen::VectorXd& u,
                                   Eigen::VectorXd& xdot, Eigen::MatrixXd& F) const {
  FilterState xd7;
  model::FilterStateJacobian F7;
  fm_.fAndF(x.head<7>(), model::FilterInput(u(0), u(1)), xd7, F7);
  augmentRate(x, xd7, xdot);
  augmentJacobian(F7, F);
}

void WheelchairProcessModel::Q(const Eigen::VectorXd&, const Eigen::VectorXd&,
                               Eigen::MatrixXd& Q) const {
  Q = Q_;
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
  q << o.q_v_m2_s3, o.q_omega_rad2_s3, o.q_xy_m2_s, o.q_xy_m2_s, o.q_phi_rad2_s, o.q_obstacle_m2_s,
      polar ? o.q_obstacle_bearing_rad2_s : o.q_obstacle_m2_s;
  return q;
}

}  // namespace

WheelchairEkf::WheelchairEkf(const config::WheelchairConfig& cfg, const EkfOptions& opt,
                             const InputSignal* input)
    : Estimator(cfg, opt),
      input_(input),
      zero_input_(opt.input_interpolation),
      pm_(makeFilterModel(cfg, opt_), processNoiseDiag(opt_), opt_.current_noise_density_A2_s),
      ekf_(pm_, opt_.cvode) {
  if (!input_) input_ = &zero_input_;
  u_in_.signal = input_;
  xs_.resize(kPhysicsStateDim);
}

FilterState WheelchairEkf::head() const {
  return ekf_.x().head<7>();
}

void WheelchairEkf::start(double t0) {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(kPhysicsStateDim);
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(kPhysicsStateDim, kPhysicsStateDim);
  P(model::kIdxV, model::kIdxV) = opt_.initial_sigma_v_m_s * opt_.initial_sigma_v_m_s;
  P(model::kIdxOmega, model::kIdxOmega) =
      opt_.initial_sigma_omega_rad_s * opt_.initial_sigma_omega_rad_s;
  P(model::kIdxX, model::kIdxX) = opt_.initial_sigma_xy_m * opt_.initial_sigma_xy_m;
  P(model::kIdxY, model::kIdxY) = opt_.initial_sigma_xy_m * opt_.initial_sigma_xy_m;
  P(model::kIdxPhi, model::kIdxPhi) = opt_.initial_sigma_phi_rad * opt_.initial_sigma_phi_rad;
  ekf_.reset(t0, x, P);
  // Obstacle at its most likely place: configured position (also the placeholder until the
  // first valid sonar reading in first_sonar mode).
  setObstacle(configObstacle(), configObstacleCov());
  obstacle_initialised_ = opt_.initial_obstacle == ObstacleInit::Config;
  acc_valid_ = false;
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
  acc_start_s_ = t;
  acc_valid_ = true;
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
    resetAccumulators(iv.t1_s);
    return;
  }
  const Eigen::Vector2d z(iv.v_m_s, iv.omega_rad_s);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, kPhysicsStateDim);
  Eigen::Vector2d h;
  const Eigen::VectorXd& x = ekf_.x();
  if (opt_.encoder_model == EncoderMeasurementModel::Mean) {
    h << x(kIdxSv) / dt, x(kIdxSomega) / dt;
    H(0, kIdxSv) = 1.0 / dt;
    H(1, kIdxSomega) = 1.0 / dt;
  } else {
    h << model::FilterModel::hV(x.head<7>()), model::FilterModel::hOmega(x.head<7>());
    H.block<1, 7>(0, 0) = model::FilterModel::HV();
    H.block<1, 7>(1, 0) = model::FilterModel::HOmega();
  }
  const double g = gate(2);
  const UpdateResult r = ekf_.update(z - h, H, encoderNoise(dt), g);
  record(Sensor::Encoders, iv.t1_s, r, g);
  wrap();
  resetAccumulators(iv.t1_s);
}

UpdateResult WheelchairEkf::gyroUpdate(double z, double R, double g) {
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, kPhysicsStateDim);
  H.block<1, 7>(0, 0) = model::FilterModel::HOmega();
  Eigen::VectorXd y(1);
  y(0) = z - model::FilterModel::hOmega(head());
  const UpdateResult r = ekf_.update(y, H, Eigen::MatrixXd::Constant(1, 1, R), g);
  wrap();
  return r;
}

UpdateResult WheelchairEkf::sonarUpdate(double z, double R, double g) {
  const FilterState x7 = head();
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, kPhysicsStateDim);
  H.block<1, 7>(0, 0) = filterModel().HSonar(x7);
  Eigen::VectorXd y(1);
  y(0) = z - filterModel().hSonar(x7);
  const UpdateResult r = ekf_.update(y, H, Eigen::MatrixXd::Constant(1, 1, R), g);
  wrap();
  return r;
}

UpdateResult WheelchairEkf::pozyxUpdate(const Eigen::Vector2d& z, const Eigen::Matrix2d& R,
                                        double g) {
  const FilterState x7 = head();
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, kPhysicsStateDim);
  H.block<2, 7>(0, 0) = filterModel().HPozyx(x7);
  const Eigen::VectorXd y = z - filterModel().hPozyx(x7);
  const UpdateResult r = ekf_.update(y, H, R, g);
  wrap();
  return r;
}

EstimateSample WheelchairEkf::estimate() const {
  return canonicalFromFilterState(ekf_.time(), ekf_.x(), ekf_.P(), filterModel().form(),
                                  obstacle_initialised_);
}

}  // namespace wheelchair::estimation
