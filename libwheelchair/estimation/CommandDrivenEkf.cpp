#include "libwheelchair/estimation/CommandDrivenEkf.h"

#include <nlohmann/json.hpp>

#include "libwheelchair/estimation/Measurement.h"
#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/stats/Distributions.h"

#include <fmt/format.h>
#include "libwheelchair/config/WheelchairConfig.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <stdexcept>

namespace wheelchair::estimation {

namespace {
using model::wrapAngle;

model::CommandSignal commandSignal(const io::Recording& rec, const CommandDrivenEkfOptions& o) {
  std::vector<model::CommandSample> rows;
  rows.reserve(rec.joystick.size());
  for (const auto& j : rec.joystick) rows.push_back({j.t_s, j.v_cmd_m_s, j.omega_cmd_rad_s});
  // CommandSignal needs file order (non-decreasing time); a stable sort keeps the order of
  // equal timestamps, so the LAST row of equal times stays the one in effect.
  std::stable_sort(
      rows.begin(), rows.end(),
      [](const model::CommandSample& a, const model::CommandSample& b) { return a.t_s < b.t_s; });
  model::CommandSignalOptions so;
  so.drop_short_zero_runs = o.ignore_zero_runs;
  so.max_zero_run_s = o.max_zero_run_s;
  return model::CommandSignal(rows, so);
}
}  // namespace

bool CommandDrivenEkfOptions::hasUnmodeled() const {
  for (const auto& ch : unmodeled)
    for (double c : ch)
      if (c != 0) return true;
  return false;
}

Eigen::Vector2d CommandDrivenEkfOptions::unmodeledVelocity(const Eigen::Vector2d& cmd) const {
  const auto fe = model::commandFeatures(cmd);
  Eigen::Vector2d d = Eigen::Vector2d::Zero();
  for (int k = 0; k < model::kNumCommandFeatures; ++k)
    d(0) += unmodeled[0][k] * fe(k), d(1) += unmodeled[1][k] * fe(k);
  return d;
}

namespace {
// Pose increment of the unmodeled velocities over h (midpoint heading), and its heading
// Jacobian for the covariance.
void addUnmodeled(model::CommandState& x, const Eigen::Vector2d& dv, double h,
                  Eigen::Matrix<double, 5, 5>* Phi = nullptr) {
  const double ds = dv(0) * h, dphi = dv(1) * h, a = x(2) + dphi / 2;
  x(0) += ds * std::cos(a);
  x(1) += ds * std::sin(a);
  x(2) += dphi;
  if (Phi) (*Phi)(0, 2) += -ds * std::sin(a), (*Phi)(1, 2) += ds * std::cos(a);
}
}  // namespace

CommandDrivenEkfOptions loadCommandDrivenEkfOptions(const std::string& path) {
  if (!std::filesystem::exists(path)) throw std::runtime_error(path + ": no such file");
  const auto cfg = config::WheelchairConfig::load(path);  // strict: every key checked
  return loadCommandDrivenEkfOptions(cfg.ini());
}

std::map<std::string, std::string> responseConfigKeys(const CommandDrivenEkfOptions& o) {
  using K = model::CommandKind;
  const auto& p = o.response;
  std::map<std::string, std::string> k;
  // Shortest text that reads back to the same double (fmt's default).
  const auto num = [](double v) { return fmt::format("{}", v); };
  k["v_delay_s"] = num(p.v.delay_s);
  k["v_time_constant_s"] = num(p.v.time_constant_s);
  k["v_deadband_m_s"] = num(p.v.deadband);
  k["omega_delay_s"] = num(p.omega.delay_s);
  k["omega_time_constant_s"] = num(p.omega.time_constant_s);
  k["omega_deadband_rad_s"] = num(p.omega.deadband);
  k["v_gain_straight"] = num(p.v_gain[static_cast<int>(K::Straight)]);
  k["v_gain_arc"] = num(p.v_gain[static_cast<int>(K::Arc)]);
  k["v_gain_backward"] = num(p.v_gain_backward);
  k["omega_gain_turn_in_place"] = num(p.omega_gain[static_cast<int>(K::TurnInPlace)]);
  k["omega_gain_arc"] = num(p.omega_gain[static_cast<int>(K::Arc)]);
  k["ignore_zero_runs"] = o.ignore_zero_runs ? "true" : "false";
  k["max_zero_run_s"] = num(o.max_zero_run_s);
  for (int ch = 0; ch < 2; ++ch) {
    nlohmann::json u = nlohmann::json::object();
    for (int j = 0; j < model::kNumCommandFeatures; ++j)
      if (o.unmodeled[ch][j] != 0) u[model::commandFeatureNames()[j]] = o.unmodeled[ch][j];
    if (!u.empty()) k[ch == 0 ? "unmodeled_v" : "unmodeled_omega"] = u.dump();
  }
  return k;
}

std::string toIni(const CommandDrivenEkfOptions& o) {
  std::string s = "[mrclam_response]\n";
  for (const auto& [key, value] : responseConfigKeys(o)) s += key + " = " + value + "\n";
  const auto kv = [&s](const char* k, double v) { s += fmt::format("{} = {}\n", k, v); };
  s += "\n[mrclam_filter]\n";
  kv("dt_s", o.dt_s);
  kv("output_every_s", o.output_every_s);
  kv("v_noise_m_s_sqrt_s", std::sqrt(o.q_v));
  kv("omega_noise_rad_s_sqrt_s", std::sqrt(o.q_omega));
  kv("range_sigma_m", o.range_sigma_m);
  kv("bearing_sigma_rad", o.bearing_sigma_rad);
  kv("gate_probability", o.gate_probability);
  kv("init_window_s", o.init_window_s);
  kv("init_min_separation_m", o.init_min_separation_m);
  kv("init_sigma_xy_m", o.init_sigma_xy_m);
  kv("init_sigma_phi_rad", o.init_sigma_phi_rad);
  s += fmt::format("init_from_geometry = {}\n", o.init_from_geometry ? "true" : "false");
  return s;
}

bool hasCommandDrivenSections(const mrpt::config::CConfigFileBase& ini) {
  std::vector<std::string> sections;
  ini.getAllSections(sections);
  return std::any_of(sections.begin(), sections.end(), [](const std::string& s) {
    return s == "mrclam_filter" || s == "mrclam_response";
  });
}

bool isCommandDrivenRecording(const io::Recording& rec) {
  return !rec.landmarks.empty() || !io::landmarkMap(rec).empty();
}

std::vector<std::string> missingForCommandDrivenEkf(const io::Recording& rec) {
  std::vector<std::string> missing;
  const auto map = io::landmarkMap(rec);
  if (rec.joystick.empty()) missing.push_back("the command stream (JOYSTICK)");
  if (rec.landmarks.empty())
    missing.push_back("landmark range-bearing sightings (LANDMARKS, CObservationBearingRange)");
  if (map.empty())
    missing.push_back(
        "the landmark map (header meta keys landmark.<id> = x y sx sy, written by `wheelchair "
        "import --format mrclam` from Landmark_Groundtruth.dat)");
  if (!map.empty() && !rec.landmarks.empty()) {
    std::set<int> ids;
    for (const auto& m : map) ids.insert(m.id);
    if (std::none_of(rec.landmarks.begin(), rec.landmarks.end(),
                     [&](const io::LandmarkSample& z) { return ids.count(z.landmark_id) > 0; }))
      missing.push_back("sightings of mapped landmarks (every sighting is of an unmapped subject)");
  }
  return missing;
}

namespace {
[[maybe_unused]] const bool kRegistered = config::registerOptions([] {
  auto o = std::make_shared<CommandDrivenEkfOptions>();
  auto t = o->options();
  for (auto& x : t) x.keepAlive(o);
  return t;
});

// A density given as its square root (the INI's unit) and stored squared.
config::Options& sqrtKey(config::Options& t, const char* key, double& squared, const char* help) {
  return t.custom(
      key,
      [&squared](const std::string& s) {
        const double x = config::parseStrictNumber(s, "value");
        if (!(x >= 0)) throw std::runtime_error(fmt::format("{} is out of range >= 0", s));
        squared = x * x;
      },
      [&squared] { return fmt::format("{}", std::sqrt(squared)); }, help);
}

// unmodeled_v / unmodeled_omega: JSON {feature: coefficient}.
config::Options& unmodeledKey(config::Options& t, const char* key,
                              std::array<double, model::kNumCommandFeatures>& coef) {
  return t.custom(
      key,
      [&coef](const std::string& text) {
        nlohmann::json j;
        try {
          j = nlohmann::json::parse(text);
        } catch (const std::exception& e) {
          throw std::runtime_error(
              fmt::format("not a JSON object of feature -> coefficient ({})", e.what()));
        }
        const auto& names = model::commandFeatureNames();
        for (auto it = j.begin(); it != j.end(); ++it) {
          const auto at = std::find(names.begin(), names.end(), it.key());
          if (at == names.end() || !it.value().is_number())
            throw std::runtime_error(
                fmt::format("unknown feature '{}' (known: 1, v_cmd, omega_cmd, |omega_cmd|, "
                            "v_cmd*|omega_cmd|) or non-numeric coefficient",
                            it.key()));
          coef[at - names.begin()] = it.value().get<double>();
        }
      },
      [&coef] {
        nlohmann::json u = nlohmann::json::object();
        for (int j = 0; j < model::kNumCommandFeatures; ++j)
          if (coef[j] != 0) u[model::commandFeatureNames()[j]] = coef[j];
        return u.empty() ? std::string() : u.dump();
      },
      "terms outside the catalogue (JSON {feature: coefficient}; written by diagnose)");
}
}  // namespace

std::vector<config::Options> CommandDrivenEkfOptions::options() {
  using config::Range;
  using K = model::CommandKind;
  const Range pos = Range::above(0), nonneg = Range::atLeast(0);
  auto& p = response;
  config::Options r("mrclam_response", "drive response to the commanded (v, omega)");
  r.real("v_delay_s", p.v.delay_s, "pure delay of v (s)", nonneg)
      .real("v_time_constant_s", p.v.time_constant_s, "lag time constant of v (s)", nonneg)
      .real("v_deadband_m_s", p.v.deadband, "deadband of v (m/s)", nonneg)
      .real("omega_delay_s", p.omega.delay_s, "pure delay of omega (s)", nonneg)
      .real("omega_time_constant_s", p.omega.time_constant_s, "lag time constant of omega (s)",
            nonneg)
      .real("omega_deadband_rad_s", p.omega.deadband, "deadband of omega (rad/s)", nonneg)
      .real("v_gain_straight", p.v_gain[static_cast<int>(K::Straight)], "gain on v, straight (-)")
      .real("v_gain_arc", p.v_gain[static_cast<int>(K::Arc)], "gain on v, arcs (-)")
      .real("v_gain_backward", p.v_gain_backward, "extra gain on v, backward (-)")
      .real("omega_gain_turn_in_place", p.omega_gain[static_cast<int>(K::TurnInPlace)],
            "gain on omega, turning in place (-)")
      .real("omega_gain_arc", p.omega_gain[static_cast<int>(K::Arc)], "gain on omega, arcs (-)")
      .flag("ignore_zero_runs", ignore_zero_runs, "ignore short (0,0) command runs")
      .real("max_zero_run_s", max_zero_run_s, "longest (0,0) run treated as a blip (s)", nonneg);
  unmodeledKey(r, "unmodeled_v", unmodeled[0]);
  unmodeledKey(r, "unmodeled_omega", unmodeled[1]);
  config::Options f("mrclam_filter", "command-driven EKF (docs/real-data.md)");
  f.real("dt_s", dt_s, "propagation step (s)", pos)
      .real("output_every_s", output_every_s, "output interval (s)", pos);
  sqrtKey(f, "v_noise_m_s_sqrt_s", q_v, "white-noise density on v (m/s/sqrt(s))");
  sqrtKey(f, "omega_noise_rad_s_sqrt_s", q_omega, "white-noise density on omega (rad/s/sqrt(s))");
  f.real("range_sigma_m", range_sigma_m, "sighting range noise, 1 sigma (m)", pos)
      .real("bearing_sigma_rad", bearing_sigma_rad, "sighting bearing noise, 1 sigma (rad)", pos)
      .real("gate_probability", gate_probability, "NIS gate probability (-; 0 = no gate)",
            Range{0, 1, false, true})
      .real("init_window_s", init_window_s, "two initialising sightings within (s)", pos)
      .real("init_min_separation_m", init_min_separation_m,
            "of landmarks at least this far apart (m)", nonneg)
      .real("init_sigma_xy_m", init_sigma_xy_m, "initial position 1 sigma (m)", nonneg)
      .real("init_sigma_phi_rad", init_sigma_phi_rad, "initial heading 1 sigma (rad)", nonneg)
      .flag("init_from_geometry", init_from_geometry, "initial covariance from the geometry");
  return {r, f};
}

CommandDrivenEkfOptions loadCommandDrivenEkfOptions(const mrpt::config::CConfigFileBase& ini) {
  CommandDrivenEkfOptions o;
  for (const auto& t : o.options()) t.load(ini);
  return o;
}

Eigen::Vector2d rangeBearing(const model::CommandState& x, const Eigen::Vector2d& L,
                             Eigen::Matrix<double, 2, 5>* H) {
  const double dx = L(0) - x(0), dy = L(1) - x(1);
  const double q = dx * dx + dy * dy, r = std::sqrt(q);
  if (H) {
    H->setZero();
    (*H)(0, 0) = -dx / r;
    (*H)(0, 1) = -dy / r;
    (*H)(1, 0) = dy / q;
    (*H)(1, 1) = -dx / q;
    (*H)(1, 2) = -1;
  }
  return {r, wrapAngle(std::atan2(dy, dx) - x(2))};
}

namespace {

/// The filter's start from the first two sightings z[i], z[j] of mapped landmarks at least
/// init_min_separation_m apart within init_window_s: closed-form pose (map frame: heading from
/// the landmark pair, position from L_j), with init_from_geometry the sighting noise
/// propagated through it (numerical Jacobian; else 0), the index of the first sighting after
/// them (j + 1) and the time of z[j].
struct SightingStart {
  bool found = false;
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  std::size_t next = 0;
  double t_s = 0;
};

SightingStart startFromSightings(const std::vector<io::LandmarkSample>& z,
                                 const std::map<int, Eigen::Vector2d>& L,
                                 const CommandDrivenEkfOptions& o) {
  SightingStart s0;
  const auto initPose = [](const Eigen::Vector2d& Li, const Eigen::Vector2d& Lj,
                           const Eigen::Vector4d& m) {
    const Eigen::Vector2d bi = m(0) * Eigen::Vector2d(std::cos(m(1)), std::sin(m(1)));
    const Eigen::Vector2d bj = m(2) * Eigen::Vector2d(std::cos(m(3)), std::sin(m(3)));
    const double phi = wrapAngle(std::atan2(Lj(1) - Li(1), Lj(0) - Li(0)) -
                                 std::atan2(bj(1) - bi(1), bj(0) - bi(0)));
    const Eigen::Vector2d p = Lj - Eigen::Vector2d(std::cos(phi) * bj(0) - std::sin(phi) * bj(1),
                                                   std::sin(phi) * bj(0) + std::cos(phi) * bj(1));
    return Eigen::Vector3d(p(0), p(1), phi);
  };
  for (std::size_t i = 0; i < z.size(); ++i)
    for (std::size_t j = i + 1; j < z.size() && z[j].t_s - z[i].t_s <= o.init_window_s; ++j) {
      const Eigen::Vector2d Li = L.at(z[i].landmark_id), Lj = L.at(z[j].landmark_id);
      if ((Lj - Li).norm() < o.init_min_separation_m) continue;
      const Eigen::Vector4d m(z[i].range_m, z[i].bearing_rad, z[j].range_m, z[j].bearing_rad);
      s0.pose = initPose(Li, Lj, m);
      Eigen::Matrix<double, 3, 4> J;
      for (int k = 0; k < 4; ++k) {
        const double h = k % 2 ? 1e-6 : 1e-6 * std::max(1.0, m(k));
        Eigen::Vector4d a = m, b = m;
        a(k) += h;
        b(k) -= h;
        Eigen::Vector3d d = initPose(Li, Lj, a) - initPose(Li, Lj, b);
        d(2) = wrapAngle(d(2));
        J.col(k) = d / (2 * h);
      }
      const Eigen::Vector4d r_var(
          o.range_sigma_m * o.range_sigma_m, o.bearing_sigma_rad * o.bearing_sigma_rad,
          o.range_sigma_m * o.range_sigma_m, o.bearing_sigma_rad * o.bearing_sigma_rad);
      if (o.init_from_geometry) s0.P = J * r_var.asDiagonal() * J.transpose();
      s0.next = j + 1;
      s0.t_s = z[j].t_s;
      s0.found = true;
      return s0;
    }
  return s0;
}

/// The lagged velocity states (v, omega) at t_s: the drive response integrated on the dt_s
/// grid from the first command (steps counted in time relative to it, independent of the
/// clock offset).
Eigen::Vector2d responseAt(const model::CommandDrivenModel& mdl, const model::CommandSignal& sig,
                           const CommandDrivenEkfOptions& o, double t_s) {
  double yv = 0, yw = 0;
  const double t0 = sig.startTime(), span_s = t_s - t0;
  for (long i = 0; static_cast<double>(i) * o.dt_s < span_s; ++i) {
    const Eigen::Vector2d u = mdl.target(sig, t0 + (static_cast<double>(i) + 0.5) * o.dt_s);
    yv = model::lagStep(yv, u(0), o.dt_s, o.response.v.time_constant_s).y_next;
    yw = model::lagStep(yw, u(1), o.dt_s, o.response.omega.time_constant_s).y_next;
  }
  return {yv, yw};
}

/// One grid step of h seconds (input: the target at the step's midpoint t_mid): the mean by
/// the model's exact step (+ the unmodeled velocities of the command at t_mid), the
/// covariance P <- Phi P Phi' + G_w Qc G_w' h with Phi = I + F h + (F h)^2 / 2 and white noise
/// on the pose rates (v along the heading, omega) and, for a lagged channel, on its velocity.
void predictStep(const model::CommandDrivenModel& mdl, const model::CommandSignal& sig,
                 const CommandDrivenEkfOptions& o, double t_mid, double h, model::CommandState& x,
                 Eigen::Matrix<double, 5, 5>& P) {
  const bool lag_v = o.response.v.time_constant_s > 0, lag_w = o.response.omega.time_constant_s > 0;
  const Eigen::Vector2d u = mdl.target(sig, t_mid);
  const auto Fc = mdl.F(x, u);
  const Eigen::Matrix<double, 5, 5> A = Fc * h;
  const Eigen::Matrix<double, 5, 5> Phi = Eigen::Matrix<double, 5, 5>::Identity() + A + 0.5 * A * A;
  // Noise input: on the pose rates (unmodelled velocity error, both forms) and, for a
  // lagged channel, also on its velocity state.
  Eigen::Matrix<double, 5, 4> Gw = Eigen::Matrix<double, 5, 4>::Zero();
  const double c = std::cos(x(2)), s = std::sin(x(2));
  Gw(0, 0) = c;
  Gw(1, 0) = s;
  Gw(2, 1) = 1;
  if (lag_v) Gw(3, 2) = 1;
  if (lag_w) Gw(4, 3) = 1;
  const Eigen::Matrix4d Qc = Eigen::Vector4d(o.q_v, o.q_omega, o.q_v, o.q_omega).asDiagonal();
  x = mdl.step(x, u, h);
  Eigen::Matrix<double, 5, 5> Phi_u = Phi;
  if (o.hasUnmodeled()) addUnmodeled(x, o.unmodeledVelocity(sig.at(t_mid)), h, &Phi_u);
  P = Phi_u * P * Phi_u.transpose() + Gw * Qc * Gw.transpose() * h;
  P = 0.5 * (P + P.transpose());
}

/// The sightings of mapped landmarks in time order (stable: equal stamps keep the file's
/// order); `unmapped` counts the others.
std::vector<io::LandmarkSample> mappedSightings(const io::Recording& rec,
                                                const std::map<int, Eigen::Vector2d>& L,
                                                std::size_t& unmapped) {
  std::vector<io::LandmarkSample> sightings = rec.landmarks;
  std::stable_sort(
      sightings.begin(), sightings.end(),
      [](const io::LandmarkSample& a, const io::LandmarkSample& b) { return a.t_s < b.t_s; });
  std::vector<io::LandmarkSample> z;
  for (const auto& s : sightings) {
    if (L.count(s.landmark_id))
      z.push_back(s);
    else
      ++unmapped;
  }
  return z;
}

/// The start covariance: the pose's from the two initial sightings (P_pose) plus the
/// configured floors, the velocity states 0.05 m/s and 0.2 rad/s (1 sigma).
Eigen::Matrix<double, 5, 5> initialCovariance(const Eigen::Matrix3d& P_pose,
                                              const CommandDrivenEkfOptions& o) {
  Eigen::Matrix<double, 5, 5> P = Eigen::Matrix<double, 5, 5>::Zero();
  P.topLeftCorner<3, 3>() = P_pose;
  P(0, 0) += o.init_sigma_xy_m * o.init_sigma_xy_m;
  P(1, 1) += o.init_sigma_xy_m * o.init_sigma_xy_m;
  P(2, 2) += o.init_sigma_phi_rad * o.init_sigma_phi_rad;
  P(3, 3) = 0.05 * 0.05;
  P(4, 4) = 0.2 * 0.2;
  return P;
}

}  // namespace

CommandDrivenEkfResult runCommandDrivenEkf(const io::Recording& rec,
                                           const std::vector<io::LandmarkPosition>& map,
                                           const CommandDrivenEkfOptions& o,
                                           const ProgressFunction& progress) {
  using model::CommandState;
  CommandDrivenEkfResult res;
  std::map<int, Eigen::Vector2d> L;
  for (const auto& m : map) L[m.id] = {m.x_m, m.y_m};
  if (L.empty()) throw std::invalid_argument("runCommandDrivenEkf: empty landmark map");
  const std::vector<io::LandmarkSample> z = mappedSightings(rec, L, res.unmapped);
  // Initialisation from two sightings of well separated landmarks.
  const SightingStart s0 = startFromSightings(z, L, o);
  if (!s0.found) return res;
  CommandState x = CommandState::Zero();
  x << s0.pose(0), s0.pose(1), s0.pose(2), 0, 0;
  const std::size_t start = s0.next;
  res.t_start_s = s0.t_s;
  res.initialised = true;
  res.before_start = start;
  res.start_pose_xy = x.head<2>();
  res.start_phi_rad = x(2);
  Eigen::Matrix<double, 5, 5> P = initialCovariance(s0.P, o);

  const model::CommandSignal sig = commandSignal(rec, o);
  res.commands = sig.samples().size();
  res.dropped_zero_runs = sig.droppedZeroRuns();
  const model::CommandDrivenModel mdl(o.response);
  // Velocity states: start at the model's response (integrated from the first command).
  res.start_velocity = responseAt(mdl, sig, o, res.t_start_s);
  x(3) = res.start_velocity(0);
  x(4) = res.start_velocity(1);
  const double gate = o.gate_probability > 0 ? stats::chi2Quantile(o.gate_probability, 2) : 0.0;
  Eigen::Matrix2d R =
      Eigen::Vector2d(o.range_sigma_m * o.range_sigma_m, o.bearing_sigma_rad * o.bearing_sigma_rad)
          .asDiagonal();
  // The grid runs in time relative to the start (tau = t - t_ref): steps accumulated in UNIX
  // time (MRCLAM: 1.25e9 s) would round each to 2.4e-7 s and make the grid depend on the
  // clock offset (docs/estimation.md, "Clock offset"). t = t_ref + tau is for u(t) and outputs.
  const double t_ref = res.t_start_s;
  double tau = 0, next_out_tau = 0, t = t_ref;
  const double t_end = std::max(sig.endTime(), z.empty() ? t : z.back().t_s);
  double nis_sum_all = 0;
  const double t_first = t, span = std::max(t_end - t_first, 1e-9);
  double next_progress = t_first;
  const auto emit = [&] {
    CommandDrivenEstimate e{t, x(0), x(1), wrapAngle(x(2)), P(0, 0), P(1, 1), P(0, 1), P(2, 2)};
    // With no lag the velocity state is unused: the velocities in effect are the targets.
    const Eigen::Vector2d vel =
        mdl.effectiveVelocity(x, mdl.target(sig, t)) + o.unmodeledVelocity(sig.at(t));
    e.v_m_s = vel(0);
    e.omega_rad_s = vel(1);
    e.var_v = P(3, 3);
    e.var_omega = P(4, 4);
    res.trajectory.push_back(e);
    if (progress && t >= next_progress) {
      progress(std::min(1.0, (t - t_first) / span));
      next_progress += span / 200;
    }
  };
  emit();
  next_out_tau += o.output_every_s;
  std::size_t k = start;
  const auto propagateTo = [&](double t1) {
    const double tau1 = t1 - t_ref;
    while (tau < tau1 - 1e-12) {
      const double h = std::min(o.dt_s, tau1 - tau);
      const double t_mid = t_ref + (tau + h / 2);
      predictStep(mdl, sig, o, t_mid, h, x, P);
      tau += h;
      t = t_ref + tau;
      if (tau >= next_out_tau - 1e-9) {
        emit();
        next_out_tau += o.output_every_s;
      }
    }
  };
  // The library's one update path (Measurement.h) on work copies of the fixed-size state.
  Measurement meas(Sensor::Landmarks, 2, 5);
  meas.R = R;
  meas.angular_rows = 0b10;  // the bearing
  Eigen::VectorXd xw(5);
  Eigen::MatrixXd Pw(5, 5);
  for (; k < z.size(); ++k) {
    propagateTo(z[k].t_s);
    Eigen::Matrix<double, 2, 5> H;
    meas.h = rangeBearing(x, L[z[k].landmark_id], &H);
    meas.H = H;
    meas.z << z[k].range_m, z[k].bearing_rad;
    xw = x;
    Pw = P;
    const UpdateResult r = correct(xw, Pw, meas, gate);
    bookUpdate(res, Sensor::Landmarks, z[k].t_s, r, gate, false);
    nis_sum_all += r.nis;
    if (!r.accepted) continue;
    x = xw;
    P = Pw;
  }
  propagateTo(t_end);
  const SensorStats& st = res.landmarks();
  const long attempts = st.used + st.rejected;
  res.mean_nis_all = attempts ? nis_sum_all / double(attempts) : 0;
  if (progress) progress(1.0);
  return res;
}

std::vector<CommandDrivenEstimate> deadReckoningCommands(const io::Recording& rec,
                                                         const CommandDrivenEkfOptions& o,
                                                         double t0_s, const Eigen::Vector3d& pose0,
                                                         const Eigen::Vector2d& vel0) {
  std::vector<CommandDrivenEstimate> out;
  const model::CommandSignal sig = commandSignal(rec, o);
  if (sig.samples().empty()) return out;
  const model::CommandDrivenModel mdl(o.response);
  const bool unmodeled = o.hasUnmodeled();
  model::CommandState x;
  x << pose0(0), pose0(1), pose0(2), vel0(0), vel0(1);
  // Relative time on the grid, as in runCommandDrivenEkf.
  double tau = 0, next_out_tau = 0, t = t0_s;
  const double t_end = sig.endTime(), tau_end = t_end - t0_s;
  const auto emit = [&] {
    CommandDrivenEstimate e{t, x(0), x(1), wrapAngle(x(2)), 0, 0, 0, 0};
    const Eigen::Vector2d vel =
        mdl.effectiveVelocity(x, mdl.target(sig, t)) + o.unmodeledVelocity(sig.at(t));
    e.v_m_s = vel(0);
    e.omega_rad_s = vel(1);
    out.push_back(e);
    next_out_tau += o.output_every_s;
  };
  emit();
  while (tau < tau_end - 1e-12) {
    const double h = std::min(o.dt_s, tau_end - tau);
    const double t_mid = t0_s + (tau + h / 2);
    x = mdl.step(x, mdl.target(sig, t_mid), h);
    if (unmodeled) addUnmodeled(x, o.unmodeledVelocity(sig.at(t_mid)), h);
    tau += h;
    t = t0_s + tau;
    if (tau >= next_out_tau - 1e-9) emit();
  }
  if (out.back().t_s < t) emit();
  return out;
}

}  // namespace wheelchair::estimation
