#include "libwheelchair/estimation/EkfOptions.h"

#include "libwheelchair/config/Options.h"
#include "libwheelchair/config/WheelchairConfig.h"

#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

namespace wheelchair::estimation {

namespace {

template <typename E>
using Names = std::vector<std::pair<E, const char*>>;

const Names<FilterKind> kFilter{{FilterKind::Physics, "physics"},
                                {FilterKind::Baseline, "baseline"}};
const Names<ObstacleFormOption> kForm{{ObstacleFormOption::Cartesian, "cartesian"},
                                      {ObstacleFormOption::Polar, "polar"}};
const Names<EncoderMeasurementModel> kEnc{{EncoderMeasurementModel::Mean, "mean"},
                                          {EncoderMeasurementModel::Instant, "instant"}};
const Names<InputInterpolation> kInterp{{InputInterpolation::Linear, "linear"},
                                        {InputInterpolation::Hold, "hold"}};
const Names<ObstacleInit> kInit{{ObstacleInit::FirstSonar, "first_sonar"},
                                {ObstacleInit::Config, "config"}};
const Names<EncoderFaultPrior> kFaultPrior{{EncoderFaultPrior::Either, "either"},
                                           {EncoderFaultPrior::Short, "short"},
                                           {EncoderFaultPrior::None, "none"}};
const Names<HealthyScaleLearning> kHealthyLearn{{HealthyScaleLearning::None, "none"},
                                                {HealthyScaleLearning::Difference, "difference"},
                                                {HealthyScaleLearning::Both, "both"}};
const Names<CvodeOptions::Method> kMethod{{CvodeOptions::Method::Adams, "adams"},
                                          {CvodeOptions::Method::Bdf, "bdf"}};

[[maybe_unused]] const bool kRegistered = config::registerOptionsOf<EkfOptions>("estimator");

}  // namespace

config::Options EkfOptions::options(const std::string& section) {
  using config::Range;
  const Range pos = Range::above(0), nonneg = Range::atLeast(0), any = Range::any();
  const char* sensor = "1 sigma; < 0: the sensor section's datasheet value";
  auto& c = cvode;
  config::Options o(section, "state estimation (docs/estimation.md)");
  o.choice("filter", filter, kFilter, "physics EKF or constant-velocity baseline")
      .choice("obstacle_form", obstacle_form, kForm, "obstacle state, eq. (7) or (8)")
      .choice("encoder_model", encoder_model, kEnc, "encoder measurement model")
      .choice("input_interpolation", input_interpolation, kInterp, "motor currents between samples")
      .flag("use_encoders", use_encoders, "use the encoders")
      .flag("use_gyro", use_gyro, "use the gyro")
      .flag("use_sonar", use_sonar, "use the sonar")
      .flag("use_pozyx", use_pozyx, "use the Pozyx (needs the anchor frame)")
      .real("output_rate_hz", output_rate_hz, "output rate (Hz); 0: per measurement", nonneg)
      .real("gate_probability", gate_probability,
            "NIS gate chi-square probability (-); 0 or 1: no gate", Range::between(0, 1))
      .integer("sonar_reinit_after_rejections", sonar_reinit_after_rejections,
               "re-initialise the obstacle after this many gated readings (count; 0 = never)",
               nonneg)
      .integer("pozyx_inflate_after_rejections", pozyx_inflate_after_rejections,
               "after this many consecutive gated Pozyx readings, inflate the position "
               "covariance until the reading fits the gate (count; 0 = never)",
               nonneg)
      .choice("cvode_method", c.method, kMethod, "CVODE method")
      .real("cvode_rel_tol", c.rel_tol, "CVODE relative tolerance (-)", pos)
      .real("cvode_abs_tol_state", c.abs_tol_state, "CVODE absolute tolerance, state", pos)
      .real("cvode_abs_tol_cov", c.abs_tol_cov, "CVODE absolute tolerance, covariance", pos)
      .real("cvode_nonlin_conv_coef", c.nonlin_conv_coef, "CVODE corrector safety factor (-)", pos)
      .flag("cvode_adaptive_initial_step", c.adaptive_initial_step,
            "initial step from the previous restart")
      .integer("cvode_max_num_steps", c.max_num_steps, "CVODE max steps per interval", pos)
      .real("cvode_max_step_s", c.max_step_s, "CVODE max step (s; 0 = none)", nonneg)
      .integer("cvode_max_order", c.max_order, "CVODE max order (0 = default)", nonneg)
      .flag("cvode_restart_at_input_samples", c.restart_at_input_samples,
            "restart CVODE at every motor-current sample")
      .real("q_v_m2_s3", q_v_m2_s3, "process noise density on vdot (m^2/s^3)", nonneg)
      .real("q_omega_rad2_s3", q_omega_rad2_s3, "on omegadot (rad^2/s^3)", nonneg)
      .flag("yaw_noise_from_manoeuvre", yaw_noise_from_manoeuvre, "yaw noise from the manoeuvre")
      .real("yaw_noise_floor_rad_s2", yaw_noise_floor_rad_s2, "a_0, standing (rad/s^2)", nonneg)
      .real("yaw_noise_com_ahead_m", yaw_noise_com_ahead_m, "centre of mass ahead of axle (m)", any)
      .real("yaw_noise_side_fraction", yaw_noise_side_fraction, "drive sides' error (-)", nonneg)
      .real("q_xy_m2_s", q_xy_m2_s, "on xdot, ydot (m^2/s)", nonneg)
      .real("q_phi_rad2_s", q_phi_rad2_s, "on phidot (rad^2/s)", nonneg)
      .real("q_obstacle_m2_s", q_obstacle_m2_s, "on the obstacle px, py or d (m^2/s)", nonneg)
      .real("q_obstacle_bearing_rad2_s", q_obstacle_bearing_rad2_s, "on beta (rad^2/s)", nonneg)
      .real("current_noise_density_A2_s", current_noise_density_A2_s,
            "motor-current noise density (A^2 s); < 0: [motors] current_noise_A^2 / rate_hz", any)
      .flag("encoder_quantisation", encoder_quantisation, "add the tick-quantisation variance")
      .real("encoder_extra_noise_m_s", encoder_extra_noise_m_s,
            "extra rim-speed noise, 1 sigma (m/s)", nonneg)
      .flag("encoder_quantisation_carry", encoder_quantisation_carry,
            "carry a count's quantisation error into the next interval (telescoping)")
      .real("encoder_noise_adapt_window_s", encoder_noise_adapt_window_s,
            "window of the adaptive slip variance, bounded by encoder_extra_noise_m_s "
            "(s of driving; 0 = fixed)",
            nonneg)
      .real("max_encoder_interval_s", max_encoder_interval_s,
            "longer encoder intervals give no measurement (s)", pos)
      .real("gyro_noise_rad_s", gyro_noise_rad_s, sensor, any)
      .real("sonar_noise_m", sonar_noise_m, sensor, any)
      .real("pozyx_noise_m", pozyx_noise_m, sensor, any)
      .real("pozyx_anchor_x_m", pozyx_anchor_x_m, "anchor frame x (m)")
      .real("pozyx_anchor_y_m", pozyx_anchor_y_m, "anchor frame y (m)")
      .real("pozyx_anchor_yaw_deg", pozyx_anchor_yaw_deg, "anchor frame yaw (deg)")
      .flag("estimate_encoder_scales", estimate_encoder_scales,
            "estimate the per-wheel encoder scales (states k_R, k_L)")
      .real("encoder_scale_right", encoder_scale_right,
            "right encoder scale prior mean (reported / true distance, -)", pos)
      .real("encoder_scale_left", encoder_scale_left,
            "left encoder scale prior mean (reported / true distance, -)", pos)
      .real("encoder_scale_sigma", encoder_scale_sigma, "encoder scale prior 1 sigma (-)", pos)
      .real("q_encoder_scale_1_s", q_encoder_scale_1_s,
            "random-walk density of each encoder scale (1/s)", nonneg)
      .choice("encoder_fault_prior", encoder_fault_prior, kFaultPrior,
              "before a turn: one wheel healthy, either side | the one reading more | none")
      .real("healthy_encoder_scale_sigma", healthy_encoder_scale_sigma,
            "1 sigma of a healthy encoder's scale (-)", pos)
      .flag("estimate_gyro_bias", estimate_gyro_bias, "estimate the gyro z bias (state b_g)")
      .real("gyro_bias_rad_s", gyro_bias_rad_s, "gyro bias prior mean (rad/s)")
      .real("gyro_bias_sigma_rad_s", gyro_bias_sigma_rad_s, "gyro bias prior 1 sigma (rad/s)", pos)
      .real("q_gyro_bias_rad2_s3", q_gyro_bias_rad2_s3,
            "random-walk density of the gyro bias (rad^2/s^3)", nonneg)
      .flag("open_sensor_errors_on_alarm", open_sensor_errors_on_alarm,
            "sensor-error states start closed and open on their sensor's CUSUM alarm")
      .real("closed_encoder_scale_sigma", closed_encoder_scale_sigma,
            "1 sigma of each encoder scale while closed, a consider state (-; 0: held exactly)",
            nonneg)
      .real("closed_gyro_bias_sigma_rad_s", closed_gyro_bias_sigma_rad_s,
            "1 sigma of the gyro bias while closed, a consider state (rad/s; 0: held exactly)",
            nonneg)
      .choice("learn_healthy_encoder_scales", learn_healthy_encoder_scales, kHealthyLearn,
              "scales learned before the alarm: none | difference (k_d) | both (k_d, k_s)")
      .real("initial_sigma_v_m_s", initial_sigma_v_m_s, "initial 1 sigma of v (m/s)", pos)
      .real("initial_sigma_omega_rad_s", initial_sigma_omega_rad_s,
            "initial 1 sigma of omega (rad/s)", pos)
      .real("initial_sigma_xy_m", initial_sigma_xy_m, "initial 1 sigma of x, y (m)", pos)
      .real("initial_sigma_phi_rad", initial_sigma_phi_rad, "initial 1 sigma of phi (rad)", pos)
      .choice("initial_obstacle", initial_obstacle, kInit, "initial obstacle")
      .real("initial_obstacle_x_m", initial_obstacle_x_m, "config mode: body-frame x (m)")
      .real("initial_obstacle_y_m", initial_obstacle_y_m, "config mode: body-frame y (m)")
      .real("initial_obstacle_range_sigma_m", initial_obstacle_range_sigma_m,
            "initial range 1 sigma (m)", pos)
      .real("initial_obstacle_bearing_sigma_deg", initial_obstacle_bearing_sigma_deg,
            "initial bearing 1 sigma (deg); < 0: cone half-angle / sqrt(3)", any);
  addBaselineKeys(o);
  return o;
}

void EkfOptions::addBaselineKeys(config::Options& o) {
  const config::Range nonneg = config::Range::atLeast(0);
  o.real("baseline_q_v_m2_s3", baseline_q_v_m2_s3, "baseline: density of v (m^2/s^3)", nonneg)
      .real("baseline_q_omega_rad2_s3", baseline_q_omega_rad2_s3,
            "baseline: density of omega (rad^2/s^3)", nonneg)
      .real("baseline_q_xy_m2_s", baseline_q_xy_m2_s, "baseline: on x, y (m^2/s)", nonneg)
      .real("baseline_q_phi_rad2_s", baseline_q_phi_rad2_s, "baseline: on phi (rad^2/s)", nonneg)
      .real("baseline_q_obstacle_m2_s", baseline_q_obstacle_m2_s,
            "baseline: on the obstacle (m^2/s)", nonneg);
}

void EkfOptions::loadFromConfig(const mrpt::config::CConfigFileBase& ini,
                                const std::string& section) {
  options(section).load(ini);
  try {
    validate();
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(config::keyLocation(ini, section, "") + ": " + e.what());
  }
}

void EkfOptions::saveToConfig(mrpt::config::CConfigFileBase& ini,
                              const std::string& section) const {
  EkfOptions copy = *this;  // the table binds to a mutable object
  copy.options(section).save(ini);
}

void EkfOptions::resolveSensorDefaults(const config::WheelchairConfig& cfg) {
  if (gyro_noise_rad_s < 0) gyro_noise_rad_s = cfg.imu.gyro_noise_rad_s;
  if (sonar_noise_m < 0) sonar_noise_m = cfg.sonar.noise_m;
  if (pozyx_noise_m < 0) pozyx_noise_m = cfg.pozyx.noise_m;
  if (current_noise_density_A2_s < 0)
    current_noise_density_A2_s = cfg.motors.current_noise_A * cfg.motors.current_noise_A /
                                 std::max(cfg.motors.rate_hz, 1e-9);
  if (initial_obstacle_bearing_sigma_deg < 0)
    initial_obstacle_bearing_sigma_deg = cfg.sonar.cone_half_angle_deg / std::sqrt(3.0);
}

void EkfOptions::validate() const {
  auto nonneg = [](double v, const char* k) {
    if (!(v >= 0)) throw std::invalid_argument(std::string(k) + " must be >= 0");
  };
  auto pos = [](double v, const char* k) {
    if (!(v > 0)) throw std::invalid_argument(std::string(k) + " must be > 0");
  };
  nonneg(output_rate_hz, "output_rate_hz");
  nonneg(gate_probability, "gate_probability");
  nonneg(encoder_noise_adapt_window_s, "encoder_noise_adapt_window_s");
  if (sonar_reinit_after_rejections < 0)
    throw std::invalid_argument("sonar_reinit_after_rejections must be >= 0");
  if (pozyx_inflate_after_rejections < 0)
    throw std::invalid_argument("pozyx_inflate_after_rejections must be >= 0");
  pos(cvode.rel_tol, "cvode_rel_tol");
  pos(cvode.abs_tol_state, "cvode_abs_tol_state");
  pos(cvode.abs_tol_cov, "cvode_abs_tol_cov");
  pos(cvode.nonlin_conv_coef, "cvode_nonlin_conv_coef");
  if (cvode.max_num_steps <= 0) throw std::invalid_argument("cvode_max_num_steps must be > 0");
  nonneg(cvode.max_step_s, "cvode_max_step_s");
  if (cvode.max_order < 0) throw std::invalid_argument("cvode_max_order must be >= 0");
  for (auto [v, k] : {std::pair{q_v_m2_s3, "q_v_m2_s3"},
                      {q_omega_rad2_s3, "q_omega_rad2_s3"},
                      {yaw_noise_floor_rad_s2, "yaw_noise_floor_rad_s2"},
                      {yaw_noise_side_fraction, "yaw_noise_side_fraction"},
                      {q_xy_m2_s, "q_xy_m2_s"},
                      {q_phi_rad2_s, "q_phi_rad2_s"},
                      {q_obstacle_m2_s, "q_obstacle_m2_s"},
                      {q_obstacle_bearing_rad2_s, "q_obstacle_bearing_rad2_s"},
                      {encoder_extra_noise_m_s, "encoder_extra_noise_m_s"},
                      {q_encoder_scale_1_s, "q_encoder_scale_1_s"},
                      {q_gyro_bias_rad2_s3, "q_gyro_bias_rad2_s3"},
                      {baseline_q_v_m2_s3, "baseline_q_v_m2_s3"},
                      {baseline_q_omega_rad2_s3, "baseline_q_omega_rad2_s3"},
                      {baseline_q_xy_m2_s, "baseline_q_xy_m2_s"},
                      {baseline_q_phi_rad2_s, "baseline_q_phi_rad2_s"},
                      {baseline_q_obstacle_m2_s, "baseline_q_obstacle_m2_s"}})
    nonneg(v, k);
  pos(max_encoder_interval_s, "max_encoder_interval_s");
  for (auto [v, k] : {std::pair{initial_sigma_v_m_s, "initial_sigma_v_m_s"},
                      {initial_sigma_omega_rad_s, "initial_sigma_omega_rad_s"},
                      {initial_sigma_xy_m, "initial_sigma_xy_m"},
                      {initial_sigma_phi_rad, "initial_sigma_phi_rad"},
                      {initial_obstacle_range_sigma_m, "initial_obstacle_range_sigma_m"},
                      {encoder_scale_right, "encoder_scale_right"},
                      {encoder_scale_left, "encoder_scale_left"},
                      {encoder_scale_sigma, "encoder_scale_sigma"},
                      {healthy_encoder_scale_sigma, "healthy_encoder_scale_sigma"},
                      {gyro_bias_sigma_rad_s, "gyro_bias_sigma_rad_s"}})
    pos(v, k);
}

}  // namespace wheelchair::estimation
