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

model::FilterState BaselineEkf::toModelState(Eigen::Matrix<double, 7, 7>* J) const {
  const double phi = x_(kBphi), c = std::cos(phi), s = std::sin(phi);
  Eigen::Matrix2d Rt;  // R(phi)'
  Rt << c, s, -s, c;
  Eigen::Matrix2d dRt;  // d R(phi)' / d phi
  dRt << -s, c, -c, -s;
  const Eigen::Vector2d rel(x_(kBox) - x_(kBx), x_(kBoy) - x_(kBy));
  model::FilterState m;
  m << x_(kBv), x_(kBomega), x_(kBx), x_(kBy), phi, Rt * rel;
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

void BaselineEkf::initObstacleFromSonar(double range) {
  setObstacleBody(sonarPointBody(range), sonarPointCovBody(range));
  obstacle_initialised_ = true;
}

UpdateResult BaselineEkf::apply(const Eigen::VectorXd& y, const Eigen::MatrixXd& H,
                                const Eigen::MatrixXd& R, double g) {
  const UpdateResult r = josephUpdate(x_, P_, y, H, R, g);
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
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, kBaselineStateDim);
  H(0, kBv) = 1;
  H(1, kBomega) = 1;
  const Eigen::Vector2d y(iv.v_m_s - x_(kBv), iv.omega_rad_s - x_(kBomega));
  const double g = gate(2);
  record(Sensor::Encoders, iv.t1_s, apply(y, H, encoderNoise(dt), g), g);
}

UpdateResult BaselineEkf::gyroUpdate(double z, double R, double g) {
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, kBaselineStateDim);
  H(0, kBomega) = 1;
  Eigen::VectorXd y(1);
  y(0) = z - x_(kBomega);
  return apply(y, H, Eigen::MatrixXd::Constant(1, 1, R), g);
}

UpdateResult BaselineEkf::sonarUpdate(double z, double R, double g) {
  Eigen::Matrix<double, 7, 7> J;
  const model::FilterState m = toModelState(&J);
  const Eigen::MatrixXd H = fm_.HSonar(m) * J;
  Eigen::VectorXd y(1);
  y(0) = z - fm_.hSonar(m);
  return apply(y, H, Eigen::MatrixXd::Constant(1, 1, R), g);
}

UpdateResult BaselineEkf::pozyxUpdate(const Eigen::Vector2d& z, const Eigen::Matrix2d& R,
                                      double g) {
  Eigen::Matrix<double, 7, 7> J;
  const model::FilterState m = toModelState(&J);
  const Eigen::MatrixXd H = fm_.HPozyx(m) * J;
  const Eigen::VectorXd y = z - fm_.hPozyx(m);
  return apply(y, H, R, g);
}

EstimateSample BaselineEkf::estimate() const {
  Eigen::Matrix<double, 7, 7> J;
  const model::FilterState m = toModelState(&J);
  const Eigen::MatrixXd Pm = J * P_ * J.transpose();
  return canonicalFromFilterState(t_, m, Pm, model::ObstacleForm::Cartesian, obstacle_initialised_);
}

}  // namespace wheelchair::estimation
