// Baseline: a discrete-time kinematic EKF of the robot_localization kind (no physics, no motor
// currents), for comparison with the physics CD-EKF (docs/estimation.md, "Baseline").
//
// State (7): [x, y, phi, v, omega, ox, oy]: pose in the start frame, constant-velocity model
// for (v, omega) (random walks), and the static obstacle in the START frame (constant).
// Prediction over dt by one explicit Euler step of (1), as robot_localization does:
//   x+ = x + dt f(x),  F = I + dt df/dx,  P+ = F P F' + dt Q.
// Measurements as for the physics filter, except that an encoder interval's mean speeds are
// taken as (v, omega) at the interval's end (what a ROS odometry twist means). The sonar range
// uses model::FilterModel::hSonar on the obstacle mapped into the base frame.
#pragma once

#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/model/FilterModel.h"

namespace wheelchair::estimation {

constexpr int kBaselineStateDim = 7;

class BaselineEkf : public Estimator {
 public:
  BaselineEkf(const config::WheelchairConfig& cfg, const EkfOptions& opt);

  void start(double t0_s) override;
  void predictTo(double t_s) override;
  double time() const override { return t_; }
  EstimateSample estimate() const override;
  void encoderStart(double) override {}
  void encoderInterval(const sensors::WheelSpeedInterval& iv) override;

  const Eigen::VectorXd& x() const { return x_; }
  const Eigen::MatrixXd& P() const { return P_; }

  const Eigen::VectorXd& state() const override { return x_; }
  Measurement& gyroModel(const Eigen::VectorXd& x, double z, double R) override;
  /// Sonar and Pozyx: model::FilterModel's h and H on the model state of x, H chained with
  /// d(model state)/d(baseline state).
  Measurement& sonarModel(const Eigen::VectorXd& x, double z, double R) override;
  Measurement& pozyxModel(const Eigen::VectorXd& x, const Eigen::Vector2d& z_start,
                          const Eigen::Matrix2d& R) override;

 protected:
  /// Measurement.h correct(), then phi wrapped.
  UpdateResult correct(Measurement& m, double gate) override;
  bool obstacleInitialised() const override { return obstacle_initialised_; }
  void initObstacleFromSonar(double range_m) override;
  void inflatePositionCovariance(double var_m2) override;

 private:
  /// The model's state for this estimate (obstacle in the base frame, Cartesian) and the
  /// Jacobian d(model state)/d(baseline state).
  static model::FilterState toModelState(const Eigen::VectorXd& x, Eigen::Matrix<double, 7, 7>* J);
  void setObstacleBody(const Eigen::Vector2d& p_body, const Eigen::Matrix2d& cov_body);

  model::FilterModel fm_;
  double t_ = 0;
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
  Eigen::Matrix<double, 7, 1> q_;
  bool obstacle_initialised_ = false;
  Measurement enc_m_, gyro_m_, sonar_m_, pozyx_m_;  ///< preallocated (sized once)
};

}  // namespace wheelchair::estimation
