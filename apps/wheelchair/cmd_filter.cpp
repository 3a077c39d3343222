// wheelchair filter FILE.rawlog : replays a recording through the estimator (the paper's
// continuous-discrete EKF integrated by CVODE, or the kinematic baseline) and writes the
// estimated trajectory, the per-time estimates with their standard deviations, and the
// Fig. 5 raw variants. Prints per-sensor usage, rejections and NIS statistics.
#include "Command.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/DeadReckoning.h"
#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/estimation/ModelExtensions.h"
#include "libwheelchair/evaluation/Batch.h"
#include "libwheelchair/evaluation/Trajectory.h"
#include "libwheelchair/io/RawlogIO.h"

#include <fmt/core.h>
#include <fmt/os.h>

#include <chrono>
#include <filesystem>
#include <iostream>

namespace wheelchair::cli {
namespace {

struct FilterCliOptions {
  std::string input, config_path, trajectory, estimates, filter, obstacle_form;
  bool variants = false, pozyx = false;
};

std::string withSuffix(const std::string& path, const std::string& suffix) {
  const std::filesystem::path p(path);
  return (p.parent_path() / (p.stem().string() + suffix + p.extension().string())).string();
}

void writeEstimatesCsv(const std::string& path, const estimation::EstimationResult& res) {
  const std::string tmp = path + ".tmp";
  {
    auto out = fmt::output_file(tmp);
    out.print(
        "t_s,v_m_s,omega_rad_s,x_m,y_m,phi_rad,obstacle_x_m,obstacle_y_m,obstacle_distance_m,"
        "sd_v_m_s,sd_omega_rad_s,sd_x_m,sd_y_m,sd_phi_rad,sd_obstacle_x_m,sd_obstacle_y_m,"
        "sd_obstacle_distance_m\n");
    for (const auto& e : res.estimates) {
      const auto& x = e.x;
      const auto& sd = e.sd;
      out.print("{:.6f},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", e.t_s, x(0), x(1), x(2),
                x(3), x(4), x(5), x(6), e.obstacle_distance_m, sd(0), sd(1), sd(2), sd(3), sd(4),
                sd(5), sd(6), e.obstacle_distance_sd_m);
    }
  }
  std::filesystem::rename(tmp, path);
}

int runFilter(const FilterCliOptions& o) {
  auto cfg = o.config_path.empty() ? config::WheelchairConfig()
                                   : config::WheelchairConfig::load(o.config_path);
  if (!o.filter.empty()) cfg.set("estimator", "filter", o.filter);
  if (!o.obstacle_form.empty()) cfg.set("estimator", "obstacle_form", o.obstacle_form);
  if (o.pozyx) cfg.set("estimator", "use_pozyx", "1");
  estimation::EkfOptions opt;
  opt.loadFromConfig(cfg.ini());
  opt.resolveSensorDefaults(cfg);

  io::RawlogReadReport rep;
  io::Recording rec = io::readRawlog(o.input, &rep);
  // A corrected configuration (`wheelchair diagnose --write-config`) calibrates the sensors
  // and the drive train before filtering (estimation/ModelExtensions.h).
  const auto ext = estimation::ModelExtensions::fromConfig(cfg.ini());
  if (!ext.empty()) {
    cfg = ext.adjustConfig(cfg);
    rec = ext.apply(rec, cfg);
    fmt::print("model extensions applied: {}\n", ext.summary());
  }
  const auto t0 = std::chrono::steady_clock::now();
  const estimation::EstimationResult res = estimation::runEstimator(rec, cfg, opt);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const double duration_s = rec.endTime() - rec.startTime();
  long measurements = 0;
  fmt::print("{}: {:.1f} s of recording, {} filter, processed in {:.3f} s ({:.0f}x real time)\n",
             o.input, duration_s, res.filter, wall_s, wall_s > 0 ? duration_s / wall_s : 0.0);
  fmt::print("{:<9} {:>7} {:>9} {:>9} {:>9} {:>10} {:>14} {:>9}\n", "sensor", "used", "rejected",
             "dropouts", "skipped", "mean NIS", "95% band", "in band");
  for (int s = 0; s < estimation::kNumSensors; ++s) {
    const auto& st = res.sensors[s];
    measurements += st.used + st.rejected + st.dropouts;
    if (!st.used && !st.rejected && !st.dropouts && !st.skipped) continue;
    const auto band = st.meanNisBand95();
    fmt::print("{:<9} {:>7} {:>9} {:>9} {:>9} {:>10.3f} {:>6.2f}..{:<6.2f} {:>8.1f}%\n",
               estimation::sensorName(static_cast<estimation::Sensor>(s)), st.used, st.rejected,
               st.dropouts, st.skipped, st.meanNis(), band.first, band.second,
               100 * st.fractionInside95());
  }
  for (const auto& w : res.warnings) fmt::print("warning: {}\n", w);
  if (!res.estimates.empty()) {
    const auto& f = res.final();
    fmt::print("final pose x = {:.3f} +- {:.3f} m, y = {:.3f} +- {:.3f} m, phi = {:.1f} deg\n",
               f.x(2), f.sd(2), f.x(3), f.sd(3), f.x(4) * 180 / M_PI);
  }

  if (!o.trajectory.empty()) {
    evaluation::writeTum(o.trajectory, evaluation::toTrajectory(res));
    fmt::print("trajectory (TUM, start frame): {}\n", o.trajectory);
  }
  if (!o.estimates.empty()) {
    writeEstimatesCsv(o.estimates, res);
    fmt::print("estimates (CSV): {}\n", o.estimates);
  }
  if (!o.trajectory.empty() || !o.estimates.empty()) {
    const std::string cfg_path =
        (o.trajectory.empty() ? o.estimates : o.trajectory) + ".config.ini";
    cfg.save(cfg_path);
    fmt::print("configuration used: {}\n", cfg_path);
  }
  if (o.variants) {
    const std::string base = o.trajectory.empty() ? "filter.tum" : o.trajectory;
    const auto enc = estimation::deadReckoningEncoders(rec.encoders, cfg.encoders.params,
                                                       cfg.vehicle.geom);
    const auto encg = estimation::deadReckoningEncoderGyro(rec.encoders, rec.imu,
                                                           cfg.encoders.params, cfg.vehicle.geom);
    evaluation::writeTum(withSuffix(base, "_encoders"), evaluation::toTrajectory(enc));
    evaluation::writeTum(withSuffix(base, "_encoders_gyro"), evaluation::toTrajectory(encg));
    fmt::print("Fig. 5 variants: {} (d_path {:.2f} m), {} (d_path {:.2f} m)\n",
               withSuffix(base, "_encoders"), estimation::pathLength(enc),
               withSuffix(base, "_encoders_gyro"), estimation::pathLength(encg));
  }
  return kExitOk;
}

const RegisterCommand reg{Command{
    "filter", "Replay a rawlog through the estimator (CVODE-integrated EKF or baseline)",
    [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<FilterCliOptions>();
      sub.add_option("input", o->input, "Input rawlog")->required();
      sub.add_option("--config", o->config_path, "Configuration INI (default: nominal)");
      sub.add_option("--trajectory", o->trajectory,
                     "Write the estimated body pose (TUM: t x y z qx qy qz qw, start frame)");
      sub.add_option("--estimates", o->estimates,
                     "Write v, omega, x, y, phi, obstacle x, y, distance and their sigmas (CSV)");
      sub.add_flag("--variants", o->variants,
                   "Also write the Fig. 5 raw variants: encoders only, encoder v + gyro omega");
      sub.add_option("--filter", o->filter, "physics (default) or baseline")
          ->check(CLI::IsMember({"physics", "baseline"}));
      sub.add_option("--obstacle-form", o->obstacle_form, "cartesian (7) or polar (8)")
          ->check(CLI::IsMember({"cartesian", "polar"}));
      sub.add_flag("--pozyx", o->pozyx, "Also fuse Pozyx positions (off: they are ground truth)");
      return [o] { return runFilter(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
