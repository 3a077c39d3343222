// Trajectory types for evaluation, TUM file I/O, interpolation, lever arm, path length.
// Definitions and formulas: docs/evaluation.md.
//
// Frames: planar world frame of the ground truth (x, y in m, phi in rad, counter-clockwise),
// body frame x forward, y left. A pose (x, y, phi) maps a body point l to x + R(phi) l.
//
// TUM format (one pose per line, '#' starts a comment line):
//   t x y z qx qy qz qw
// written here with z = 0 and a yaw-only quaternion (qz = sin(phi/2), qw = cos(phi/2)); read
// back by projecting onto the xy plane (yaw of the normalised quaternion, z ignored) like
// `evo ... --project_to_plane xy`.
// Example:
//   Trajectory est = readTum("est.tum");
//   double d = pathLength(est);
#pragma once

#include <cstddef>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace wheelchair::evaluation {

/// One estimated (or ground-truth) planar pose at time t_s.
struct Pose2DStamped {
  double t_s;
  double x_m, y_m, phi_rad;
};
/// Time-ordered (strictly increasing t_s).
using Trajectory = std::vector<Pose2DStamped>;

/// Ground-truth sample: position of the tracked point (Pozyx tag / Vicon object origin) and,
/// when the ground truth measures it (Vicon), the body heading. NaN heading = not measured.
struct Position2DStamped {
  double t_s;
  double x_m, y_m;
  double phi_rad = std::numeric_limits<double>::quiet_NaN();
  bool hasHeading() const { return phi_rad == phi_rad; }
};

/// Streaming TUM writer (the one TUM writer of the project): poses go to the file as they
/// come, through util::AtomicFile (complete at `path` after commit(), else absent). Lines:
/// optional `# COMMENT` lines, the column header, then `t x y 0 0 0 qz qw` with every number in
/// the shortest form that reads back to the same double. Poses must come in non-decreasing
/// time; of equal timestamps the last one is written (as toTrajectory keeps it). Throws
/// std::runtime_error naming the file on an I/O failure or a pose earlier than the previous.
/// Example:
///   TumWriter tum("out/ekf.tum", {"frame: start"});
///   for (const auto& p : poses) tum.add(p);
///   tum.commit();
class TumWriter {
 public:
  explicit TumWriter(const std::string& path, const std::vector<std::string>& comments = {});
  ~TumWriter();
  TumWriter(const TumWriter&) = delete;
  TumWriter& operator=(const TumWriter&) = delete;
  void add(const Pose2DStamped& p);
  void commit();
  std::size_t poses() const { return poses_; }  ///< poses written or pending

 private:
  void flushPending();
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::optional<Pose2DStamped> pending_;
  std::size_t poses_ = 0;
};

/// Writes `traj` as TUM to `path` (TumWriter: atomic, shortest round-trip numbers). Throws
/// std::runtime_error naming the file on I/O failure.
void writeTum(const std::string& path, const Trajectory& traj,
              const std::vector<std::string>& comments = {});
/// Reads a TUM file. Throws std::runtime_error "<path>:<line>: <what>" on a malformed line
/// (field count, non-numeric or non-finite field, zero quaternion, non-increasing time).
Trajectory readTum(const std::string& path);
/// Reads a TUM file as ground truth; the heading is kept when `with_heading`, else NaN
/// (use false for position-only sources exported with a dummy quaternion).
std::vector<Position2DStamped> readTumGroundTruth(const std::string& path, bool with_heading);

/// Poses -> ground truth samples (heading kept when `with_heading`).
std::vector<Position2DStamped> toGroundTruth(const Trajectory& traj, bool with_heading);

/// Sum of the Euclidean distances between consecutive positions, m.
double pathLength(const Trajectory& traj);

/// Position of the body point `lever_arm_m` (body frame) for a pose: x + R(phi) l.
Eigen::Vector2d bodyPointPosition(const Pose2DStamped& pose, const Eigen::Vector2d& lever_arm_m);
/// The same trajectory with the position moved to the body point `lever_arm_m` (heading kept).
Trajectory applyLeverArm(const Trajectory& traj, const Eigen::Vector2d& lever_arm_m);

/// The poses re-expressed in the frame of the pose `origin` (T_origin^-1 T; headings wrapped to
/// [-pi, pi]). Example: relativeTo(traj, traj.front()) starts at (0, 0, 0).
Trajectory relativeTo(const Trajectory& traj, const Pose2DStamped& origin);

/// Linear interpolation of the pose at t_s (angle along the shorter arc, result in (-pi, pi]).
/// Empty when t_s is outside [front.t, back.t] or the bracketing samples are more than
/// `max_gap_s` apart (a sample exactly at t_s is always returned).
std::optional<Pose2DStamped> interpolatePose(const Trajectory& traj, double t_s, double max_gap_s);

/// Throws std::invalid_argument(`what` + reason) unless times are finite and strictly increasing.
void checkTimeOrdered(const Trajectory& traj, const std::string& what);
void checkTimeOrdered(const std::vector<Position2DStamped>& gt, const std::string& what);

}  // namespace wheelchair::evaluation
