#include "libwheelchair/simulation/Simulator.h"

#include "libwheelchair/util/AtomicFile.h"
#include "libwheelchair/util/Text.h"

#include "libwheelchair/model/DriveDynamics.h"
#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/sensors/Encoders.h"
#include "libwheelchair/sensors/VoltageCircuit.h"
#include "libwheelchair/simulation/MujocoEngine.h"
#include "libwheelchair/simulation/Random.h"
#include "libwheelchair/simulation/UnknownEffects.h"
#include "libwheelchair/util/AtomicFile.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>

namespace wheelchair::simulation {

namespace {

constexpr double kDeg = M_PI / 180.0;

/// The streams in effects::streamNames() order (sensor_delay's index).
enum Stream { kEncoders, kImu, kMotors, kSonar, kPozyx, kJoystick, kNumStreams };

/// Sampling instants of one stream: nominal grid with a per-seed phase plus uniform jitter.
class StreamClock {
 public:
  StreamClock(double rate_hz, double jitter_s, uint64_t seed, const std::string& name)
      : rng_(seed, name + ".time") {
    if (!(rate_hz > 0)) {
      next_ = std::numeric_limits<double>::infinity();
      return;
    }
    period_ = 1.0 / rate_hz;
    jitter_ = std::clamp(jitter_s, 0.0, 0.4 * period_);
    nominal_ = jitter_ + rng_.uniform(0, period_);
    draw();
  }
  double next() const { return next_; }
  /// Upper bound of the samples in a run of duration_s (to size the vectors once).
  std::size_t capacityFor(double duration_s) const {
    return period_ > 0 ? static_cast<std::size_t>(duration_s / period_) + 2 : 0;
  }
  void advance() {
    nominal_ += period_;
    draw();
  }

