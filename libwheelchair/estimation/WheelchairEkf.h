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
// Sensor-error states (EkfOptions::sensorErrorStates(); docs/estimation.md), appended as
// components 9-11 when on:
//   k_s, k_d     common scale and scale difference of the encoders, k_s = (k_R + k_L) / 2,
//                k_d = k_R - k_L, with k_R, k_L the per-wheel scales (reported / true rim
//                distance, -): the encoders report the rim speeds u_R = k_R (v + omega l_w / 2),
//                u_L = k_L (v - omega l_w / 2), so with a = the true mean (v, omega) over the
//                interval (accumulators / dt):
//                  z_v     = k_s a_v + k_d l_w a_omega / 4
//                  z_omega = k_s a_omega + k_d a_v / l_w
//   b_g          additive gyro z bias (rad/s): z_gyro = omega + b_g
// each a random walk (kdot = w, E[w w'] = q delta) with prior N(mean, sigma^2) from [estimator].
// A group that is not estimated has prior sigma 0 and q 0: it stays at its configured mean
// (a fixed calibration). Observability (no other absolute speed reference): the gyro gives
// omega, so z_omega - omega reveals k_R - k_L as soon as the chair moves (straight driving
// gives the RATIO k_R / k_L); the common scale (k_R + k_L) / 2 needs both rim speeds in
// different proportions, i.e. turning: z_omega = k_s a_omega against the gyro. The common
// scale never learns from z_v (whose regressor v is known only through the motor model (6),
// ~9 % off) nor from the gyro or sonar; until a turn its uncertainty is carried into the pose
// by a consider update (gains computed with k_s known, Joseph covariance with the true
// Jacobian), and a turn corrects the pose along its sensitivity to k_s. Fault prior
// (encoder_fault_prior): once the ratio is known, one wheel is taken as healthy (either side
// by default: the turn decides which). Fault detection and isolation
// (open_sensor_errors_on_alarm, default): a group starts closed and opens on its sensor's CUSUM
// alarm (HealthMonitor.h): encoder scales on the encoders' yaw-rate row, gyro bias at
// standstill. Closed, it is a Schmidt "consider" state: held at its prior mean, its gain rows
// zero in every update, but its variance (closed_encoder_scale_sigma: a healthy wheel's 0.5 %;
// closed_gyro_bias_sigma_rad_s, 0 by default) stays in P, so with K = [K_x; 0] the Joseph form
//   P_cc <- P_cc,  P_xc <- (I - K_x H_x) P_xc - K_x H_c P_cc,
//   P_xx <- (I - K_x H_x) P_xx (..)' - K_x H_c P_cx (..)' - ... + K_x (H_c P_cc H_c' + R) K_x'
// (the full Joseph product with H = [H_x, H_c]) carries what the unlearned error does to the
// pose; K_x is the Kalman gain's x rows from the full P (schmidtUpdate; the encoder, gyro and
// sonar updates keep their own gain models, with the closed rows zeroed). Between updates the
// closed states are constant and do not enter f: P_xc = Phi P_xc (CdEkf::setHeldTail, consider
// tail). 0 sigma: held exactly (the filter without the group).
// At standstill nothing is observable except b_g (omega = 0 is known from the
// encoders): the scale states keep their prior (tests/estimation/test_sensor_error_states.cpp). A
// gyro SCALE is not a state: with the encoders the only yaw-rate reference, it trades off exactly
// with the common encoder scale (it needs an absolute heading or position reference such as Pozyx).
//
// Example:
//   InputSignal u;  u.setSamples(rec.motors);
//   WheelchairEkf ekf(cfg, opt, &u);
//   ekf.start(t0);  ekf.predictTo(t1);  ekf.gyro(t1, 0.01);
#pragma once

#include "libwheelchair/estimation/CdEkf.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/estimation/HealthMonitor.h"
#include "libwheelchair/estimation/Measurement.h"
#include "libwheelchair/model/FilterModel.h"

#include <cmath>
#include <memory>

