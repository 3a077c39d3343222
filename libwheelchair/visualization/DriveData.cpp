#include "libwheelchair/visualization/DriveData.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/model/Kinematics.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace wheelchair::visualization {

bool TruthInfo::poseAt(double t, double& x, double& y, double& phi) const {
  if (t_s.empty()) return false;
  if (t <= t_s.front()) {
    x = x_m.front(), y = y_m.front(), phi = phi_rad.front();
    return true;
  }
  if (t >= t_s.back()) {
    x = x_m.back(), y = y_m.back(), phi = phi_rad.back();
    return true;
  }
  const std::size_t k = std::upper_bound(t_s.begin(), t_s.end(), t) - t_s.begin();
  const double a = (t - t_s[k - 1]) / (t_s[k] - t_s[k - 1]);
  x = x_m[k - 1] + a * (x_m[k] - x_m[k - 1]);
  y = y_m[k - 1] + a * (y_m[k] - y_m[k - 1]);
  phi = phi_rad[k - 1] + a * model::wrapAngle(phi_rad[k] - phi_rad[k - 1]);
  return true;
}

std::optional<TruthInfo> readTruthJson(const std::string& path) {
  if (!std::filesystem::exists(path)) return std::nullopt;
  std::ifstream in(path);
  TruthInfo t;
  try {
    const auto j = nlohmann::json::parse(in);
    const auto& tr = j.at("trajectory");
    auto col = [&](const char* name, std::vector<double>& v) {
      if (tr.contains(name)) v = tr.at(name).get<std::vector<double>>();
    };
    col("t_s", t.t_s);
    col("x_m", t.x_m);
    col("y_m", t.y_m);
    col("phi_rad", t.phi_rad);
    col("v_m_s", t.v_m_s);
    col("omega_rad_s", t.omega_rad_s);
    const std::size_t n = t.t_s.size();
    if (t.x_m.size() != n || t.y_m.size() != n || t.phi_rad.size() != n)
      throw std::runtime_error("trajectory columns of unequal length");
    for (const auto& o : j.value("obstacles", nlohmann::json::array()))
      t.obstacles.push_back(
          {o.at("x_m").get<double>(), o.at("y_m").get<double>(), o.value("radius_m", 0.05)});
    if (j.contains("pozyx_anchor")) {
      const auto& a = j.at("pozyx_anchor");
      t.anchor_x_m = a.value("x_m", 0.0);
      t.anchor_y_m = a.value("y_m", 0.0);
      t.anchor_yaw_rad = a.value("yaw_rad", 0.0);
    }
    t.scenario = j.value("scenario", "");
    for (const auto& e : j.value("effects", nlohmann::json::array()))
      t.effects += (t.effects.empty() ? "" : "; ") + e.value("text", std::string());
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": not a readable truth file: " + e.what());
  }
  return t;
}

const estimation::EstimateSample* DriveData::ekfAt(double t) const {
  const auto& v = est.ekf.estimates;
  if (v.empty()) return nullptr;
  auto it =
      std::upper_bound(v.begin(), v.end(), t,
                       [](double tt, const estimation::EstimateSample& s) { return tt < s.t_s; });
  if (it == v.begin()) return &v.front();
  return &*(it - 1);
}

DriveData loadDrive(const std::string& path, const config::WheelchairConfig& cfg,
                    const evaluation::MetricOptions& metric_options,
                    const std::string& truth_path) {
  return loadDrive(io::readRawlog(path), path, cfg, metric_options, truth_path);
}