 private:
  void draw() { next_ = nominal_ + (jitter_ > 0 ? rng_.uniform(-jitter_, jitter_) : 0.0); }
  Rng rng_;
  double period_ = 0, jitter_ = 0, nominal_ = 0;
  double next_ = 0;
};

/// Mechanical state integrated by RK4.
struct Mech {
  double x = 0, y = 0, phi = 0, v = 0, om = 0, psiR = 0, psiL = 0;
  Mech operator+(const Mech& o) const {
    return {x + o.x, y + o.y, phi + o.phi, v + o.v, om + o.om, psiR + o.psiR, psiL + o.psiL};
  }
  Mech operator*(double a) const {
    return {x * a, y * a, phi * a, v * a, om * a, psiR * a, psiL * a};
  }
};

/// The motor currents an external forward force F (N) and yaw moment M (N m) are worth:
/// i_i = -(r / r_G) (F/2 + s_i M / l_w) / (eta_i k_i), s_R = +1, s_L = -1 (they save current).
Eigen::Vector2d externalCurrents(const Mech& s, const model::DriveTrain& dt,
                                 const ExternalLoad& ext) {
  const Eigen::Vector2d fm = ext.forceMoment(s.v, s.om, s.phi);
  const double r = dt.geom.wheel_radius_m, lw = dt.geom.track_width_m, rG = dt.geom.gear_ratio;
  Eigen::Vector2d i;
  for (int k = 0; k < 2; ++k) {
    const double alpha = 1.0 / (dt.side[k].gearbox_efficiency * dt.side[k].torque_constant_Nm_A);
    i(k) = -alpha * r / rG * (fm(0) / 2 + (k == 0 ? 1 : -1) * fm(1) / lw);
  }
  return i;
}

Mech derivative(const Mech& s, const model::DriveTrain& dt, const Eigen::Vector2d& I,
                const ExternalLoad& ext) {
  const Eigen::Vector2d acc = dt.acceleration(
      {s.v, s.om, s.phi}, ext.any() ? Eigen::Vector2d(I - externalCurrents(s, dt, ext)) : I);
  const double r = dt.geom.wheel_radius_m, lw = dt.geom.track_width_m;
  return {s.v * std::cos(s.phi),     s.v * std::sin(s.phi),    s.om, acc(0), acc(1),
          (s.v + lw * s.om / 2) / r, (s.v - lw * s.om / 2) / r};
}

Mech rk4(const Mech& s, const model::DriveTrain& dt, const Eigen::Vector2d& I, double h,
         const ExternalLoad& ext) {
  const Mech k1 = derivative(s, dt, I, ext);
  const Mech k2 = derivative(s + k1 * (h / 2), dt, I, ext);
  const Mech k3 = derivative(s + k2 * (h / 2), dt, I, ext);
  const Mech k4 = derivative(s + k3 * h, dt, I, ext);
  return s + (k1 + k2 * 2 + k3 * 2 + k4) * (h / 6);
}

/// The sensors' view of the truth at one instant (linear interpolation within a step).
struct Snap {
  double x, y, phi, v, om, psiR, psiL, vrcR, vrcL;
};

/// The truth a fraction a in [0, 1] of the way from (m0, vrc0) to (m1, vrc1), linearly.
Snap interpolate(const Mech& m0, const double vrc0[2], const Mech& m1, const double vrc1[2],
                 double a) {
  auto L = [a](double p, double q) { return p + a * (q - p); };
  return Snap{L(m0.x, m1.x),       L(m0.y, m1.y),       L(m0.phi, m1.phi),
              L(m0.v, m1.v),       L(m0.om, m1.om),     L(m0.psiR, m1.psiR),
              L(m0.psiL, m1.psiL), L(vrc0[0], vrc1[0]), L(vrc0[1], vrc1[1])};
}

}  // namespace

// ------------------------------------------------------------------------------------------
namespace {

[[maybe_unused]] const bool kRegistered =
    config::registerOptionsOf<SimulationOptions>("simulation");

// Obstacle list "x y x y ..." (m; commas or semicolons also separate), each of `radius_m`.
config::Options& obstacleKey(config::Options& t, const char* key, std::vector<Obstacle>& v,
                             const double& radius_m, const char* help) {
  return t.custom(
      key,
      [&v, &radius_m](const std::string& text) {
        std::string norm = text;
        for (char& c : norm)
          if (c == ',' || c == ';') c = ' ';
        std::istringstream ss(norm);
        std::vector<double> xs;
        for (std::string tok; ss >> tok;) xs.push_back(config::parseStrictNumber(tok, "obstacle"));
        if (xs.size() % 2) throw std::runtime_error("expected pairs 'x y x y ...' (m)");
        v.clear();
        for (std::size_t i = 0; i + 1 < xs.size(); i += 2)
          v.push_back({xs[i], xs[i + 1], radius_m});
      },
      [&v] {
        std::string out;
        for (const auto& o : v) out += fmt::format("{}{} {}", out.empty() ? "" : " ", o.x_m, o.y_m);
        return out;
      },
      help);
}

}  // namespace

config::Options SimulationOptions::options(const std::string& sec) {
  using config::Range;
  const Range P = Range::above(0), any = Range::any();
  auto& pw = power;
  auto& sv = supervisory;
  auto& sc = scenario;
  config::Options t(sec, "truth simulator (docs/simulation.md); effects are given per run");
  t.real("step_s", step_s, "RK4 step and power-module control period (s)", Range{0, 0.01, true})
      .real("truth_rate_hz", truth_rate_hz, "truth trajectory sample rate (Hz)", P)
      .real("start_time_s", start_time_s, "recording clock at the start (s)", any)
      .real("timestamp_jitter_s", timestamp_jitter_s, "sampling-instant jitter, uniform +- (s)",
            any)
      .real("max_accel_m_s2", pw.max_accel_m_s2, "power module: acceleration limit (m/s^2)", P)
      .real("max_decel_m_s2", pw.max_decel_m_s2, "power module: deceleration limit (m/s^2)", P)
      .real("max_angular_accel_rad_s2", pw.max_angular_accel_rad_s2,
            "power module: angular acceleration limit (rad/s^2)", P)
      .real("actuator_delay_s", pw.delay_s, "power module: pure delay (s)", any)
      .real("actuator_time_constant_s", pw.time_constant_s, "power module: lag (s)", any)
      .real("speed_kp_A_s_m", pw.speed_kp_A_s_m, "PI speed loop: A per m/s", any)
      .real("speed_ki_A_m", pw.speed_ki_A_m, "PI speed loop: A per m", any)
      .real("current_limit_A", pw.current_limit_A, "motor current limit (A)", P)
      .real("battery_voltage_V", pw.battery_voltage_V, "battery voltage (V)", P)
      .real("coulomb_smoothing_m_s", coulomb_smoothing_m_s, "sgn(u) ~ tanh(u / this) (m/s)", P)
      .flag("pozyx_anchor_random", pozyx_anchor_random, "random anchor frame per seed")
      .real("pozyx_anchor_max_offset_m", pozyx_anchor_max_offset_m,
            "random anchor frame: max translation (m)", any)
      .real("pozyx_anchor_x_m", pozyx_anchor_x_m, "fixed anchor frame x (m)", any)
      .real("pozyx_anchor_y_m", pozyx_anchor_y_m, "fixed anchor frame y (m)", any)
      .real("pozyx_anchor_yaw_deg", pozyx_anchor_yaw_deg, "fixed anchor frame yaw (deg)", any)
      .integer("encoder_initial_ticks_right", encoder_initial_ticks_right,
               "right counter at the start (counts)", any)
      .integer("encoder_initial_ticks_left", encoder_initial_ticks_left,
               "left counter at the start (counts)", any)
      .real("footprint_front_m", footprint.front_m, "footprint ahead of the axle (m)", P)
      .real("footprint_rear_m", footprint.rear_m, "footprint behind the axle (m)", P)
      .real("footprint_half_width_m", footprint.half_width_m, "footprint half width (m)", P)
      .flag("supervisory", sv.enabled, "assist-as-needed supervisory control")
      .real("supervisory_slow_distance_m", sv.slow_distance_m, "slow-down distance (m)", any)
      .real("supervisory_stop_distance_m", sv.stop_distance_m, "stop distance (m)", any)
      .real("supervisory_horizon_s", sv.horizon_s, "prediction horizon (s)", P)
      .real("supervisory_prediction_step_s", sv.prediction_step_s, "prediction step (s)", P)
      .real("supervisory_margin_m", sv.margin_m, "contact margin (m)", any)
      .real("supervisory_rate_hz", sv.rate_hz, "supervisory rate (Hz)", P)
      .flag("record_ground_truth", record_ground_truth, "store the true pose as GROUND_TRUTH")
      .real("start_pause_s", sc.start_pause_s, "pilot: standstill before moving (s)", any)
      .real("driver_max_speed_m_s", sc.max_speed_m_s, "pilot: cruise speed (m/s)", P)
      .real("driver_max_turn_rate_rad_s", sc.max_turn_rate_rad_s,
            "pilot: turn rate in place (rad/s)", P)
      .real("driver_decel_m_s2", sc.comfort_decel_m_s2, "pilot: braking (m/s^2)", P)
      .real("driver_angular_decel_rad_s2", sc.comfort_angular_decel_rad_s2,
            "pilot: angular braking (rad/s^2)", P)
      .real("driver_heading_gain_1_s", sc.heading_gain_1_s, "pilot: steering gain (1/s)", P)
      .real("three_task_length_m", sc.three_task_length_m, "three_task: leg length (m)", P)
      .real("square_side_m", sc.square_side_m, "square: side (m)", P)
      .real("excite_mean_speed_m_s", sc.excite_mean_speed_m_s, "excite: mean speed (m/s)", any)
      .real("obstacles_v_cmd_m_s", sc.field_v_m_s, "obstacles: fixed joystick v (m/s)", any)
      .real("obstacles_omega_cmd_rad_s", sc.field_omega_rad_s,
            "obstacles: fixed joystick omega (rad/s)", any)
      .real("obstacles_drive_s", sc.field_drive_s, "obstacles: drive time (s)", P)
      .real("obstacle_radius_m", sc.obstacle_radius_m, "post radius (m)", P);
  // After obstacle_radius_m: the lists take the radius read above.
  obstacleKey(t, "three_task_obstacles_xy_m", sc.three_task_obstacles, sc.obstacle_radius_m,
              "three_task: obstacles 'x y x y ...' in the start frame (m)");
  obstacleKey(t, "obstacle_field_xy_m", sc.field_obstacles, sc.obstacle_radius_m,
              "obstacles: posts 'x y x y ...' (m; empty = a 1 m lattice)");
  return t;
}

void SimulationOptions::loadFromConfig(const mrpt::config::CConfigFileBase& ini,
                                       const std::string& sec) {
  const config::Options t = options(sec);
  t.load(ini);
  // The default three_task obstacles take a configured radius too (given lists already do).
  for (auto& o : scenario.three_task_obstacles) o.radius_m = scenario.obstacle_radius_m;
  if (supervisory.stop_distance_m >= supervisory.slow_distance_m)
    throw std::runtime_error(config::keyLocation(ini, sec, "supervisory_stop_distance_m") +
                             ": must be < supervisory_slow_distance_m");
}

// ------------------------------------------------------------------------------------------
namespace {

/// The Pozyx anchor frame of a run: random per seed or the configured one.
AnchorFrame anchorFrame(const SimulationOptions& opt, uint64_t seed) {
  AnchorFrame anchor;
  if (opt.pozyx_anchor_random) {
    Rng a(seed, "pozyx.anchor");
    anchor.x_m = a.uniform(-opt.pozyx_anchor_max_offset_m, opt.pozyx_anchor_max_offset_m);
    anchor.y_m = a.uniform(-opt.pozyx_anchor_max_offset_m, opt.pozyx_anchor_max_offset_m);
    anchor.yaw_rad = a.uniform(-M_PI, M_PI);
  } else {
    anchor = {opt.pozyx_anchor_x_m, opt.pozyx_anchor_y_m, opt.pozyx_anchor_yaw_deg * kDeg};
  }
  return anchor;
}

/// The run's description in the result and the recording's META.
void describeRun(SimulationResult& res, const config::WheelchairConfig& cfg,
                 const std::string& scenario_name, uint64_t seed, double T,
                 const std::vector<effects::EffectSpec>& effects, const SimulationOptions& opt) {
  res.scenario = scenario_name;
  res.engine = opt.engine;
  res.seed = seed;
  res.duration_s = T;
  res.effects = effects;
  res.supervisory = opt.supervisory.enabled;
  res.config_text = cfg.text();
  std::string eff;
  for (const auto& e : effects) eff += (eff.empty() ? "" : " ") + effects::formatEffect(e);
  io::Recording& rec = res.recording;
  rec.meta["source"] = "wheelchair simulate (libwheelchair truth simulator)";
  rec.meta["scenario"] = scenario_name;
  rec.meta["engine"] = opt.engine;
  rec.meta["seed"] = std::to_string(seed);
  rec.meta["effects"] = eff.empty() ? "none" : eff;
  rec.meta["supervisory"] = opt.supervisory.enabled ? "on" : "off";
  std::ostringstream d;
  d << T;
  rec.meta["duration_s"] = d.str();
}

/// Voltage circuit (11) on the two wires of each motor: V_RC of wire 1 (U > 0) and wire 2
/// (U < 0). Its time constant (R_par C = 0.17 ms) is shorter than the step, so it is integrated
/// exponentially (exact for the linear part) around the steady state of the end-of-step lead
/// voltage, with the local rate constant of (11) there (the Zener conductance included).
class WireCircuit {
 public:
  WireCircuit(const sensors::VoltageCircuitParams& vc, double h) : vc_(vc), h_(h) {
    // (11) with no lead voltage: steady state and decay over one step.
    rc_ss0_ = sensors::steadyStateVrc(0.0, vc);
    rc_decay0_ = std::exp(
        h *
        (sensors::vrcRate(rc_ss0_ + 1e-4, 0.0, vc) - sensors::vrcRate(rc_ss0_ - 1e-4, 0.0, vc)) /
        2e-4);
    for (auto& m : wire_)
      for (double& w : m) w = sensors::steadyStateVrc(0.0, vc);
  }
  /// Differential V_RC of motor m (V).
  double vrc(int m) const { return wire_[m][0] - wire_[m][1]; }
  /// One step with motor m's lead voltage U_end (V) at the end of the step.
  void step(int m, double U_end) {
    const double Vw[2] = {std::max(U_end, 0.0), std::max(-U_end, 0.0)};
    for (int w = 0; w < 2; ++w) {
      double& x = wire_[m][w];
      if (Vw[w] == 0.0) {
        x = rc_ss0_ + (x - rc_ss0_) * rc_decay0_;
        continue;
      }
      const double xs = sensors::steadyStateVrc(Vw[w], vc_);
      const double lam =
          (sensors::vrcRate(xs + 1e-4, Vw[w], vc_) - sensors::vrcRate(xs - 1e-4, Vw[w], vc_)) /
          2e-4;
      x = xs + (x - xs) * std::exp(lam * h_);
    }
  }

