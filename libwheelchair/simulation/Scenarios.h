// Driving scenarios of the simulator: who holds the joystick and what stands on the floor.
//
//   three_task  the paper's experiment (IV.A): wait, drive 10 m forward, turn 180 deg in place
//               (to the left), drive back to the start, stop. One obstacle stands ahead of the
//               10 m mark, in the sonar's view during the first leg.
//   excite      persistently exciting open-loop drive for identification: multisine plus
//               square-wave demands of v and omega (phases from the seed), short stops and
//               reversals; no obstacles.
//   square      waypoints around a square (side [simulation] square_side_m), left turns in
//               place, back to the start.
//   obstacles   Fig. 2: a 1 m lattice of posts, joystick fixed at v = 0.52 m/s,
//               omega = 0.27 rad/s for 10 s (with or without the supervisory control).
//
// The waypoint scenarios are driven by a pilot that sees the TRUE pose (like a person
// following floor marks): it turns in place towards the next waypoint, drives to it with a
// comfortable deceleration profile and a heading correction, and waits for the chair to
// stop before the next one. Its demands are what the joystick stream records.
//
// Example:
//   ScenarioSettings s;
//   Scenario sc = makeScenario("three_task", 42, s);
//   JoystickDemand d = sc.driver->demand({t, x, y, phi, v, omega});
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace wheelchair::simulation {

/// A static obstacle: a round post at (x, y) in the start frame (m), radius (m).
struct Obstacle {
  double x_m = 0;
  double y_m = 0;
  double radius_m = 0.05;
};

struct JoystickDemand {
  double v_m_s = 0;
  double omega_rad_s = 0;
};

/// What the driver sees: time since the start and the true state (start frame).
struct DriverView {
  double t_s = 0;
  double x_m = 0, y_m = 0, phi_rad = 0;
  double v_m_s = 0, omega_rad_s = 0;
};

class Driver {
 public:
  virtual ~Driver() = default;
  virtual JoystickDemand demand(const DriverView& view) = 0;
  /// true once the scenario's task is over (the chair stands still from then on).
  virtual bool finished() const { return false; }
};

/// The three_task post: (11.8, 0.25) m, radius 5 cm, ahead of the 10 m mark.
std::vector<Obstacle> defaultThreeTaskObstacles();

/// Scenario settings ([simulation] keys, see SimulationOptions::loadFromConfig).
struct ScenarioSettings {
  double start_pause_s = 1.0;        ///< standstill before the driver moves (gyro bias!)
  double max_speed_m_s = 0.8;        ///< pilot's cruise speed
  double max_turn_rate_rad_s = 0.6;  ///< pilot's turning rate in place
  double comfort_decel_m_s2 = 0.4;   ///< pilot's braking profile v = sqrt(2 a d)
  double comfort_angular_decel_rad_s2 = 0.6;
  double heading_gain_1_s = 1.5;  ///< pilot's steering: omega = gain * heading error
  double three_task_length_m = 10.0;
  std::vector<Obstacle> three_task_obstacles = defaultThreeTaskObstacles();
  double square_side_m = 3.0;
  double excite_mean_speed_m_s = 0.35;
  std::vector<Obstacle> field_obstacles;  ///< empty: the default 1 m lattice (fieldLattice)
  double field_v_m_s = 0.52;
  double field_omega_rad_s = 0.27;
  double field_drive_s = 10.0;
  double obstacle_radius_m = 0.05;
};

/// The default Fig. 2 field: posts on a 1 m lattice, x = -0.5 .. 3.5, y = -1.5 .. 4.5 m.
std::vector<Obstacle> fieldLattice(double radius_m);

struct Scenario {
  std::string name;
  double default_duration_s = 0;
  double duration_s = 0;  ///< the run's duration (the requested one, or the default)
  std::vector<Obstacle> obstacles;
  std::unique_ptr<Driver> driver;
};

/// Known scenario names: three_task, excite, square, obstacles.
const std::vector<std::string>& scenarioNames();
/// Builds a scenario for a run of duration_s (<= 0: the scenario's default); throws
/// std::invalid_argument for an unknown name.
Scenario makeScenario(const std::string& name, uint64_t seed, const ScenarioSettings& s,
                      double duration_s = 0);

}  // namespace wheelchair::simulation