namespace wheelchair::estimation {

constexpr int kPhysicsStateDim = 9;
constexpr int kIdxSv = 7;
constexpr int kIdxSomega = 8;
constexpr int kNumSensorErrorStates = 3;
constexpr int kIdxEncScaleS = 9;   ///< k_s = (k_R + k_L) / 2 (-)
constexpr int kIdxEncScaleD = 10;  ///< k_d = k_R - k_L (-)
constexpr int kIdxGyroBias = 11;   ///< b_g (rad/s)

/// Encoder mean speeds z = (z_v, z_omega) reported for true mean speeds a = (a_v, a_omega)
/// with scales k_s, k_d and track width l_w (header comment), and the Jacobians d z / d a and
/// d z / d (k_s, k_d). Example: a = (0.5, 0), k_s = 0.975, k_d = 0.05 -> z = (0.4875, 0.0455).
Eigen::Vector2d scaledEncoderSpeeds(const Eigen::Vector2d& a, double k_s, double k_d,
                                    double track_width_m, Eigen::Matrix2d* dz_da = nullptr,
                                    Eigen::Matrix2d* dz_dk = nullptr);

/// Yaw process noise that follows the manoeuvre (EkfOptions::yaw_noise_from_manoeuvre,
/// docs/estimation.md "Yaw noise that follows the manoeuvre"). The model (6) leaves out yaw
/// accelerations that act only while the motors pull and the chair moves: the centre of mass a
/// distance d ahead of the axle (m_b d v omega / I_z), and the two drive sides' differences
/// (torque constant, gearbox efficiency, friction, castor swivel torques at turn starts): (6)
/// writes omegadot as the right side's minus the left side's yaw acceleration,
///   omegadot = [a2 i_R + (a4 / l_w) u_R] - [a2 i_L + (a4 / l_w) u_L],  u_R,L = v +- omega l_w / 2,
/// and each side's torque and friction known to a fraction epsilon leave an error up to
/// epsilon (|a2| (|i_R| + |i_L|) + |a4 / l_w| (|u_R| + |u_L|)), whatever the turn. A sustained
/// yaw-acceleration error a, with the gyro's white noise r = sigma_g^2 / rate (rad^2/s), is
/// covered by the white density q = a^(4/3) r^(1/3) (its lag a / sqrt(q / r) equals the omega
/// sd (q r)^(1/4)); here a follows the state and the measured currents:
///   a(t) = a_0 + kappa |v omega| + epsilon (|a2| (|i_R| + |i_L|) + |a4 / l_w| (|u_R| + |u_L|))
///   q_omega(t) = a(t)^(4/3) r^(1/3)
/// with kappa = m_b d / I_z (1/m) and a_0 the floor (standing: only a_0 remains).
struct ManoeuvreYawNoise {
  bool on = false;
  double floor_rad_s2 = 0;       ///< a_0 (rad/s^2)
  double kappa_1_m = 0;          ///< m_b d / I_z (1/m)
  double side_fraction = 0;      ///< epsilon (-)
  double a2_rad_s2_A = 0;        ///< |a2| of (6) (rad/s^2 per A)
  double a4_per_track_1_ms = 0;  ///< |a4| / l_w (1/(m s))
  double half_track_m = 0;       ///< l_w / 2 (m)
  double cbrt_r = 0;             ///< r^(1/3), r = gyro variance / rate (rad^2/s)
  /// q_omega (rad^2/s^3) at speed v (m/s), turn rate omega (rad/s), currents i_R, i_L (A).
  double qOmega(double v, double omega, double i_R, double i_L) const {
    const double w = omega * half_track_m;
    const double sides = a2_rad_s2_A * (std::fabs(i_R) + std::fabs(i_L)) +
                         a4_per_track_1_ms * (std::fabs(v + w) + std::fabs(v - w));
    const double a = floor_rad_s2 + kappa_1_m * std::fabs(v * omega) + side_fraction * sides;
    return a * std::cbrt(a) * cbrt_r;
  }
};

/// The augmented process model of WheelchairEkf: f, F = df/dx and
/// Q = diag(q) + G Sigma_u G' (Sigma_u = current-noise density I_2) on the first 7 states;
/// the accumulators have no process noise of their own (they integrate v and omega exactly).
/// With `error_q` (3 random-walk densities of k_R, k_L, b_g) the state has the 3 sensor-error
/// components, with f = 0, F = 0 and Q = diag(error_q) on them.
/// With `yaw.on`, Q(omega, omega) = (the constant part, q_diag(1) + the current noise's) +
/// yaw.qOmega(v, omega, i_R, i_L) at every right-hand side (varyingQ); the rest stays constant.
class WheelchairProcessModel : public CdModel {
 public:
  WheelchairProcessModel(const model::FilterModel& fm, const Eigen::Matrix<double, 7, 1>& q_diag,
                         double current_density_A2_s, const Eigen::VectorXd& error_q = {},
                         const ManoeuvreYawNoise& yaw = {});
  int stateDim() const override { return n_; }
  void f(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::VectorXd& xdot) const override;
  void F(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::MatrixXd& F) const override;
  void fAndF(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::VectorXd& xdot,
             Eigen::MatrixXd& F) const override;
  void Q(const Eigen::VectorXd& x, const Eigen::VectorXd& u, Eigen::MatrixXd& Q) const override;
  bool constantQ() const override { return true; }
  int varyingQIndex() const override { return yaw_.on ? model::kIdxOmega : -1; }
  double varyingQ(const Eigen::VectorXd& x, const Eigen::VectorXd& u) const override;
  const model::FilterModel& filterModel() const { return fm_; }