 private:
  const sensors::VoltageCircuitParams& vc_;
  double h_, rc_ss0_ = 0, rc_decay0_ = 0;
  double wire_[2][2] = {{0, 0}, {0, 0}};
};

/// The sensors of a run: their clocks, noise and distortions (the effects' SensorDistortion).
class SensorSuite {
 public:
  SensorSuite(const config::WheelchairConfig& cfg, const SimulationOptions& opt, uint64_t seed,
              const effects::SensorDistortion& se, const AnchorFrame& anchor,
              const std::vector<Obstacle>& cone_obstacles, const MujocoChair* mj)
      : cfg_(cfg),
        opt_(opt),
        se_(se),
        anchor_(anchor),
        cone_obstacles_(cone_obstacles),
        mj_(mj),
        clocks_{{cfg.encoders.rate_hz, opt.timestamp_jitter_s, seed, "encoders"},
                {cfg.imu.rate_hz, opt.timestamp_jitter_s, seed, "imu"},
                {cfg.motors.rate_hz, opt.timestamp_jitter_s, seed, "motors"},
                {cfg.sonar.rate_hz, opt.timestamp_jitter_s, seed, "sonar"},
                {cfg.pozyx.rate_hz, opt.timestamp_jitter_s, seed, "pozyx"},
                {cfg.joystick.rate_hz, opt.timestamp_jitter_s, seed, "joystick"}},
        gyro_noise_(seed, "imu.noise"),
        cur_noise_(seed, "motors.current_noise"),
        vrc_noise_(seed, "motors.vrc_noise"),
        sonar_noise_(seed, "sonar.noise"),
        sonar_fail_(seed, "sonar.dropout"),
        pozyx_noise_(seed, "pozyx.noise"),
        pozyx_out_(seed, "pozyx.outliers") {}

