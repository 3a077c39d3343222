// The paper's internal model as a continuous-discrete EKF (section IV, docs/estimation.md).
//
// State (9): [v, omega, x, y, phi, o1, o2, s_v, s_omega]
//   v, omega     velocities, dynamics (6) driven by the MEASURED motor currents u(t)
//   x, y, phi    pose in the start frame, (1)
//   o1, o2       one static obstacle in the base frame, (7) Cartesian or (8) polar
//   s_v, s_omega accumulators s_v = int v dt, s_omega = int omega dt since the last encoder
//                sample: the exact model of a differenced encoder count, which measures the
//                MEAN speed over its interval: z = (s_v, s_omega) / dt. They are reset to 0 (and
//                their covariance rows/columns zeroed) after each encoder sample.
// The first seven components and all maths on them come from model::FilterModel.
//
// Example:
//   InputSignal u;  u.setSamples(rec.motors);
//   WheelchairEkf ekf(cfg, opt, &u);
//   ekf.start(t0);  ekf.predictTo(t1);  ekf.gyro(t1, 0.01);
#pragma once

#include "libwheelchair/estimation/CdEkf.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/model/FilterModel.h"

#include <memory>

namespace wheelchair::estimation {

constexpr int kPhysicsStateDim = 9;
constexpr int kIdxSv = 7;
constexpr int kIdxSomega = 8;

/// The augmented process model of WheelchairEkf: f, F = df/dx and
/// Q = diag(q) + G Sigma_u G' (Sigma_u = current-noise density I_2) on the first 7 states;
/// the accumulators have no process noise of their own (they integrate v and omega exactly).
class WheelchairProcessModel : public CdModel {
 public:
  WheelchairProcessModel(const model::FilterModel& fm, const Eigen::Matrix<double, 7, 1>& q_diag,
                         double current_density_A2_s);
  int stateDim() const override { return kPhysicsStateDim; }
  void f(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::VectorXd& xdot) const override;
  void F(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::MatrixXd& F) const override;
  void fAndF(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::VectorXd& xdot,
             Eigen::MatrixXd& F) const override;
  void Q(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::MatrixXd& Q) const override;
  bool constantQ() const override { return true; }
  const model::FilterModel& filterModel() const { return fm_; }

 private:
  model::FilterModel fm_;
  Eigen::Matrix<double, kPhysicsStateDim, kPhysicsStateDim> Q_;
};

class WheelchairEkf : public Estimator {
 public:
  /// `input` (motor currents) must outlive the filter; nullptr means u = 0.
  WheelchairEkf(const config::WheelchairConfig& cfg, const EkfOptions& opt,
                const InputSignal* input);

  void start(double t0_s) override;
  void predictTo(double t_s) override;
  double time() const override { return ekf_.time(); }
  EstimateSample estimate() const override;
  void encoderStart(double t_s) override;
  void encoderInterval(const sensors::WheelSpeedInterval& iv) override;

  /// The full 9-dimensional filter (state, covariance, CVODE counters).
  const CdEkf& filter() const { return ekf_; }
  const model::FilterModel& filterModel() const { return pm_.filterModel(); }

 protected:
  UpdateResult gyroUpdate(double z, double R, double gate) override;
  UpdateResult sonarUpdate(double z, double R, double gate) override;
  UpdateResult pozyxUpdate(const Eigen::Vector2d& z_start, const Eigen::Matrix2d& R,
                           double gate) override;
  bool obstacleInitialised() const override { return obstacle_initialised_; }
  void initObstacleFromSonar(double range_m) override;

 private:
  model::FilterState head() const;
  void wrap();
  void resetAccumulators(double t_s);
  /// Sets the obstacle components to a body-frame Cartesian point with covariance, in the
  /// configured form; cross-covariances with the rest of the state are zeroed.
  void setObstacle(const Eigen::Vector2d& p_m, const Eigen::Matrix2d& cov_m2);

  /// u(t) from the InputSignal for CdEkf: the signal itself (linear interpolation, continuous)
  /// or a value held over the interval (zero-order hold).
  struct SignalInput final : CdInput {
    const InputSignal* signal = nullptr;
    bool hold = false;
    Eigen::Vector2d held = Eigen::Vector2d::Zero();
    void eval(double t_s, Eigen::VectorXd& u) const override {
      if (hold)
        u = held;
      else
        u = signal->at(t_s);
    }
  };

  const InputSignal* input_;
  InputSignal zero_input_;
  SignalInput u_in_;
  Eigen::VectorXd xs_;  // scratch state
  WheelchairProcessModel pm_;
  CdEkf ekf_;
  bool obstacle_initialised_ = false;
  double acc_start_s_ = -1e300;
  bool acc_valid_ = false;
};

/// Canonical estimate from a state whose first 7 components follow model::FilterModel
/// (obstacle converted to Cartesian with the Jacobian of the change of variables).
EstimateSample canonicalFromFilterState(double t_s, const Eigen::VectorXd& x,
                                        const Eigen::MatrixXd& P, model::ObstacleForm form,
                                        bool obstacle_initialised);

}  // namespace wheelchair::estimation
