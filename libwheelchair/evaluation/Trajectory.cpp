#include "libwheelchair/evaluation/Trajectory.h"

#include "libwheelchair/util/AtomicFile.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/util/AtomicFile.h"

namespace wheelchair::evaluation {

namespace {

bool parseDouble(const std::string& token, double& out) {
  if (token.empty()) return false;
  const char* begin = token.c_str();
  char* end = nullptr;
  errno = 0;
  out = std::strtod(begin, &end);
  return end == begin + token.size() && errno != ERANGE;
}

}  // namespace

struct TumWriter::Impl {
  explicit Impl(const std::string& path) : file(path) {}
  util::AtomicFile file;
};

TumWriter::TumWriter(const std::string& path, const std::vector<std::string>& comments)
    : impl_(std::make_unique<Impl>(path)) {
  std::ostream& os = impl_->file.stream();
  for (const auto& c : comments) os << "# " << c << "\n";
  os << "# timestamp x y z qx qy qz qw (planar pose, yaw-only quaternion)\n";
  impl_->file.check();
}

TumWriter::~TumWriter() = default;

void TumWriter::add(const Pose2DStamped& p) {
  if (pending_ && p.t_s < pending_->t_s)
    throw std::runtime_error(fmt::format("{}: pose at t = {} s after one at t = {} s",
                                         impl_->file.path(), p.t_s, pending_->t_s));
  if (!pending_ || p.t_s != pending_->t_s) {
    flushPending();
    ++poses_;
  }
  pending_ = p;
}

void TumWriter::flushPending() {
  if (!pending_) return;
  const auto& p = *pending_;
  // "{}" prints the shortest representation that reads back to the same double.
  fmt::memory_buffer buf;
  fmt::format_to(std::back_inserter(buf), "{} {} {} 0 0 0 {} {}\n", p.t_s, p.x_m, p.y_m,
                 std::sin(0.5 * p.phi_rad), std::cos(0.5 * p.phi_rad));
  impl_->file.stream().write(buf.data(), static_cast<std::streamsize>(buf.size()));
  if (poses_ % 4096 == 0) impl_->file.check();
  pending_.reset();
}

void TumWriter::commit() {
  flushPending();
  impl_->file.commit();
}

void writeTum(const std::string& path, const Trajectory& traj,
              const std::vector<std::string>& comments) {
  TumWriter w(path, comments);
  for (const auto& p : traj) w.add(p);
  w.commit();
}

Trajectory readTum(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error(fmt::format("{}: cannot open TUM file", path));
  Trajectory out;
  std::string line;
  std::size_t line_no = 0;
  std::size_t prev_line = 0;
  while (std::getline(f, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ss(line);
    std::vector<std::string> tok;
    for (std::string s; ss >> s;) tok.push_back(s);
    const auto where = fmt::format("{}:{}", path, line_no);
    if (tok.size() != 8) {
      throw std::runtime_error(
          fmt::format("{}: expected 8 space-separated fields 't x y z qx qy qz qw', got {}: '{}'",
                      where, tok.size(), line));
    }
    static const char* kNames[8] = {"t", "x", "y", "z", "qx", "qy", "qz", "qw"};
    double v[8];
    for (int i = 0; i < 8; ++i) {
      if (!parseDouble(tok[i], v[i]) || !std::isfinite(v[i])) {
        throw std::runtime_error(fmt::format("{}: field {} ({}) '{}' is not a finite number", where,
                                             i + 1, kNames[i], tok[i]));
      }
    }
    const double n = std::sqrt(v[4] * v[4] + v[5] * v[5] + v[6] * v[6] + v[7] * v[7]);
    if (n < 1e-9) throw std::runtime_error(fmt::format("{}: zero quaternion", where));
    const double qx = v[4] / n, qy = v[5] / n, qz = v[6] / n, qw = v[7] / n;
    const double yaw =
        std::atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz));  // ZYX yaw
    if (!out.empty() && !(v[0] > out.back().t_s)) {
      throw std::runtime_error(
          fmt::format("{}: timestamp {} is not after {} (line {}); TUM files must be "
                      "strictly time-ordered",
                      where, tok[0], out.back().t_s, prev_line));
    }
    out.push_back({v[0], v[1], v[2], yaw});
    prev_line = line_no;
  }
  if (f.bad()) throw std::runtime_error(fmt::format("{}: read error", path));
  return out;
}

std::vector<Position2DStamped> readTumGroundTruth(const std::string& path, bool with_heading) {
  return toGroundTruth(readTum(path), with_heading);
}