  /// Sized once (no doubling slack, no copy on growth: a long drive's peak is its data).
  void reserve(io::Recording& rec, double T) const {
    rec.encoders.reserve(clocks_[kEncoders].capacityFor(T));
    rec.imu.reserve(clocks_[kImu].capacityFor(T));
    rec.motors.reserve(clocks_[kMotors].capacityFor(T));
    rec.sonar.reserve(clocks_[kSonar].capacityFor(T));
    rec.pozyx.reserve(clocks_[kPozyx].capacityFor(T));
    rec.joystick.reserve(clocks_[kJoystick].capacityFor(T));
  }

  /// Every stream's samples due up to t_end (stamped t0 + t + that stream's delay);
  /// snapAt(t) is the truth at t.
  /// Each sample goes to put(io::AnySample).
  template <class SnapAt, class Put>
  void sampleUntil(double t_end, double t0, const SnapAt& snapAt, const Eigen::Vector2d& I,
                   const JoystickDemand& joy, const Put& put) {
    for (int st = 0; st < kNumStreams; ++st) {
      StreamClock& clk = clocks_[st];
      while (clk.next() <= t_end) {
        const double tm = clk.next();
        clk.advance();
        const Snap q = snapAt(tm);
        const double stamp = t0 + tm + se_.delay_s[st];
        switch (st) {
          case kEncoders:
            put(encoders(stamp, tm, q));
            break;
          case kImu:
            put(imu(stamp, q));
            break;
          case kMotors:
            put(motors(stamp, q, I));
            break;
          case kSonar:
            put(io::SonarSample{stamp, sonar(q)});
            break;
          case kPozyx:
            put(pozyx(stamp, q));
            break;
          case kJoystick:
            put(io::JoystickSample{stamp, joy.v_m_s, joy.omega_rad_s});
            break;
        }
      }
    }
  }

