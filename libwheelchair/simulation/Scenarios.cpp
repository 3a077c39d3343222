#include "libwheelchair/simulation/Scenarios.h"

#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/simulation/Random.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace wheelchair::simulation {

namespace {

using model::wrapAngle;

double clampAbs(double x, double m) {
  return std::max(-m, std::min(m, x));
}

struct Waypoint {
  double x, y;
};

/// Turns in place towards each waypoint, drives to it, waits for standstill.
class WaypointPilot : public Driver {
 public:
  WaypointPilot(std::vector<Waypoint> wps, const ScenarioSettings& s)
      : wps_(std::move(wps)), s_(s) {}

  JoystickDemand demand(const DriverView& w) override {
    if (w.t_s < s_.start_pause_s || idx_ >= wps_.size()) return {};
    const Waypoint& g = wps_[idx_];
    const double dx = g.x - w.x_m, dy = g.y - w.y_m;
    const double dist = std::hypot(dx, dy);
    double err = wrapAngle(std::atan2(dy, dx) - w.phi_rad);
    if (std::abs(err) > M_PI - 0.05) err = std::abs(err);  // a U-turn goes to the left
    const double along = dx * std::cos(w.phi_rad) + dy * std::sin(w.phi_rad);
    switch (phase_) {
      case Phase::Turn: {
        if (std::abs(err) < 0.01 || dist < 0.05) {
          phase_ = Phase::TurnSettle;
          return {};
        }
        const double mag = std::max(
            0.05, std::min(s_.max_turn_rate_rad_s,
                           std::sqrt(2 * s_.comfort_angular_decel_rad_s2 * std::abs(err))));
        return {0.0, err > 0 ? mag : -mag};
      }
      case Phase::TurnSettle:
        if (std::abs(w.omega_rad_s) < 0.02 && std::abs(w.v_m_s) < 0.02) phase_ = Phase::Drive;
        return {};
      case Phase::Drive: {
        if (along < 0.01) {
          phase_ = Phase::Settle;
          return {};
        }
        const double v = std::max(
            0.03, std::min(s_.max_speed_m_s, std::sqrt(2 * s_.comfort_decel_m_s2 * along)));
        const double om =
            dist > 0.3 ? clampAbs(s_.heading_gain_1_s * err, 0.5 * s_.max_turn_rate_rad_s) : 0.0;
        return {v, om};
      }
      case Phase::Settle:
        if (std::abs(w.omega_rad_s) < 0.01 && std::abs(w.v_m_s) < 0.01) {
          ++idx_;
          phase_ = Phase::Turn;
        }
        return {};
    }
    return {};
  }
  bool finished() const override { return idx_ >= wps_.size(); }

 private:
  enum class Phase { Turn, TurnSettle, Drive, Settle };
  std::vector<Waypoint> wps_;
  ScenarioSettings s_;
  std::size_t idx_ = 0;
  Phase phase_ = Phase::Turn;
};

/// Multisine + square-wave demands with periodic stops; phases from the seed.
class ExciteDriver : public Driver {
 public:
  ExciteDriver(uint64_t seed, const ScenarioSettings& s, double duration) : s_(s), T_(duration) {
    Rng rng(seed, "scenario.excite");
    for (double& p : ph_) p = rng.uniform(0, 2 * M_PI);
  }
  JoystickDemand demand(const DriverView& w) override {
    const double t = w.t_s - s_.start_pause_s;
    if (t < 0 || w.t_s > T_ - 2.0) return {};
    const double ramp = std::min(1.0, t / 1.0);
    const double gate = std::fmod(t, 15.0) > 13.5 ? 0.0 : 1.0;  // a 1.5 s stop every 15 s
    auto sq = [](double x) { return std::sin(x) >= 0 ? 1.0 : -1.0; };
    const double tw = 2 * M_PI * t;
    const double v = s_.excite_mean_speed_m_s + 0.25 * std::sin(0.05 * tw + ph_[0]) +
                     0.15 * std::sin(0.13 * tw + ph_[1]) + 0.10 * sq(0.31 * tw + ph_[2]);
    const double om = 0.45 * std::sin(0.07 * tw + ph_[3]) + 0.25 * std::sin(0.19 * tw + ph_[4]) +
                      0.15 * sq(0.41 * tw + ph_[5]);
    return {ramp * gate * v, ramp * gate * om};
  }

 private:
  ScenarioSettings s_;
  double T_;
  double ph_[6];
};

/// Fig. 2: the joystick held at a fixed position for a while.
class FixedJoystick : public Driver {
 public:
  FixedJoystick(double v, double om, double hold_s) : v_(v), om_(om), hold_(hold_s) {}
  JoystickDemand demand(const DriverView& w) override {
    if (w.t_s < hold_) return {v_, om_};
    return {};
  }

 private:
  double v_, om_, hold_;
};

}  // namespace

std::vector<Obstacle> defaultThreeTaskObstacles() {
  std::vector<Obstacle> o(1);
  o[0].x_m = 11.8;
  o[0].y_m = 0.25;
  o[0].radius_m = 0.05;
  return o;
}

std::vector<Obstacle> fieldLattice(double radius_m) {
  std::vector<Obstacle> o;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 7; ++j) o.push_back({-0.5 + i, -1.5 + j, radius_m});
  return o;
}

const std::vector<std::string>& scenarioNames() {
  static const std::vector<std::string> n = {"three_task", "excite", "square", "obstacles"};
  return n;
}

Scenario makeScenario(const std::string& name, uint64_t seed, const ScenarioSettings& s,
                      double duration_s) {
  Scenario sc;
  sc.name = name;
  if (name == "three_task") {
    const double L = s.three_task_length_m;
    sc.obstacles = s.three_task_obstacles;
    sc.driver = std::make_unique<WaypointPilot>(std::vector<Waypoint>{{L, 0}, {0, 0}}, s);
    // pause + two legs at cruise (with braking) + a half turn + settling + rest at the end
    sc.default_duration_s = std::ceil(s.start_pause_s + 2 * (L / s.max_speed_m_s + 2.5) +
                                      M_PI / s.max_turn_rate_rad_s + 6.0);
  } else if (name == "square") {
    const double a = s.square_side_m;
    sc.driver =
        std::make_unique<WaypointPilot>(std::vector<Waypoint>{{a, 0}, {a, a}, {0, a}, {0, 0}}, s);
    sc.default_duration_s = std::ceil(s.start_pause_s + 4 * (a / s.max_speed_m_s + 2.0) +
                                      4 * (M_PI / 2 / s.max_turn_rate_rad_s + 1.0) + 3.0);
  } else if (name == "excite") {
    sc.default_duration_s = 60.0;
    sc.driver = std::make_unique<ExciteDriver>(seed, s,
                                               duration_s > 0 ? duration_s : sc.default_duration_s);
  } else if (name == "obstacles") {
    sc.obstacles =
        s.field_obstacles.empty() ? fieldLattice(s.obstacle_radius_m) : s.field_obstacles;
    sc.driver =
        std::make_unique<FixedJoystick>(s.field_v_m_s, s.field_omega_rad_s, s.field_drive_s);
    sc.default_duration_s = s.field_drive_s;
  } else {
    std::string known;
    for (const auto& n : scenarioNames()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown scenario '" + name + "' (known: " + known + ")");
  }
  sc.duration_s = duration_s > 0 ? duration_s : sc.default_duration_s;
  return sc;
}

}  // namespace wheelchair::simulation
