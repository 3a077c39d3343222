// Options of the estimators: the [estimator] section of the configuration
// (config/wheelchair.ini documents every key with its unit; docs/estimation.md explains them).
//
// Sensor noise keys set to a negative value mean "take the datasheet value from the shared
// sensor sections" ([imu] gyro_noise_rad_s, [sonar] noise_m, [pozyx] noise_m,
// [motors] current_noise_A / rate_hz); resolveSensorDefaults() does that.
//
// Example:
//   auto cfg = config::WheelchairConfig::load("config/wheelchair.ini");
//   EkfOptions opt;
//   opt.loadFromConfig(cfg.ini());          // section "estimator"; missing keys keep defaults
//   opt.resolveSensorDefaults(cfg);
//   auto res = runEstimator(rec, cfg, opt);
#pragma once

#include "libwheelchair/config/Options.h"
#include "libwheelchair/estimation/CdEkf.h"

#include <mrpt/config/CConfigFileBase.h>

#include <string>

namespace wheelchair::config {
class WheelchairConfig;
}

namespace wheelchair::estimation {

enum class FilterKind { Physics, Baseline };
enum class EncoderMeasurementModel {
  Mean,    ///< exact: z = (integral of (v, omega) over the interval) / dt, by accumulators
  Instant  ///< naive: the interval mean taken as (v, omega) at the interval's end
};
enum class InputInterpolation { Linear, Hold };
enum class ObstacleInit { FirstSonar, Config };
enum class ObstacleFormOption { Cartesian, Polar };
/// What the encoder scales assume about a fault before a turn reveals the common scale
/// (docs/estimation.md, "Sensor-error states").
enum class EncoderFaultPrior {
  Either,  ///< one wheel is faulty, either one, reading short or long: k_s = 1 +- |k_d| / 2
  Short,   ///< a faulty encoder loses counts: the wheel reading more is healthy (scale 1)
  None     ///< the common scale keeps its prior until a turn
};

/// Which encoder scales a HEALTHY chair's filter learns before an alarm opens the group
/// (open_sensor_errors_on_alarm; docs/estimation.md, "Learning a healthy chair's radii").
enum class HealthyScaleLearning {
  None,        ///< both closed: consider states until the alarm
  Difference,  ///< k_d = k_R - k_L learned (gyro vs encoders while moving), k_s closed
  Both         ///< k_d, and k_s from the encoders' yaw rate against the gyro while turning
};

struct EkfOptions {
  // --- what runs --------------------------------------------------------------------------
  FilterKind filter = FilterKind::Physics;  ///< filter = physics | baseline
  ObstacleFormOption obstacle_form = ObstacleFormOption::Cartesian;  ///< (7) | (8)
  EncoderMeasurementModel encoder_model = EncoderMeasurementModel::Mean;
  InputInterpolation input_interpolation = InputInterpolation::Linear;
  bool use_encoders = true, use_gyro = true, use_sonar = true, use_pozyx = false;
  double output_rate_hz = 0;  ///< 0: one output per processed measurement time

  // --- gating -----------------------------------------------------------------------------
  double gate_probability = 0.999;  ///< chi2 probability of the NIS gate in [0, 1]; 0 or 1: no gate
  /// After this many consecutive gated sonar readings the obstacle is re-initialised from the
  /// reading (a different obstacle took over the echo); 0: never.
  int sonar_reinit_after_rejections = 5;
  /// Pozyx outliers (multipath, a blocked anchor) fail the gate and are counted as rejected.
  /// After this many CONSECUTIVE gated Pozyx readings it is the filter, not the tag, that has
  /// drifted while its covariance says otherwise: the position variances are inflated until
  /// the reading fits the gate, and it is applied (counted as `inflated`). Only once a reading
  /// has passed the gate: a Pozyx rejected from its first reading on is in a wrong anchor
  /// frame. A burst of outliers longer than this would be taken for the truth. 0: never.
  int pozyx_inflate_after_rejections = 20;

  // --- integrator -------------------------------------------------------------------------
  CvodeOptions cvode;