 private:
  /// Encoder counts at run time tm (s) of the true wheel angles in q.
  io::EncoderSample encoders(double stamp, double tm, const Snap& q) {
    const sensors::EncoderParams& enc = cfg_.encoders.params;
    // The counter holds whole edges: floor of the continuous count of (9).
    const auto tr = static_cast<int64_t>(
        std::floor(sensors::wheelAngleToTicks(reportedAngle(0, tm, q.psiR), enc)));
    const auto tl = static_cast<int64_t>(
        std::floor(sensors::wheelAngleToTicks(reportedAngle(1, tm, q.psiL), enc)));
    return {stamp, sensors::toHardwareCounter(opt_.encoder_initial_ticks_right + tr),
            sensors::toHardwareCounter(opt_.encoder_initial_ticks_left + tl)};
  }
  /// The wheel angle side w's encoder reports for the true angle psi (rad) at run time tm (s):
  /// scale x psi, or with a step fault (encoder_from_s) psi before it and
  /// anchor + scale (psi - anchor) from the first sample at or after it.
  double reportedAngle(int w, double tm, double psi) {
    const double from_s = se_.encoder_from_s[w];
    if (from_s <= 0) return se_.encoder_scale[w] * psi;
    if (tm < from_s) return psi;
    if (!anchored_[w]) anchor_rad_[w] = psi, anchored_[w] = true;
    return anchor_rad_[w] + se_.encoder_scale[w] * (psi - anchor_rad_[w]);
  }
  io::ImuSample imu(double stamp, const Snap& q) {
    io::ImuSample is;
    is.t_s = stamp;
    is.gyro_z_rad_s = se_.gyro_scale * q.om + se_.gyro_bias_rad_s +
                      cfg_.imu.gyro_noise_rad_s * gyro_noise_.normal();
    return is;
  }
  io::MotorSample motors(double stamp, const Snap& q, const Eigen::Vector2d& I) {
    io::MotorSample ms;
    ms.t_s = stamp;
    ms.current_right_A =
        I(0) + se_.current_offset_A[0] + cfg_.motors.current_noise_A * cur_noise_.normal();
    ms.current_left_A =
        I(1) + se_.current_offset_A[1] + cfg_.motors.current_noise_A * cur_noise_.normal();
    ms.vrc_right_V = q.vrcR + cfg_.motors.vrc_noise_V * vrc_noise_.normal();
    ms.vrc_left_V = q.vrcL + cfg_.motors.vrc_noise_V * vrc_noise_.normal();
    return ms;
  }
  /// Range of the sonar (m; 0 = no echo or a dropout).
  double sonar(const Snap& q) {
    const auto& son = cfg_.sonar;
    // Sonar pose in the start frame.
    const double c = std::cos(q.phi), sn = std::sin(q.phi);
    const double sx = q.x + c * son.x_m - sn * son.y_m;
    const double sy = q.y + sn * son.x_m + c * son.y_m;
    const double syaw = q.phi + son.yaw_deg * kDeg;
    double best = std::numeric_limits<double>::infinity();
    if (mj_) best = mj_->sonarRange(sx, sy, syaw, son.cone_half_angle_deg * kDeg);
    for (const auto& o : cone_obstacles_) {
      const double dx = o.x_m - sx, dy = o.y_m - sy;
      const double d = std::hypot(dx, dy);
      if (d <= o.radius_m) {
        best = 0;
        continue;
      }
      const double bearing = std::abs(model::wrapAngle(std::atan2(dy, dx) - syaw));
      const double half = son.cone_half_angle_deg * kDeg + std::asin(o.radius_m / d);
      if (bearing <= half) best = std::min(best, d - o.radius_m);
    }
    const double n = son.noise_m * sonar_noise_.normal();  // drawn for every reading
    double range = 0;
    if (std::isfinite(best) && best >= son.min_range_m && best <= son.max_range_m)
      range = std::max(0.0, best + n);
    // Dropouts: two-state Markov chain with mean burst length L and long-run
    // failure fraction p (enter a burst with p / (L (1 - p))).
    const double u = sonar_fail_.uniform();
    if (se_.dropout_probability > 0) {
      const double L = std::max(1.0, se_.dropout_burst);
      const double p = se_.dropout_probability;
      in_burst_ = in_burst_ ? (u >= 1.0 / L) : (u < std::min(1.0, p / (L * (1 - p))));
      if (in_burst_) range = 0;
    }
    return range;
  }
  io::PozyxSample pozyx(double stamp, const Snap& q) {
    const auto& poz = cfg_.pozyx;
    const double c = std::cos(q.phi), sn = std::sin(q.phi);
    const double tx = q.x + c * poz.lever_x_m - sn * poz.lever_y_m;
    const double ty = q.y + sn * poz.lever_x_m + c * poz.lever_y_m;
    const double ca = std::cos(anchor_.yaw_rad), sa = std::sin(anchor_.yaw_rad);
    io::PozyxSample ps;
    ps.t_s = stamp;
    ps.x_m = anchor_.x_m + ca * tx - sa * ty + poz.noise_m * pozyx_noise_.normal();
    ps.y_m = anchor_.y_m + sa * tx + ca * ty + poz.noise_m * pozyx_noise_.normal();
    const double u = pozyx_out_.uniform(), dir = pozyx_out_.uniform(0, 2 * M_PI),
                 mag = pozyx_out_.uniform(0.5, 1.5);
    if (u < se_.outlier_rate) {
      ps.x_m += se_.outlier_magnitude_m * mag * std::cos(dir);
      ps.y_m += se_.outlier_magnitude_m * mag * std::sin(dir);
    }
    return ps;
  }