std::vector<Position2DStamped> toGroundTruth(const Trajectory& traj, bool with_heading) {
  std::vector<Position2DStamped> gt;
  gt.reserve(traj.size());
  for (const auto& p : traj) {
    Position2DStamped g{p.t_s, p.x_m, p.y_m};
    if (with_heading) g.phi_rad = p.phi_rad;
    gt.push_back(g);
  }
  return gt;
}

double pathLength(const Trajectory& traj) {
  double d = 0.0;
  for (std::size_t k = 1; k < traj.size(); ++k) {
    d += std::hypot(traj[k].x_m - traj[k - 1].x_m, traj[k].y_m - traj[k - 1].y_m);
  }
  return d;
}

Eigen::Vector2d bodyPointPosition(const Pose2DStamped& p, const Eigen::Vector2d& l) {
  const double c = std::cos(p.phi_rad), s = std::sin(p.phi_rad);
  return {p.x_m + c * l.x() - s * l.y(), p.y_m + s * l.x() + c * l.y()};
}

Trajectory relativeTo(const Trajectory& traj, const Pose2DStamped& origin) {
  Trajectory out;
  out.reserve(traj.size());
  const double c = std::cos(origin.phi_rad), s = std::sin(origin.phi_rad);
  for (const auto& p : traj) {
    const double dx = p.x_m - origin.x_m, dy = p.y_m - origin.y_m;
    out.push_back({p.t_s, c * dx + s * dy, -s * dx + c * dy,
                   std::remainder(p.phi_rad - origin.phi_rad, 2 * M_PI)});
  }
  return out;
}

Trajectory applyLeverArm(const Trajectory& traj, const Eigen::Vector2d& l) {
  Trajectory out = traj;
  for (auto& p : out) {
    const Eigen::Vector2d q = bodyPointPosition(p, l);
    p.x_m = q.x();
    p.y_m = q.y();
  }
  return out;
}

std::optional<Pose2DStamped> interpolatePose(const Trajectory& traj, double t, double max_gap_s) {
  if (traj.empty() || !(t >= traj.front().t_s) || !(t <= traj.back().t_s)) return std::nullopt;
  // First sample with time > t (exists unless t == back.t).
  auto hi = std::upper_bound(traj.begin(), traj.end(), t,
                             [](double tv, const Pose2DStamped& p) { return tv < p.t_s; });
  auto lo = hi - 1;  // lo->t_s <= t
  if (lo->t_s == t) {
    Pose2DStamped p = *lo;
    p.t_s = t;
    p.phi_rad = model::wrapAngle(p.phi_rad);
    return p;
  }
  if (hi == traj.end()) return std::nullopt;  // unreachable (t <= back.t), kept for safety
  const double dt = hi->t_s - lo->t_s;
  if (dt > max_gap_s) return std::nullopt;
  const double a = (t - lo->t_s) / dt;
  Pose2DStamped p;
  p.t_s = t;
  p.x_m = (1.0 - a) * lo->x_m + a * hi->x_m;
  p.y_m = (1.0 - a) * lo->y_m + a * hi->y_m;
  p.phi_rad = model::wrapAngle(lo->phi_rad + a * model::wrapAngle(hi->phi_rad - lo->phi_rad));
  return p;
}

void checkTimeOrdered(const Trajectory& traj, const std::string& what) {
  for (std::size_t k = 0; k < traj.size(); ++k) {
    if (!std::isfinite(traj[k].t_s)) {
      throw std::invalid_argument(fmt::format("{}: sample {} has a non-finite time", what, k));
    }
    if (k > 0 && !(traj[k].t_s > traj[k - 1].t_s)) {
      throw std::invalid_argument(
          fmt::format("{}: times must be strictly increasing (sample {} at t={} s follows t={} s)",
                      what, k, traj[k].t_s, traj[k - 1].t_s));
    }
  }
}

void checkTimeOrdered(const std::vector<Position2DStamped>& gt, const std::string& what) {
  for (std::size_t k = 0; k < gt.size(); ++k) {
    if (!std::isfinite(gt[k].t_s)) {
      throw std::invalid_argument(fmt::format("{}: sample {} has a non-finite time", what, k));
    }
    if (k > 0 && !(gt[k].t_s > gt[k - 1].t_s)) {
      throw std::invalid_argument(
          fmt::format("{}: times must be strictly increasing (sample {} at t={} s follows t={} s)",
                      what, k, gt[k].t_s, gt[k - 1].t_s));
    }
  }
}

}  // namespace wheelchair::evaluation