  // --- process noise (continuous-time spectral densities) ---------------------------------
  double q_v_m2_s3 = 0.01;        ///< on vdot (model error of (6))
  double q_omega_rad2_s3 = 0.02;  ///< on omegadot (docs/estimation.md "Error budget")
  /// Yaw noise that follows the manoeuvre (WheelchairEkf.h ManoeuvreYawNoise): q_omega(t) =
  /// a(t)^(4/3) (gyro variance / rate)^(1/3) with the yaw-acceleration error of (6) a(t) =
  /// yaw_noise_floor_rad_s2 + m_b yaw_noise_com_ahead_m / I_z |v omega| +
  /// yaw_noise_side_fraction (|a2| (|i_R| + |i_L|) + |a4 / l_w| (|u_R| + |u_L|)), instead of the
  /// constant q_omega_rad2_s3 (physics filter only).
  bool yaw_noise_from_manoeuvre = false;
  double yaw_noise_floor_rad_s2 = 0.05;  ///< a_0: yaw-acceleration error standing (rad/s^2)
  double yaw_noise_com_ahead_m = 0.07;   ///< d: centre of mass (chair + user) ahead of the axle
  /// epsilon: each drive side's torque and friction in (6) known to this fraction (-)
  double yaw_noise_side_fraction = 0.3;
  double q_xy_m2_s = 1e-8;                  ///< on xdot, ydot (lateral tyre creep only)
  double q_phi_rad2_s = 0;                  ///< on phidot (0: phi integrates omega exactly)
  double q_obstacle_m2_s = 1e-5;            ///< on the obstacle (px, py) or d
  double q_obstacle_bearing_rad2_s = 1e-5;  ///< on beta (polar form)
  /// Density of the motor-current measurement noise mapped through G = df/du (A^2 s);
  /// negative: [motors] current_noise_A^2 / rate_hz.
  double current_noise_density_A2_s = -1;

  // --- measurement noise ------------------------------------------------------------------
  bool encoder_quantisation = true;        ///< add the tick quantisation variance
  double encoder_extra_noise_m_s = 0.005;  ///< per-wheel rim speed noise, 1 sigma (m/s)
  double max_encoder_interval_s = 0.5;     ///< longer encoder gaps give no speed measurement
  double gyro_noise_rad_s = -1;            ///< 1 sigma; negative: [imu] gyro_noise_rad_s
  double sonar_noise_m = -1;               ///< 1 sigma; negative: [sonar] noise_m
  double pozyx_noise_m = -1;               ///< 1 sigma per axis; negative: [pozyx] noise_m
  /// Pozyx anchor frame: p_anchor = R(yaw) p_start + (x, y) (m, m, deg).
  double pozyx_anchor_x_m = 0, pozyx_anchor_y_m = 0, pozyx_anchor_yaw_deg = 0;
  /// Telescoping quantisation (physics filter, encoder_model = mean; docs/estimation.md
  /// "Coloured encoder errors"): a count's quantisation error e_k (uniform, tick^2 / 12 per
  /// wheel) enters interval k with + and interval k+1 with -. true: the accumulators restart
  /// after an update at minus the estimate of e_k, alpha (s - dt z) with alpha = its share of
  /// the interval's noise (1 without slip), covariance kept, instead of 0, and R has
  /// tick^2 / 12 / dt^2 per wheel (each error once); false: white, tick^2 / 6 / dt^2.
  bool encoder_quantisation_carry = true;
  /// Adaptive slip variance (physics filter): the per-wheel rim-speed variance beyond the
  /// quantisation is estimated from the encoder innovations while moving (Mehra: mean of
  /// y y' - H P H' - R_quantisation, exponential window of this many seconds of driving),
  /// bounded to [0, encoder_extra_noise_m_s^2] and starting at the upper bound; 0: fixed
  /// encoder_extra_noise_m_s.
  double encoder_noise_adapt_window_s = 0.0;