 private:
  model::FilterModel fm_;
  int n_ = kPhysicsStateDim;
  Eigen::MatrixXd Q_;  ///< constant Q (with yaw_.on: Q(omega, omega) without yaw_.qOmega)
  ManoeuvreYawNoise yaw_;
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

  /// The full filter (9 states, 12 with the sensor-error states; covariance, CVODE counters).
  const CdEkf& filter() const { return ekf_; }
  SensorErrorEstimate sensorErrors() const;
  /// Model-health events so far (estimate_encoder_scales on; HealthMonitor.h).
  const std::vector<HealthEvent>& healthEvents() const { return health_.events(); }
  const model::FilterModel& filterModel() const { return pm_.filterModel(); }

  const Eigen::VectorXd& state() const override { return ekf_.x(); }
  Measurement& gyroModel(const Eigen::VectorXd& x, double z, double R) override;
  Measurement& sonarModel(const Eigen::VectorXd& x, double z, double R) override;
  Measurement& pozyxModel(const Eigen::VectorXd& x, const Eigen::Vector2d& z_start,
                          const Eigen::Matrix2d& R) override;

 protected:
  /// CdEkf::correct, then the angles wrapped.
  UpdateResult correct(Measurement& m, double gate) override;
  bool obstacleInitialised() const override { return obstacle_initialised_; }
  void initObstacleFromSonar(double range_m) override;
  void inflatePositionCovariance(double var_m2) override;

