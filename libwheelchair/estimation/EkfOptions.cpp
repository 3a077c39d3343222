#include "libwheelchair/estimation/EkfOptions.h"

#include "libwheelchair/config/WheelchairConfig.h"

#include <cmath>
#include <cstdlib>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

namespace wheelchair::estimation {

namespace {

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return {};
  const auto b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

double parseDouble(const std::string& t, const std::string& where) {
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (end == t.c_str() || *end != '\0' || !std::isfinite(v))
    throw std::runtime_error(where + ": expected a number, got '" + t + "'");
  return v;
}

std::string fmtDouble(double v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

// Enum <-> text tables.
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
const Names<CvodeOptions::Method> kMethod{{CvodeOptions::Method::Adams, "adams"},
                                          {CvodeOptions::Method::Bdf, "bdf"}};

template <typename E>
const char* nameOf(const Names<E>& t, E e) {
  for (const auto& [k, n] : t)
    if (k == e) return n;
  return "?";
}

// One key of the section: reader and writer.
struct Key {
  const char* name;
  std::function<void(const std::string& text, const std::string& where)> read;
  std::function<std::string()> write;
};

template <typename E>
Key enumKey(const char* name, E& v, const Names<E>& t) {
  return {name,
          [&v, &t](const std::string& s, const std::string& where) {
            for (const auto& [k, n] : t)
              if (s == n) {
                v = k;
                return;
              }
            std::string all;
            for (const auto& kn : t) all += std::string(all.empty() ? "" : " | ") + kn.second;
            throw std::runtime_error(where + ": expected " + all + ", got '" + s + "'");
          },
          [&v, &t] { return std::string(nameOf(t, v)); }};
}

Key dblKey(const char* name, double& v) {
  return {name, [&v](const std::string& s, const std::string& w) { v = parseDouble(s, w); },
          [&v] { return fmtDouble(v); }};
}

Key boolKey(const char* name, bool& v) {
  return {name,
          [&v](const std::string& s, const std::string& w) {
            if (s == "true" || s == "on" || s == "yes")
              v = true;
            else if (s == "false" || s == "off" || s == "no")
              v = false;
            else
              v = parseDouble(s, w) != 0;
          },
          [&v] { return std::string(v ? "1" : "0"); }};
}

template <typename I>
Key intKey(const char* name, I& v) {
  return {name,
          [&v](const std::string& s, const std::string& w) {
            const double x = parseDouble(s, w);
            if (x != std::floor(x)) throw std::runtime_error(w + ": expected an integer");
            v = static_cast<I>(x);
          },
          [&v] { return std::to_string(v); }};
}

std::vector<Key> keys(EkfOptions& o) {
  return {
      enumKey("filter", o.filter, kFilter),
      enumKey("obstacle_form", o.obstacle_form, kForm),
      enumKey("encoder_model", o.encoder_model, kEnc),
      enumKey("input_interpolation", o.input_interpolation, kInterp),
      boolKey("use_encoders", o.use_encoders),
      boolKey("use_gyro", o.use_gyro),
      boolKey("use_sonar", o.use_sonar),
      boolKey("use_pozyx", o.use_pozyx),
      dblKey("output_rate_hz", o.output_rate_hz),
      dblKey("gate_probability", o.gate_probability),
      intKey("sonar_reinit_after_rejections", o.sonar_reinit_after_rejections),
      enumKey("cvode_method", o.cvode.method, kMethod),
      dblKey("cvode_rel_tol", o.cvode.rel_tol),
      dblKey("cvode_abs_tol_state", o.cvode.abs_tol_state),
      dblKey("cvode_abs_tol_cov", o.cvode.abs_tol_cov),
      dblKey("cvode_nonlin_conv_coef", o.cvode.nonlin_conv_coef),
      boolKey("cvode_adaptive_initial_step", o.cvode.adaptive_initial_step),
      intKey("cvode_max_num_steps", o.cvode.max_num_steps),
      dblKey("cvode_max_step_s", o.cvode.max_step_s),
      intKey("cvode_max_order", o.cvode.max_order),
      boolKey("cvode_restart_at_input_samples", o.cvode.restart_at_input_samples),
      dblKey("q_v_m2_s3", o.q_v_m2_s3),
      dblKey("q_omega_rad2_s3", o.q_omega_rad2_s3),
      dblKey("q_xy_m2_s", o.q_xy_m2_s),
      dblKey("q_phi_rad2_s", o.q_phi_rad2_s),
      dblKey("q_obstacle_m2_s", o.q_obstacle_m2_s),
      dblKey("q_obstacle_bearing_rad2_s", o.q_obstacle_bearing_rad2_s),
      dblKey("current_noise_density_A2_s", o.current_noise_density_A2_s),
      boolKey("encoder_quantisation", o.encoder_quantisation),
      dblKey("encoder_extra_noise_m_s", o.encoder_extra_noise_m_s),
      dblKey("max_encoder_interval_s", o.max_encoder_interval_s),
      dblKey("gyro_noise_rad_s", o.gyro_noise_rad_s),
      dblKey("sonar_noise_m", o.sonar_noise_m),
      dblKey("pozyx_noise_m", o.pozyx_noise_m),
      dblKey("pozyx_anchor_x_m", o.pozyx_anchor_x_m),
      dblKey("pozyx_anchor_y_m", o.pozyx_anchor_y_m),
      dblKey("pozyx_anchor_yaw_deg", o.pozyx_anchor_yaw_deg),
      dblKey("initial_sigma_v_m_s", o.initial_sigma_v_m_s),
      dblKey("initial_sigma_omega_rad_s", o.initial_sigma_omega_rad_s),
      dblKey("initial_sigma_xy_m", o.initial_sigma_xy_m),
      dblKey("initial_sigma_phi_rad", o.initial_sigma_phi_rad),
      enumKey("initial_obstacle", o.initial_obstacle, kInit),
      dblKey("initial_obstacle_x_m", o.initial_obstacle_x_m),
      dblKey("initial_obstacle_y_m", o.initial_obstacle_y_m),
      dblKey("initial_obstacle_range_sigma_m", o.initial_obstacle_range_sigma_m),
      dblKey("initial_obstacle_bearing_sigma_deg", o.initial_obstacle_bearing_sigma_deg),
      dblKey("baseline_q_v_m2_s3", o.baseline_q_v_m2_s3),
      dblKey("baseline_q_omega_rad2_s3", o.baseline_q_omega_rad2_s3),
      dblKey("baseline_q_xy_m2_s", o.baseline_q_xy_m2_s),
      dblKey("baseline_q_phi_rad2_s", o.baseline_q_phi_rad2_s),
      dblKey("baseline_q_obstacle_m2_s", o.baseline_q_obstacle_m2_s),
  };
}

}  // namespace

void EkfOptions::loadFromConfig(const mrpt::config::CConfigFileBase& ini,
                                const std::string& section) {
  for (const Key& k : keys(*this)) {
    const std::string t = trim(ini.read_string(section, k.name, "", false));
    if (t.empty()) continue;
    k.read(t, "[" + section + "] " + k.name);
  }
  try {
    validate();
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("[" + section + "]: " + e.what());
  }
}

void EkfOptions::saveToConfig(mrpt::config::CConfigFileBase& ini,
                              const std::string& section) const {
  EkfOptions copy = *this;  // keys() binds to a mutable object
  for (const Key& k : keys(copy)) ini.write(section, k.name, k.write());
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
  if (sonar_reinit_after_rejections < 0)
    throw std::invalid_argument("sonar_reinit_after_rejections must be >= 0");
  pos(cvode.rel_tol, "cvode_rel_tol");
  pos(cvode.abs_tol_state, "cvode_abs_tol_state");
  pos(cvode.abs_tol_cov, "cvode_abs_tol_cov");
  pos(cvode.nonlin_conv_coef, "cvode_nonlin_conv_coef");
  if (cvode.max_num_steps <= 0) throw std::invalid_argument("cvode_max_num_steps must be > 0");
  nonneg(cvode.max_step_s, "cvode_max_step_s");
  if (cvode.max_order < 0) throw std::invalid_argument("cvode_max_order must be >= 0");
  for (auto [v, k] : {std::pair{q_v_m2_s3, "q_v_m2_s3"},
                      {q_omega_rad2_s3, "q_omega_rad2_s3"},
                      {q_xy_m2_s, "q_xy_m2_s"},
                      {q_phi_rad2_s, "q_phi_rad2_s"},
                      {q_obstacle_m2_s, "q_obstacle_m2_s"},
                      {q_obstacle_bearing_rad2_s, "q_obstacle_bearing_rad2_s"},
                      {encoder_extra_noise_m_s, "encoder_extra_noise_m_s"},
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
                      {initial_obstacle_range_sigma_m, "initial_obstacle_range_sigma_m"}})
    pos(v, k);
}

}  // namespace wheelchair::estimation
