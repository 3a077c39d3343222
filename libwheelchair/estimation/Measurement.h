// One measurement model shape and one update path for every EKF of the library: the physics
// CD-EKF (WheelchairEkf on CdEkf), the kinematic baseline (BaselineEkf) and the command-driven
// EKF (CommandDrivenEkf). robot_localization's Measurement + one correct() is the model.
//
// A Measurement is a sensor model linearised at the filter's current state:
//   z (dim)        the reading, in the sensor's units (m, rad, m/s, rad/s)
//   h (dim)        its prediction h(x) at the current state
//   H (dim x n)    dh/dx at the current state
//   R (dim x dim)  the reading's noise covariance
//   angular rows   rows whose innovation is an angle: wrapped to (-pi, pi] (model::wrapAngle)
//   sensor         the Sensor its NIS is booked under (EstimationResult::sensors)
// correct() is the one update: innovation y = z - h (angular rows wrapped), S = H P H' + R,
// NIS = y' S^-1 y, the chi-square gate (applied only when NIS <= gate; gate <= 0: always), and
// the Joseph-form update of CdEkf.h josephUpdate with its non-positive-definite guard (a
// degenerate S rejects the reading, NIS = inf). bookUpdate() records the attempt: counts, NIS
// statistics over the accepted updates, the rejected list, per-update NIS records.
//
// Storage: a filter keeps one Measurement per sensor, sized once (Measurement(sensor, dim, n));
// filling it and correct() allocate nothing beyond what josephUpdate returns.
//
// Each filter's H is checked against central differences of its h in the tests
// (tests/estimation/test_measurement_models.cpp).
//
// Example (gyro on a state with omega at index 1, sigma 0.01 rad/s):
//   Measurement m(Sensor::Gyro, 1, n);        // once
//   m.H.setZero();  m.H(0, 1) = 1.0;          // per reading
//   m.z(0) = gyro_z;  m.h(0) = x(1);  m.R(0, 0) = 1e-4;
//   const UpdateResult r = correct(x, P, m, chi2Quantile(0.999, 1));
//   bookUpdate(result, m.sensor, t, r, gate, true);
#pragma once

#include "libwheelchair/estimation/CdEkf.h"
#include "libwheelchair/estimation/EstimationTypes.h"

#include <Eigen/Core>

namespace wheelchair::estimation {

struct Measurement {
  Measurement() = default;
  /// Storage for a dim-dimensional reading of `sensor` on an n-dimensional state (zeroed).
  Measurement(Sensor sensor, int dim, int state_dim);

  Sensor sensor = Sensor::Encoders;
  Eigen::VectorXd z;          ///< reading (dim)
  Eigen::VectorXd h;          ///< predicted reading h(x) (dim)
  Eigen::MatrixXd H;          ///< dh/dx (dim x n)
  Eigen::MatrixXd R;          ///< noise covariance (dim x dim)
  unsigned angular_rows = 0;  ///< bit i set: row i is an angle (its innovation is wrapped)

  int dim() const { return static_cast<int>(z.size()); }
  /// y = z - h, angular rows wrapped to (-pi, pi]; written into the measurement's work space.
  const Eigen::VectorXd& innovation();

 private:
  Eigen::VectorXd y_;
};

/// The one measurement update (header comment): (x, P) updated in place when accepted.
UpdateResult correct(Eigen::VectorXd& x, Eigen::MatrixXd& P, Measurement& m, double gate);

/// Books an update attempt of sensor `s` at t_s in `res`: used/rejected counts, the NIS
/// statistics of the accepted updates (mean, share inside chi2(dof)'s two-sided 95 % interval),
/// the rejected list, and (keep_record) the per-update NIS record.
void bookUpdate(EstimationResult& res, Sensor s, double t_s, const UpdateResult& r, double gate,
                bool keep_record);

/// Two-sided 95 % interval of one chi2(dof) value (cached per dof).
std::pair<double, double> chi2Band95(int dof);

}  // namespace wheelchair::estimation