 private:
  model::FilterState head() const;
  void wrap();
  /// Restarts the accumulators (s = 0, no covariance) and, with encoder_quantisation_carry,
  /// the quantisation chain: s = -e with e the unknown error of the count at t_s, variance
  /// tickVarianceM2() mapped to (s_v, s_omega), uncorrelated with the rest.
  void resetAccumulators(double t_s);
  /// encoder_quantisation_carry applies: it is set and encoder_model is Mean.
  bool quantisationCarried() const;
  /// Per-wheel variance of a count's quantisation error as a rim distance (m^2): tick^2 / 12;
  /// 0 with encoder_quantisation off.
  double tickVarianceM2() const;
  /// R of the encoder interval of dt_s s (telescoping quantisation and adaptive slip; .cpp).
  Eigen::Matrix2d encoderIntervalNoise(double dt_s) const;
  /// After an encoder update: carries the quantisation error into the next interval
  /// (encoder_quantisation_carry, an applied update of a moving interval; see the .cpp) or
  /// restarts the accumulators.
  void nextEncoderInterval(const Eigen::Vector2d& z, double dt_s, double t_s, bool carry);
  /// The adaptive slip variance (encoder_noise_adapt_window_s) from an applied update of a
  /// moving interval with innovation covariance S and measurement noise R.
  void adaptSlipVariance(const UpdateResult& r, const Eigen::Matrix2d& R, double dt_s);
  /// Adds the prior variance to the encoder scale states (a step of unknown size; their
  /// cross-covariances are kept): the fault hypothesis after a health-monitor alarm.
  void reopenEncoderScales();
  /// The encoder fault prior (EkfOptions::encoder_fault_prior): once the wheels disagree and
  /// before a turn, one pseudo-measurement of the common scale (one wheel is healthy).
  void encoderFaultPrior();
  /// The direction of an encoder fault from the motor currents (encoder_fault_prior = either):
  /// after the symmetric fault prior and before a turn, decides "the wheel reading less is
  /// faulty (short)" against "the wheel reading more is faulty (long)" by comparing the
  /// encoders' mean speed under each with the speed the motor model (6) predicts from ONE
  /// side's current (either gearbox may be the healthy one); applies the chosen side's prior
  /// once the evidence separates them (see the .cpp).
  void encoderFaultDirection(const sensors::WheelSpeedInterval& iv);
  /// The random walks of the open sensor-error groups since their last update
  /// (open_sensor_errors_on_alarm: the process model has none for them).
  void addErrorNoise();
  /// Keeps in the scale columns of the encoder Jacobian H only the entries the update may
  /// learn from and adds the others' variance to R (see the .cpp: excitation, motor model).
  /// Returns which entries learn (rows z_v, z_omega; columns k_s, k_d; 1 learns, 0 not).
  Eigen::Matrix2d learnableScaleColumns(const Eigen::Matrix<double, 2, Eigen::Dynamic>& da,
                                        const Eigen::Vector2d& a, Eigen::MatrixXd& H,
                                        Eigen::Matrix2d& R) const;
  /// The encoder update with the sensor-error states: gain from the gain model (Hg, Rg) with
  /// the scale rows restricted to `learn`, covariance by the Joseph form with the true H, R
  /// (a consider update: honest for the gain used). NIS and gate from S = H P H' + R.
  UpdateResult scaleConsiderUpdate(const Eigen::Vector2d& y, const Eigen::MatrixXd& H,
                                   const Eigen::Matrix2d& R, const Eigen::MatrixXd& Hg,
                                   const Eigen::Matrix2d& Rg, const Eigen::Matrix2d& learn,
                                   double gate);
  /// A scalar update (gyro, sonar) that does not learn the common encoder scale k_s (gain from the
  /// covariance conditional on k_s; Joseph covariance with the true H).
  UpdateResult scaleKnownUpdate(double y, const Eigen::MatrixXd& H, double R, double gate);
  /// A closed group (open_sensor_errors_on_alarm, its CUSUM has not alarmed) is a consider
  /// (Schmidt) state: kept in P with closed_*_sigma, never learned.
  bool scalesClosed() const;
  /// Some closed group carries a non-zero variance (then every update zeroes its gain rows).
  bool closedVariance() const;
  /// Zeroes the gain rows of the closed groups (K: n x m).
  void zeroClosedGainRows(Eigen::Ref<Eigen::MatrixXd> K) const;
  /// The generic update (Pozyx; the sonar once it teaches k_s) with the closed groups as
  /// consider states: Kalman gain of the others from the full P, zero rows for the closed
  /// ones, Joseph covariance (docs/estimation.md, "Closed states as consider states").
  UpdateResult schmidtUpdate(Measurement& m, double gate);
  /// x += dx and P = P_new (the consider updates' last step).
  void applyGain(const Eigen::Ref<const Eigen::VectorXd>& dx,
                 const Eigen::Ref<const Eigen::MatrixXd>& P_new);
  /// The gyro's health monitor after its update: CUSUM of the reading against omega = 0 while
  /// the encoders show standstill; an alarm re-opens the bias state (HealthMonitor.h).
  void gyroHealth(double z_rad_s, double R);
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
  // Preallocated measurement storage (sized once: no allocation per update).
  Eigen::Matrix<double, 2, Eigen::Dynamic> da_;  // d (mean encoder speeds) / dx
  Measurement enc_m_, gyro_m_, sonar_m_, pozyx_m_;
  Eigen::MatrixXd Hg_;  // the encoder update's gain model (2 x n, sized once)
  Eigen::MatrixXd Pw_;  // scratch covariance (sized once)
  WheelchairProcessModel pm_;
  CdEkf ekf_;
  HealthMonitor health_;
  bool obstacle_initialised_ = false;
  bool fault_prior_applied_ = false;
  // encoderFaultDirection: speeds of the model chair driven by the right / left current on both
  // sides (m/s) up to model_t_s_; evidence since the symmetric prior: per (encoder hypothesis
  // short/long) x (healthy gearbox right/left) the exponential mean of the speed residual
  // (m/s), that of the encoder speed (m/s), the count of straight intervals, how many
  // consecutive tests the best hypothesis (dir_best_) has held.
  double model_v_[2] = {0, 0}, model_t_s_ = 0;
  double dir_res_[2][2] = {{0, 0}, {0, 0}}, dir_v_sum_ = 0;
  int dir_n_ = 0, dir_hold_ = 0, dir_best_ = 0;
  bool dir_decided_ = false;
  // Fault detection and isolation (open_sensor_errors_on_alarm): a group is closed (zero
  // variance, no walk) until its sensor's CUSUM alarms; the walk is added from then on.
  bool encoder_scales_open_ = false, gyro_bias_open_ = false;
  /// Learned before the group opens (learn_healthy_encoder_scales): k_d, k_s (gain rows on,
  /// walks added); the alarm, the fault prior and the sonar's scale teaching still wait.
  bool scale_difference_open_ = false, common_scale_learned_ = false;
  double encoder_noise_t_s_ = 0, gyro_noise_t_s_ = 0;  ///< walk added up to these times (s)
  bool encoders_standstill_ = false;  ///< the last encoder interval had no tick on either wheel
  double standstill_since_s_ = 0;     ///< start of the current run of tick-free intervals (s)
  double acc_start_s_ = -1e300;
  /// Per-wheel rim-speed variance beyond the quantisation (m^2/s^2): encoder_extra_noise_m_s^2,
  /// or its adaptive estimate (encoder_noise_adapt_window_s > 0).
  double slip_var_m2_s2_ = 0;
  bool acc_valid_ = false;
};

/// Canonical estimate from a state whose first 7 components follow model::FilterModel
/// (obstacle converted to Cartesian with the Jacobian of the change of variables).
EstimateSample canonicalFromFilterState(double t_s, const Eigen::VectorXd& x,
                                        const Eigen::MatrixXd& P, model::ObstacleForm form,
                                        bool obstacle_initialised);

}  // namespace wheelchair::estimation