  const config::WheelchairConfig& cfg_;
  const SimulationOptions& opt_;
  const effects::SensorDistortion& se_;
  const AnchorFrame anchor_;
  const std::vector<Obstacle>& cone_obstacles_;
  const MujocoChair* mj_;
  StreamClock clocks_[kNumStreams];
  Rng gyro_noise_, cur_noise_, vrc_noise_, sonar_noise_, sonar_fail_, pozyx_noise_, pozyx_out_;
  double anchor_rad_[2] = {0, 0};  ///< true wheel angle at a step fault (encoder_from_s)
  bool anchored_[2] = {false, false};
  bool in_burst_ = false;
};

}  // namespace

namespace {

/// The true vehicle: the nominal configuration with the effects acting on it (effects/).
effects::TruthModel trueVehicle(const config::WheelchairConfig& cfg, const SimulationOptions& opt,
                                const std::vector<effects::EffectSpec>& effects) {
  effects::TruthModel truth;
  truth.drive = model::DriveTrain::symmetric(cfg.vehicle);
  truth.drive.coulomb_smoothing_m_s = opt.coulomb_smoothing_m_s;
  truth.actuator_delay_s = opt.power.delay_s;
  truth.actuator_time_constant_s = opt.power.time_constant_s;
  effects::actOnTruth(effects, truth);
  // Out-of-catalogue effects on the truth (UnknownEffects.h): the extra yaw inertia and the
  // current sensor's offset; their forces act in the mechanics (ExternalLoad).
  const ExternalLoad ext = externalLoad(effects);
  truth.drive.yaw_inertia_kg_m2 += ext.extra_yaw_inertia_kg_m2;
  for (int s = 0; s < 2; ++s) truth.sensors.current_offset_A[s] += ext.current_offset_A[s];
  return truth;
}

/// The truth sample stamped `stamp` (s): state s, wheel speeds (rad/s), currents I (A),
/// voltages U (V), the driver's demand, the power module's references, the supervisor's scale.
TruthSample truthAt(double stamp, const Mech& s, const Eigen::Vector2d& wheel_rad_s,
                    const Eigen::Vector2d& I, const double U[2], const JoystickDemand& joy,
                    const PowerModule& pm, double sup_scale) {
  TruthSample ts;
  ts.t_s = stamp;
  ts.x_m = s.x, ts.y_m = s.y, ts.phi_rad = s.phi, ts.v_m_s = s.v, ts.omega_rad_s = s.om;
  ts.wheel_speed_right_rad_s = wheel_rad_s(0);
  ts.wheel_speed_left_rad_s = wheel_rad_s(1);
  ts.wheel_angle_right_rad = s.psiR, ts.wheel_angle_left_rad = s.psiL;
  ts.current_right_A = I(0), ts.current_left_A = I(1);
  ts.voltage_right_V = U[0], ts.voltage_left_V = U[1];
  ts.v_demand_m_s = joy.v_m_s, ts.omega_demand_rad_s = joy.omega_rad_s;
  ts.v_ref_m_s = pm.vRef(), ts.omega_ref_rad_s = pm.omegaRef();
  ts.supervisory_scale = sup_scale;
  return ts;
}

/// The MuJoCo multibody when opt.engine is "mujoco" (it replaces the mechanics and the sonar
/// geometry only), else none.
std::unique_ptr<MujocoChair> mujocoFor(const config::WheelchairConfig& cfg,
                                       const SimulationOptions& opt,
                                       const std::vector<effects::EffectSpec>& effects,
                                       const std::vector<Obstacle>& obstacles) {
  if (opt.engine != "mujoco") return nullptr;
  MujocoOptions mo;
  mo.loadFromConfig(cfg.ini(), "mujoco");
  return std::make_unique<MujocoChair>(cfg, mo, effects, obstacles);
}

/// A truth sample to the sink (res keeps the last one only) or to res.truth.samples.
void keepTruth(const TruthSample& ts, const SimulationOptions& opt, SimulationResult& res) {
  if (opt.sink) {
    opt.sink->truth(ts);
    res.truth.samples.assign(1, ts);  // the last one only
  } else {
    res.truth.samples.push_back(ts);
  }
}

/// Collisions: an obstacle centre inside the footprint at pose s (each obstacle once: hit).
void markCollisions(const std::vector<Obstacle>& obstacles, const Footprint& footprint,
                    const Mech& s, std::vector<bool>& hit, std::vector<int>& collided) {
  for (std::size_t o = 0; o < obstacles.size(); ++o)
    if (!hit[o] && footprint.contains(s.x, s.y, s.phi, obstacles[o].x_m, obstacles[o].y_m))
      hit[o] = true, collided.push_back(static_cast<int>(o));
}

}  // namespace

SimulationResult simulate(const config::WheelchairConfig& cfg, const std::string& scenario_name,
                          uint64_t seed, double duration_s,
                          const std::vector<effects::EffectSpec>& effects,
                          const SimulationOptions& opt) {
  for (const auto& e : effects) validateEngineEffect(e, opt.engine);
  if (!(opt.step_s > 0 && opt.step_s <= 0.01))
    throw std::invalid_argument("simulation step_s must be in (0, 0.01] s");

  Scenario sc = makeScenario(scenario_name, seed, opt.scenario, duration_s);
  const double T = sc.duration_s;
  const double h = opt.step_s;

  const effects::TruthModel truth = trueVehicle(cfg, opt, effects);
  const model::DriveTrain& dt = truth.drive;
  const ExternalLoad ext = externalLoad(effects);  // model engine; MuJoCo applies its own
  PowerModuleParams pmp = opt.power;
  pmp.delay_s = truth.actuator_delay_s;
  pmp.time_constant_s = truth.actuator_time_constant_s;
  const double r = dt.geom.wheel_radius_m, lw = dt.geom.track_width_m, rG = dt.geom.gear_ratio;
  const double Rm = cfg.vehicle.armature_resistance_ohm;
  const double km[2] = {dt.side[0].torque_constant_Nm_A, dt.side[1].torque_constant_Nm_A};

  SimulationResult res;
  describeRun(res, cfg, scenario_name, seed, T, effects, opt);
  const AnchorFrame anchor = anchorFrame(opt, seed);
  res.truth.obstacles = sc.obstacles;
  res.truth.pozyx_anchor = anchor;
  io::Recording& rec = res.recording;
  const double t0 = opt.start_time_s;
  if (opt.sink) opt.sink->meta(rec.meta);

  // --- state ------------------------------------------------------------------------------
  Mech s;
  PowerModule pm(pmp, lw, h);
  const std::unique_ptr<MujocoChair> mj = mujocoFor(cfg, opt, effects, sc.obstacles);
  const std::vector<Obstacle> no_obstacles;  // the MuJoCo sonar casts rays instead
  SensorSuite sensors(cfg, opt, seed, truth.sensors, anchor, mj ? no_obstacles : sc.obstacles,
                      mj.get());
  WireCircuit wires(cfg.motors.circuit, h);
  std::vector<bool> hit(sc.obstacles.size(), false);
  double sup_scale = 1.0, next_sup = 0.0;
  const long n_steps = static_cast<long>(std::ceil(T / h - 1e-9));
  const long truth_stride = std::max(1L, std::lround(1.0 / (opt.truth_rate_hz * h)));
  // Sized once (no doubling slack, no copy on growth: a long drive's peak is its data), or
  // passed to SimulationOptions::sink as produced.
  if (!opt.sink) {
    res.truth.samples.reserve(static_cast<std::size_t>(n_steps / truth_stride) + 1);
    sensors.reserve(rec, T);
  }
  const auto put = [&](io::AnySample x) {
    if (opt.sink)
      opt.sink->sample(x);
    else
      io::append(rec, std::move(x));
  };
  // Rim speeds r psidot (no slip in the model engine); back-EMF k r_G u / r of motor m at rim
  // speed u, so the motor voltage is U = R i + emf.
  const auto emf = [&](int m, double u) { return km[m] * rG * u / r; };
  auto rimSpeeds = [&]() -> Eigen::Vector2d {
    return mj ? Eigen::Vector2d(r * mj->state().psidot_right_rad_s,
                                r * mj->state().psidot_left_rad_s)
              : Eigen::Vector2d(s.v + lw * s.om / 2, s.v - lw * s.om / 2);
  };

  for (long k = 0; k <= n_steps; ++k) {
    const double t = k * h;
    // Driver and supervisor see the true state.
    const JoystickDemand joy = sc.driver->demand({t, s.x, s.y, s.phi, s.v, s.om});
    if (opt.supervisory.enabled && t >= next_sup - 1e-12) {
      sup_scale = supervisoryScale(opt.supervisory, opt.footprint, s.x, s.y, s.phi, joy.v_m_s,
                                   joy.omega_rad_s, sc.obstacles);
      next_sup += 1.0 / opt.supervisory.rate_hz;
    }
    const JoystickDemand cmd{joy.v_m_s * sup_scale, joy.omega_rad_s * sup_scale};
    // Power module: currents within the current limit and what the battery can drive.
    const Eigen::Vector2d rim = rimSpeeds();
    Eigen::Vector2d i_lo, i_hi;
    for (int m = 0; m < 2; ++m) {
      i_lo(m) = (-pmp.battery_voltage_V - emf(m, rim(m))) / Rm;
      i_hi(m) = (pmp.battery_voltage_V - emf(m, rim(m))) / Rm;
    }
    const Eigen::Vector2d I = pm.step(cmd, rim, i_lo, i_hi);
    double U[2];
    for (int m = 0; m < 2; ++m) U[m] = Rm * I(m) + emf(m, rim(m));

    if (k % truth_stride == 0) {
      keepTruth(truthAt(t0 + t, s, rim / r, I, U, joy, pm, sup_scale), opt, res);
    }
    if (k == n_steps) break;

    // Mechanics over [t, t + h] with the currents held.
    const Mech s_prev = s;
    const double vrc_prev[2] = {wires.vrc(0), wires.vrc(1)};
    if (mj) {
      mj->step(I, h);
      const ChairState c = mj->state();
      s = {c.x_m, c.y_m, c.phi_rad, c.v_m_s, c.omega_rad_s, c.psi_right_rad, c.psi_left_rad};
    } else {
      s = rk4(s, dt, I, h, ext);
    }
    const Eigen::Vector2d rim_end = rimSpeeds();
    for (int m = 0; m < 2; ++m) wires.step(m, Rm * I(m) + emf(m, rim_end(m)));
    // Collisions: an obstacle centre inside the footprint (each obstacle once).
    markCollisions(sc.obstacles, opt.footprint, s, hit, res.truth.collided_obstacles);
    // Sensors sampled in (t, t + h] (the truth interpolated linearly within the step).
    const double vrc_end[2] = {wires.vrc(0), wires.vrc(1)};
    auto snapAt = [&](double tm) {
      return interpolate(s_prev, vrc_prev, s, vrc_end, std::clamp((tm - t) / h, 0.0, 1.0));
    };
    sensors.sampleUntil(t + h, t0, snapAt, I, joy, put);
  }
  res.collisions = static_cast<int>(res.truth.collided_obstacles.size());
  if (opt.record_ground_truth && !opt.sink)
    for (const auto& ts : res.truth.samples)
      rec.ground_truth.push_back({ts.t_s, ts.x_m, ts.y_m, ts.phi_rad});
  return res;
}

// ------------------------------------------------------------------------------------------
namespace {

using nlohmann::json;

#define WC_TRUTH_COLUMNS(X)                                                                    \
  X(t_s)                                                                                       \
  X(x_m)                                                                                       \
  X(y_m)                                                                                       \
  X(phi_rad)                                                                                   \
  X(v_m_s)                                                                                     \
  X(omega_rad_s)                                                                               \
  X(wheel_speed_right_rad_s)                                                                   \
  X(wheel_speed_left_rad_s)                                                                    \
  X(wheel_angle_right_rad)                                                                     \
  X(wheel_angle_left_rad)                                                                      \
  X(current_right_A)                                                                           \
  X(current_left_A) X(voltage_right_V) X(voltage_left_V) X(v_demand_m_s) X(omega_demand_rad_s) \
      X(v_ref_m_s) X(omega_ref_rad_s) X(supervisory_scale)

std::string fmtNum(double x) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  // shortest round-trip representation
  for (int p = 6; p <= 17; ++p) {
    char b2[40];
    std::snprintf(b2, sizeof b2, "%.*g", p, x);
    if (std::strtod(b2, nullptr) == x) return b2;
  }
  return buf;
}

// A double as json::dump() writes it (shortest round trip, "null" when not finite).
void putJsonNumber(std::ostream& os, double x) {
  if (!std::isfinite(x)) {
    os << "null";
    return;
  }
  std::array<char, 64> buf{};
  const char* end = nlohmann::detail::to_chars(buf.data(), buf.data() + buf.size(), x);
  os.write(buf.data(), end - buf.data());
}

// {"column": [v, ...], ...} in the key order and format of json::dump() (keys sorted, no
// spaces), one column at a time from the samples.
void writeTruthColumns(std::ostream& os, const SimulationResult::TruthReplay& replay) {
  std::map<std::string, double TruthSample::*> columns;
#define WC_MEMBER(c) columns[#c] = &TruthSample::c;
  WC_TRUTH_COLUMNS(WC_MEMBER)
#undef WC_MEMBER
  os << '{';
  bool first = true;
  for (const auto& [name, member] : columns) {
    os << (first ? "" : ",") << json(name).dump() << ":[";
    std::size_t i = 0;
    replay([&, m = member](const TruthSample& x) {
      if (i++) os << ',';
      putJsonNumber(os, x.*m);
    });
    os << ']';
    first = false;
  }
  os << '}';
}

}  // namespace