DriveData loadDrive(io::Recording rec, const std::string& path, const config::WheelchairConfig& cfg,
                    const evaluation::MetricOptions& metric_options,
                    const std::string& truth_path) {
  DriveData d;
  d.path = path;
  d.cfg = cfg;
  d.rec = std::move(rec);
  d.est = evaluation::estimateVariants(d.rec, cfg, true);
  d.gt = evaluation::groundTruthOf(d.rec, cfg);
  d.truth = readTruthJson(truth_path.empty() ? path + ".truth.json" : truth_path);

  evaluation::MetricOptions mo = metric_options;
  mo.lever_arm_m = d.gt.lever_arm_m;
  d.metrics.recordings = 1;
  d.metrics.alignment = mo.alignment;
  d.metrics.align_first_s = mo.align_first_s;
  bool failed = false;
  for (const auto& [variant, err] : d.est.errors) {
    evaluation::BatchRow row;
    row.recording = std::filesystem::path(path).filename().string();
    row.variant = variant;
    row.ground_truth = evaluation::toString(d.gt.source);
    row.error = err;
    if (err.empty()) {
      try {
        auto t = d.est.trajectory(variant);
        row.n_estimates = t.size();
        row.metrics = evaluation::computeMetrics(t, d.gt.samples, mo);
        d.trajectories[variant] = std::move(t);
      } catch (const std::exception& e) {
        row.error = e.what();
      }
    }
    failed |= !row.error.empty();
    d.metrics.rows.push_back(std::move(row));
  }
  d.metrics.failed_recordings = failed ? 1 : 0;
  if (!d.est.ekf.estimates.empty()) {
    d.t0_s = d.est.ekf.estimates.front().t_s;
    d.t1_s = d.est.ekf.estimates.back().t_s;
  } else {
    d.t0_s = d.rec.startTime();
    d.t1_s = d.rec.endTime();
  }

  // Ground truth in the start frame.
  if (!d.gt.samples.empty()) {
    evaluation::SE2 T_inv;  // gt frame -> start frame
    bool have = false;
    if (d.truth && d.gt.source == evaluation::GroundTruthSource::Pozyx) {
      evaluation::SE2 A{d.truth->anchor_x_m, d.truth->anchor_y_m, d.truth->anchor_yaw_rad};
      T_inv = A.inverse();
      have = true;
      d.gt_frame_note = "mapped into the start frame with the simulator's known anchor frame";
    } else if (d.truth && d.gt.source == evaluation::GroundTruthSource::GroundTruthStream) {
      have = true;
      d.gt_frame_note = "simulated ground-truth stream (start frame)";
    } else if (d.trajectories.count("ekf")) {
      evaluation::MetricOptions se2 = mo;
      se2.alignment = evaluation::Alignment::SE2;
      const auto m = evaluation::computeMetrics(d.trajectories.at("ekf"), d.gt.samples, se2);
      if (m.n_matched > 0) {
        T_inv = m.alignment.inverse();
        have = true;
        d.gt_frame_note = "aligned to the EKF trajectory (least-squares SE(2))";
      }
    }
    if (have)
      for (const auto& s : d.gt.samples) {
        const Eigen::Vector2d p = T_inv.apply({s.x_m, s.y_m});
        d.gt_start.push_back(
            {s.t_s, p.x(), p.y(), s.hasHeading() ? T_inv.applyHeading(s.phi_rad) : s.phi_rad});
      }
  }
  return d;
}

double defaultObstacleTime(const DriveData& d) {
  // Middle of the first run of valid (non-zero) sonar readings: the chair approaches the
  // obstacle and the estimate is in front of it (runs separated by > 2 s of dropouts).
  double a = NAN, b = NAN;
  for (const auto& s : d.rec.sonar) {
    if (!(s.range_m > 0)) continue;
    if (std::isnan(a)) {
      a = b = s.t_s;
    } else if (s.t_s - b > 2.0) {
      break;
    } else {
      b = s.t_s;
    }
  }
  if (!std::isnan(a)) return a + 0.5 * (b - a);
  double e0 = NAN, e1 = NAN;
  for (const auto& e : d.est.ekf.estimates)
    if (e.obstacle_initialised) {
      if (std::isnan(e0)) e0 = e.t_s;
      e1 = e.t_s;
    }
  if (std::isnan(e0)) return d.t0_s;
  return e0 + 0.4 * (e1 - e0);
}

bool predictedSonarRange(const DriveData& d, const estimation::EstimateSample& e, double& r,
                         double& sd) {
  if (!e.obstacle_initialised) return false;
  const double dx = e.x(5) - d.cfg.sonar.x_m, dy = e.x(6) - d.cfg.sonar.y_m;
  r = std::hypot(dx, dy);
  if (r < 1e-9) {
    sd = std::sqrt(std::max(0.0, e.P(5, 5)));
    return true;
  }
  const Eigen::RowVector2d J(dx / r, dy / r);
  sd = std::sqrt(std::max(0.0, (J * e.P.block<2, 2>(5, 5) * J.transpose())(0, 0)));
  return true;
}

}  // namespace wheelchair::visualization