  // --- sensor-error states (physics filter; docs/estimation.md "Sensor-error states") -------
  /// Estimate the per-wheel encoder scales k_R, k_L (reported / true distance) as random walks.
  bool estimate_encoder_scales = false;
  double encoder_scale_right = 1.0, encoder_scale_left = 1.0;  ///< prior means (-)
  double encoder_scale_sigma = 0.05;                           ///< prior 1 sigma of each scale (-)
  double q_encoder_scale_1_s = 1e-7;  ///< random-walk density of each scale (1/s)
  /// Fault prior of the encoder scales once the wheels' ratio is known and before a turn:
  /// Either (default): one wheel is healthy, scale 1 +- healthy_encoder_scale_sigma, and the
  /// data (the next turn) decide which, so k_s = 1 +- sqrt((k_d / 2)^2 + sigma^2) (the moment-
  /// matched pair of the two sides); Short: the wheel reading more is the healthy one (an
  /// assumption: wrong for an encoder reading long); None: no pseudo-measurement.
  EncoderFaultPrior encoder_fault_prior = EncoderFaultPrior::Either;
  double healthy_encoder_scale_sigma = 0.005;  ///< 1 sigma of a healthy encoder's scale (-)
  /// Estimate an additive gyro z bias b_g (z = omega + b_g) as a random walk.
  bool estimate_gyro_bias = false;
  double gyro_bias_rad_s = 0.0;         ///< prior mean (rad/s)
  double gyro_bias_sigma_rad_s = 0.01;  ///< prior 1 sigma (rad/s)
  double q_gyro_bias_rad2_s3 = 1e-8;    ///< random-walk density (rad^2/s^3)
  /// Fault detection and isolation: an estimated group (encoder scales, gyro bias) starts
  /// CLOSED, held at its prior mean without random walk and not learned (a consider state with
  /// closed_*_sigma below; 0: zero variance, the filter without it), and OPENS (prior variance
  /// added, random walk on) when the health monitor's CUSUM alarms for its sensor. false: open
  /// from the start.
  bool open_sensor_errors_on_alarm = true;
  /// While a group is closed it is a Schmidt "consider" state: not learned (zero gain rows),
  /// but carried in P with this variance, so that the pose covariance includes what a healthy
  /// sensor's error does to it (docs/estimation.md, "Closed states as consider states"). Per
  /// wheel: a healthy encoder's scale 1 sigma (-), as healthy_encoder_scale_sigma; the gyro
  /// bias 1 sigma (rad/s) while closed. 0: held with zero variance (the filter without it).
  double closed_encoder_scale_sigma = 0.005;
  double closed_gyro_bias_sigma_rad_s = 0.0;
  /// With open_sensor_errors_on_alarm: the scales a healthy chair's filter LEARNS before the
  /// alarm (their gain rows on, random walk q_encoder_scale_1_s per wheel on, prior variance
  /// that of the closed scales, closed_encoder_scale_sigma per wheel), while the alarm, the
  /// fault prior and the sonar's scale teaching still wait for the alarm. The gyro observes
  /// k_d whenever the chair moves (z_omega - omega = k_d a_v / l_w) and k_s while it turns
  /// (k_s a_omega); each only through an excited regressor (learnableScaleColumns), so a
  /// drive that cannot excite a scale leaves it at its prior. None: both consider states.
  HealthyScaleLearning learn_healthy_encoder_scales = HealthyScaleLearning::None;
  /// Whether the physics filter carries the three sensor-error states: an estimate flag is on
  /// or a prior mean is not nominal (then a fixed, configured calibration).
  bool sensorErrorStates() const {
    return estimate_encoder_scales || estimate_gyro_bias || encoder_scale_right != 1.0 ||
           encoder_scale_left != 1.0 || gyro_bias_rad_s != 0.0;
  }

  // --- initialisation ---------------------------------------------------------------------
  double initial_sigma_v_m_s = 0.02;
  double initial_sigma_omega_rad_s = 0.02;
  /// The pose at t0 IS the start frame's origin (estimates are in the start frame), so its
  /// error there is zero by definition: 1e-6 m / 1e-6 rad keep P invertible and add nothing
  /// the truth does not have (1e-3 before 2026-11-24: 1 mm / 1 mrad, i.e. 10 mm across a 10 m
  /// leg, kept the position NEES ~20 % low; docs/estimation.md, "What keeps the NEES low").
  double initial_sigma_xy_m = 1e-6;
  double initial_sigma_phi_rad = 1e-6;
  ObstacleInit initial_obstacle = ObstacleInit::FirstSonar;
  double initial_obstacle_x_m = 2.0, initial_obstacle_y_m = 0.0;  ///< body frame at start (m)
  double initial_obstacle_range_sigma_m = 0.5;                    ///< Config mode (m)
  /// Bearing 1 sigma at initialisation (deg); negative: cone half-angle / sqrt(3) (uniform).
  double initial_obstacle_bearing_sigma_deg = -1;

  // --- baseline (discrete constant-velocity EKF) ------------------------------------------
  double baseline_q_v_m2_s3 = 0.5;        ///< random-walk density of v
  double baseline_q_omega_rad2_s3 = 0.5;  ///< random-walk density of omega
  double baseline_q_xy_m2_s = 1e-4;
  double baseline_q_phi_rad2_s = 1e-5;
  double baseline_q_obstacle_m2_s = 1e-5;

  /// The key table of the section (config/Options.h): name, range, help of every key,
  /// bound to this object. config/wheelchair.ini [estimator] documents the same keys.
  config::Options options(const std::string& section = "estimator");
  /// The baseline filter's keys of options() (its densities).
  void addBaselineKeys(config::Options& o);
  /// Reads the keys present in `section` (missing keys keep their values). Throws
  /// std::runtime_error naming file, line and key on a malformed or out-of-range value.
  void loadFromConfig(const mrpt::config::CConfigFileBase& ini,
                      const std::string& section = "estimator");
  /// Writes every key to `section`.
  void saveToConfig(mrpt::config::CConfigFileBase& ini,
                    const std::string& section = "estimator") const;
  /// Replaces the negative "from the sensor sections" values by the datasheet ones.
  void resolveSensorDefaults(const config::WheelchairConfig& cfg);
  /// Throws std::invalid_argument on inconsistent values.
  void validate() const;
};

}  // namespace wheelchair::estimation