void SimulationResult::writeTruth(const std::string& path) const {
  writeTruth(path, [this](const std::function<void(const TruthSample&)>& f) {
    for (const auto& x : truth.samples) f(x);
  });
}

void SimulationResult::writeTruth(const std::string& path, const TruthReplay& replay) const {
  const bool csv = path.size() >= 4 && path.compare(path.size() - 4, 4, ".csv") == 0;
  if (csv) {
    util::AtomicFile file(path);  // streamed row by row
    std::ostream& os = file.stream();
    std::string out;
#define WC_HDR(c) out += std::string(out.empty() ? "" : ",") + #c;
    WC_TRUTH_COLUMNS(WC_HDR)
#undef WC_HDR
    os << out << "\n";
    std::size_t n = 0;
    replay([&](const TruthSample& s) {
      std::string row;
#define WC_ROW(c) row += (row.empty() ? "" : ",") + fmtNum(s.c);
      WC_TRUTH_COLUMNS(WC_ROW)
#undef WC_ROW
      os << row << "\n";
      if (++n % 4096 == 0) file.check();
    });
    file.commit();
    return;
  }
  json j;
  j["format"] = "libwheelchair-truth-1";
  j["scenario"] = scenario;
  j["engine"] = engine;
  j["seed"] = seed;
  j["duration_s"] = duration_s;
  j["supervisory"] = supervisory;
  j["collisions"] = collisions;
  j["collided_obstacles"] = truth.collided_obstacles;
  json eff = json::array();
  for (const auto& e : effects) {
    json je;
    je["id"] = e.id;
    je["params"] = e.params;
    je["text"] = effects::formatEffect(e);
    eff.push_back(je);
  }
  j["effects"] = eff;
  json obs = json::array();
  for (const auto& o : truth.obstacles)
    obs.push_back({{"x_m", o.x_m}, {"y_m", o.y_m}, {"radius_m", o.radius_m}});
  j["obstacles"] = obs;
  j["frames"] = {{"trajectory", "start frame: body frame at t = 0, x forward, y left"},
                 {"pozyx_anchor", "p_anchor = R(yaw_rad) p_start + (x_m, y_m)"}};
  j["pozyx_anchor"] = {{"x_m", truth.pozyx_anchor.x_m},
                       {"y_m", truth.pozyx_anchor.y_m},
                       {"yaw_rad", truth.pozyx_anchor.yaw_rad}};
  j["trajectory"] = nullptr;  // streamed below, column by column, straight from the samples
  j["config"] = config_text;
  // One top-level key per line (readable header, compact columns); the same bytes as
  // json::dump() of the whole document, without building the ~100 B-per-number DOM.
  util::AtomicFile file(path);
  std::ostream& os = file.stream();
  os << "{\n";
  bool first = true;
  for (auto it = j.begin(); it != j.end(); ++it) {
    os << (first ? "" : ",\n") << json(it.key()).dump() << ": ";
    if (it.key() == "trajectory")
      writeTruthColumns(os, replay);
    else
      os << it.value().dump();
    file.check();
    first = false;
  }
  os << "\n}\n";
  file.commit();
}

