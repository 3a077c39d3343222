#include "libwheelchair/estimation/BaselineEkf.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/WheelchairEkf.h"
#include "libwheelchair/model/Kinematics.h"

#include <cmath>

namespace wheelchair::estimation {

namespace {
// Baseline state indices.
enum : int { kBx = 0, kBy = 1, kBphi = 2, kBv = 3, kBomega = 4, kBox = 5, kBoy = 6 };

model::FilterModel makeModel(const config::WheelchairConfig& cfg) {
  model::FilterModelParams p;  // only the measurement functions are used (no dynamics)
  p.form = model::ObstacleForm::Cartesian;
  p.sonar_offset_m = Eigen::Vector2d(cfg.sonar.x_m, cfg.sonar.y_m);
  p.pozyx_lever_arm_m = Eigen::Vector2d(cfg.pozyx.lever_x_m, cfg.pozyx.lever_y_m);
  return model::FilterModel(p);
}
}  // namespace

BaselineEkf::BaselineEkf(const config::WheelchairConfig& cfg, const EkfOptions& opt)
    : Estimator(cfg, opt), fm_(makeModel(cfg)) {
  q_ << opt_.baseline_q_xy_m2_s, opt_.baseline_q_xy_m2_s, opt_.baseline_q_phi_rad2_s,
      opt_.baseline_q_v_m2_s3, opt_.baseline_q_omega_rad2_s3, opt_.baseline_q_obstacle_m2_s,
      opt_.baseline_q_obstacle_m2_s;
  x_ = Eigen::VectorXd::Zero(kBaselineStateDim);
  P_ = Eigen::MatrixXd::Identity(kBaselineStateDim, kBaselineStateDim);
  enc_m_ = Measurement(Sensor::Encoders, 2, kBaselineStateDim);
  gyro_m_ = Measurement(Sensor::Gyro, 1, kBaselineStateDim);
  sonar_m_ = Measurement(Sensor::Sonar, 1, kBaselineStateDim);
  pozyx_m_ = Measurement(Sensor::Pozyx, 2, kBaselineStateDim);
}

void BaselineEkf::start(double t0) {
  t_ = t0;
  x_.setZero();
  P_.setZero();
  P_(kBx, kBx) = P_(kBy, kBy) = opt_.initial_sigma_xy_m * opt_.initial_sigma_xy_m;
  P_(kBphi, kBphi) = opt_.initial_sigma_phi_rad * opt_.initial_sigma_phi_rad;
  P_(kBv, kBv) = opt_.initial_sigma_v_m_s * opt_.initial_sigma_v_m_s;
  P_(kBomega, kBomega) = opt_.initial_sigma_omega_rad_s * opt_.initial_sigma_omega_rad_s;
  setObstacleBody(configObstacle(), configObstacleCov());
  obstacle_initialised_ = opt_.initial_obstacle == ObstacleInit::Config;
}

void BaselineEkf::predictTo(double t) {
  const double dt = t - t_;
  if (!(dt > 0)) return;
  const double phi = x_(kBphi), v = x_(kBv), c = std::cos(phi), s = std::sin(phi);
  Eigen::MatrixXd F = Eigen::MatrixXd::Identity(kBaselineStateDim, kBaselineStateDim);
  F(kBx, kBphi) = -dt * v * s;
  F(kBx, kBv) = dt * c;
  F(kBy, kBphi) = dt * v * c;
  F(kBy, kBv) = dt * s;
  F(kBphi, kBomega) = dt;
  x_(kBx) += dt * v * c;
  x_(kBy) += dt * v * s;
  x_(kBphi) = model::wrapAngle(x_(kBphi) + dt * x_(kBomega));
  const Eigen::MatrixXd Pn = F * P_ * F.transpose() + Eigen::MatrixXd(dt * q_.asDiagonal());
  P_ = 0.5 * (Pn + Pn.transpose());
  t_ = t;
}

model::FilterState BaselineEkf::toModelState(const Eigen::VectorXd& xb,
                                             Eigen::Matrix<double, 7, 7>* J) {
  const double phi = xb(kBphi), c = std::cos(phi), s = std::sin(phi);
  Eigen::Matrix2d Rt;  // R(phi)'
  Rt << c, s, -s, c;
  Eigen::Matrix2d dRt;  // d R(phi)' / d phi
  dRt << -s, c, -c, -s;
  const Eigen::Vector2d rel(xb(kBox) - xb(kBx), xb(kBoy) - xb(kBy));
  model::FilterState m;
  m << xb(kBv), xb(kBomega), xb(kBx), xb(kBy), phi, Rt * rel;
  if (J) {
    J->setZero();
    (*J)(model::kIdxV, kBv) = 1;
    (*J)(model::kIdxOmega, kBomega) = 1;
    (*J)(model::kIdxX, kBx) = 1;
    (*J)(model::kIdxY, kBy) = 1;
    (*J)(model::kIdxPhi, kBphi) = 1;
    J->block<2, 2>(model::kIdxO1, kBx) = -Rt;
    J->block<2, 1>(model::kIdxO1, kBphi) = dRt * rel;
    J->block<2, 2>(model::kIdxO1, kBox) = Rt;
  }
  return m;
}

void BaselineEkf::setObstacleBody(const Eigen::Vector2d& pb, const Eigen::Matrix2d& Cb) {
  const double phi = x_(kBphi), c = std::cos(phi), s = std::sin(phi);
  Eigen::Matrix2d R;
  R << c, -s, s, c;
  Eigen::Matrix2d dR;
  dR << -s, -c, c, -s;
  // o = (x, y) + R(phi) pb: Jacobian wrt the pose, then landmark initialisation.
  Eigen::Matrix<double, 2, kBaselineStateDim> Jp =
      Eigen::Matrix<double, 2, kBaselineStateDim>::Zero();
  Jp(0, kBx) = 1;
  Jp(1, kBy) = 1;
  const Eigen::Vector2d dpb = dR * pb;
  Jp(0, kBphi) = dpb.x();
  Jp(1, kBphi) = dpb.y();
  x_.segment<2>(kBox) = x_.segment<2>(kBx) + R * pb;
  P_.middleRows<2>(kBox).setZero();
  P_.middleCols<2>(kBox).setZero();
  const Eigen::MatrixXd cross = Jp * P_;  // obstacle rows (pose part only: obstacle cols are 0)
  P_.middleRows<2>(kBox) = cross;
  P_.middleCols<2>(kBox) = cross.transpose();
  P_.block<2, 2>(kBox, kBox) = cross * Jp.transpose() + R * Cb * R.transpose();
  P_ = 0.5 * (P_ + P_.transpose()).eval();
}

void BaselineEkf::inflatePositionCovariance(double var) {
  P_(kBx, kBx) += var;
  P_(kBy, kBy) += var;
}

void BaselineEkf::initObstacleFromSonar(double range) {
  setObstacleBody(sonarPointBody(range), sonarPointCovBody(range));
  obstacle_initialised_ = true;
}

UpdateResult BaselineEkf::correct(Measurement& m, double g) {
  const UpdateResult r = estimation::correct(x_, P_, m, g);
  x_(kBphi) = model::wrapAngle(x_(kBphi));
  return r;
}

void BaselineEkf::encoderInterval(const sensors::WheelSpeedInterval& iv) {
  SensorStats& st = stats(Sensor::Encoders);
  if (!opt_.use_encoders) {
    ++st.skipped;
    return;
  }
  const double dt = iv.dt();
  if (!(dt > 0) || dt > opt_.max_encoder_interval_s || !std::isfinite(iv.v_m_s) ||
      !std::isfinite(iv.omega_rad_s)) {
    ++st.dropouts;
    return;
  }
  // The mean speeds of the interval taken as (v, omega) at its end.
  Measurement& m = enc_m_;
  m.H.setZero();
  m.H(0, kBv) = 1;
  m.H(1, kBomega) = 1;
  m.z << iv.v_m_s, iv.omega_rad_s;
  m.h << x_(kBv), x_(kBomega);
  m.R = encoderNoise(dt);
  const double g = gate(2);
  record(Sensor::Encoders, iv.t1_s, correct(m, g), g);
}

Measurement& BaselineEkf::gyroModel(const Eigen::VectorXd& x, double z, double R) {
  Measurement& m = gyro_m_;
  m.H.setZero();
  m.H(0, kBomega) = 1;
  m.z(0) = z;
  m.h(0) = x(kBomega);
  m.R(0, 0) = R;
  return m;
}

Measurement& BaselineEkf::sonarModel(const Eigen::VectorXd& x, double z, double R) {
  Eigen::Matrix<double, 7, 7> J;
  const model::FilterState ms = toModelState(x, &J);
  Measurement& m = sonar_m_;
  m.H = fm_.HSonar(ms) * J;
  m.z(0) = z;
  m.h(0) = fm_.hSonar(ms);
  m.R(0, 0) = R;
  return m;
}

Measurement& BaselineEkf::pozyxModel(const Eigen::VectorXd& x, const Eigen::Vector2d& z,
                                     const Eigen::Matrix2d& R) {
  Eigen::Matrix<double, 7, 7> J;
  const model::FilterState ms = toModelState(x, &J);
  Measurement& m = pozyx_m_;
  m.H = fm_.HPozyx(ms) * J;
  m.z = z;
  m.h = fm_.hPozyx(ms);
  m.R = R;
  return m;
}

EstimateSample BaselineEkf::estimate() const {
  Eigen::Matrix<double, 7, 7> J;
  const model::FilterState m = toModelState(x_, &J);
  const Eigen::MatrixXd Pm = J * P_ * J.transpose();
  return canonicalFromFilterState(t_, m, Pm, model::ObstacleForm::Cartesian, obstacle_initialised_);
}

}  // namespace wheelchair::estimation