SimulationResult readTruth(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open truth file");
  json j;
  try {
    in >> j;
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": not a truth JSON file: " + e.what());
  }
  if (j.value("format", "") != "libwheelchair-truth-1")
    throw std::runtime_error(path + ": not a libwheelchair truth file");
  SimulationResult r;
  try {
    r.scenario = j.at("scenario").get<std::string>();
    r.engine = j.value("engine", "model");
    r.seed = j.at("seed").get<uint64_t>();
    r.duration_s = j.at("duration_s").get<double>();
    r.supervisory = j.value("supervisory", false);
    r.collisions = j.at("collisions").get<int>();
    r.truth.collided_obstacles = j.at("collided_obstacles").get<std::vector<int>>();
    for (const auto& je : j.at("effects"))
      r.effects.push_back({je.at("id").get<std::string>(),
                           je.at("params").get<std::map<std::string, std::string>>()});
    for (const auto& o : j.at("obstacles"))
      r.truth.obstacles.push_back(
          {o.at("x_m").get<double>(), o.at("y_m").get<double>(), o.at("radius_m").get<double>()});
    const auto& a = j.at("pozyx_anchor");
    r.truth.pozyx_anchor = {a.at("x_m").get<double>(), a.at("y_m").get<double>(),
                            a.at("yaw_rad").get<double>()};
    const auto& tr = j.at("trajectory");
    const std::size_t n = tr.at("t_s").size();
    r.truth.samples.resize(n);
#define WC_RD(c)                                                                     \
  {                                                                                  \
    const auto& col = tr.at(#c);                                                     \
    if (col.size() != n) throw std::runtime_error("column " #c " has wrong length"); \
    for (std::size_t i = 0; i < n; ++i) r.truth.samples[i].c = col[i].get<double>(); \
  }
    WC_TRUTH_COLUMNS(WC_RD)
#undef WC_RD
    r.config_text = j.value("config", "");
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": malformed truth file: " + e.what());
  }
  return r;
}

}  // namespace wheelchair::simulation
