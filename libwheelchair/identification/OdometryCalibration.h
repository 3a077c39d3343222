// Odometry (kinematic) calibration of a differential drive from wheel encoders and
// ground-truth poses (motion capture): the anchors of docs/discovery.md ("Real robot without a
// gyro: OptiOdom") and the fitting engine of diagnosis/KinematicCalibration.h.
//
// Model (body frame x forward, y left; index 0 / right, 1 / left; vehicle.md): per encoder
// interval the wheels roll d_R = k_R dN_R and d_L = k_L dN_L (m; k = m per tick = 2 pi r /
// ticks per wheel turn), the body turns dphi = (d_R - d_L) / b (rad; b = track, m) and
// travels ds = (d_R + d_L) / 2 along the arc: the chord ds sinc(dphi/2) along the mid-interval
// heading (model::integratePoseArc; the heading is kept unwrapped). Dead reckoning starts at
// the ground-truth pose of the first sample ("start aligned").
//
// Calibrations (all return absolute k_R, k_L, b):
//   umbmark            Borenstein & Feng 1996: from the mean return-position errors
//                      eps = truth - odometry (start frame, x along the initial heading) of
//                      clockwise and counter-clockwise squares of side L:
//                      alpha = (x_cw + x_ccw) / (-4 L), beta = (x_cw - x_ccw) / (-4 L),
//                      R = (L/2) / sin(beta/2), E_d = D_R/D_L = (R + b/2) / (R - b/2),
//                      E_b = (pi/2) / (pi/2 - alpha); mean diameter kept, b *= E_b.
//   leastSquares       two-step linear least squares over segments of `segment_s`
//                      (Antonelli, Chiaverini, Fusco, IEEE T-RO 21(5), 2005): the heading
//                      change dphi_gt = c_R dN_R - c_L dN_L gives c = k / b; then, with k = b c,
//                      the displacement dx_gt = b sum (c_R n_R + c_L n_L)/2 cos(phi_gt) (dy_gt
//                      likewise with sin) is linear in b alone.
//   trajectory         Levenberg-Marquardt (stats::levenbergMarquardt) on the dead-reckoned
//                      position error itself over whole runs (the quantity the held-out metric
//                      measures), for any subset of the relative corrections (k_R, k_L, b) =
//                      nominal * (1 + delta), optionally the lever arm and the travel angle
//                      (OdometryGeometry::travel_angle_rad, absolute).
//
// Example:
//   auto run = odometryRun(io::importOptiodom("square/230620202042", 1));
//   OdometryGeometry nom = odometryGeometry(cfg);
//   OdometryGeometry ls = leastSquaresCalibration({run}, 1.0);
//   OdometryError e = meanOdometryError({run}, ls);   // e.mean_position_m
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Recording.h"

#include <array>
#include <string>
#include <vector>

namespace wheelchair::identification {

/// Odometric geometry: metres of rim travel per tick (right, left) and the track (m); the
/// lever arm is where the ground-truth point sits in the body frame relative to the axle
/// midpoint (m; x forward, y left): dead reckoning predicts that point. `travel_angle_rad` is
/// the direction in which the body travels relative to the heading the ground truth measures
/// (rad, + = to the left): each interval's chord is laid along heading + travel_angle. It is
/// what a motion-capture rigid body whose yaw is rotated off the axle's normal looks like, and
/// also what an axle that is not square to the body (toe, crab) looks like: from encoders and
/// ground-truth poses the two are the same model (both rotate the dead-reckoned path about its
/// start by the angle).
struct OdometryGeometry {
  double m_per_tick_right = 0, m_per_tick_left = 0, track_m = 0;
  double lever_x_m = 0, lever_y_m = 0;
  double travel_angle_rad = 0;
};

/// From the configuration: k = odometryRadius(side) * wheel angle per tick; b = track_width_m;
/// travel angle = [vehicle] odometry_travel_angle_rad.
OdometryGeometry odometryGeometry(const config::WheelchairConfig& cfg);
/// Writes k_R, k_L, b back as [vehicle] wheel_radius_right_m / wheel_radius_left_m (and
/// wheel_radius_m = their mean), track_width_m and odometry_travel_angle_rad.
void applyOdometryGeometry(const OdometryGeometry& g, config::WheelchairConfig& cfg);

/// One run: cumulative ticks and the ground-truth pose interpolated at each encoder time
/// (heading unwrapped); only encoder samples inside the ground truth's time span.
struct OdometryRun {
  std::string name;
  std::vector<double> t_s, ticks_right, ticks_left, x_m, y_m, phi_rad;
  std::size_t size() const { return t_s.size(); }
};
OdometryRun odometryRun(const io::Recording& rec, const std::string& name = {});
/// The samples with t in [t0_s, t1_s].
OdometryRun cropRun(const OdometryRun& run, double t0_s, double t1_s);

struct Pose2 {
  double x_m = 0, y_m = 0, phi_rad = 0;
};
/// Dead reckoning started at the run's first ground-truth pose, one pose per sample: the pose
/// of the ground-truth point (axle midpoint + R(phi) lever arm).
std::vector<Pose2> deadReckon(const OdometryRun& run, const OdometryGeometry& g);

/// Dead-reckoning error against the ground truth (start aligned): position at the last sample,
/// time-mean position error over the run, |heading error| at the last sample.
struct OdometryError {
  double end_position_m = 0, mean_position_m = 0, end_heading_rad = 0;
  int runs = 0;
};
OdometryError odometryError(const OdometryRun& run, const OdometryGeometry& g);
/// Average of the per-run errors.
OdometryError meanOdometryError(const std::vector<OdometryRun>& runs, const OdometryGeometry& g);

struct UmbmarkResult {
  double x_cw_m = 0, y_cw_m = 0, x_ccw_m = 0, y_ccw_m = 0;  ///< mean return errors
  int n_cw = 0, n_ccw = 0;
  double alpha_rad = 0, beta_rad = 0, E_d = 1, E_b = 1;
  OdometryGeometry corrected;
};
/// UMBmark from square runs driven with `nominal` (the geometry the robot's path follower
/// used). A run's direction is the sign of its total ground-truth turn. Throws
/// std::invalid_argument without at least one run in each direction.
UmbmarkResult umbmark(const std::vector<OdometryRun>& squares, double side_m,
                      const OdometryGeometry& nominal);

/// Two-step linear least squares (see the header comment); `segment_s` > 0.
OdometryGeometry leastSquaresCalibration(const std::vector<OdometryRun>& runs, double segment_s);

/// Time offset d (s) of the encoder stamps relative to the ground truth (d > 0: the encoders
/// trail), from the heading increments: argmin over d in [-max_s, max_s] (steps of step_s) of
/// sum_i (phi_gt(t_i) - phi_gt(t_{i-1}) - s (th_odo(t_i + d) - th_odo(t_{i-1} + d)))^2 with
/// th_odo the cumulative odometric heading (k_R N_R - k_L N_L) / b, linearly interpolated, and
/// the scale s fitted for each d. The odometry is the one re-sampled: interpolating the noisy
/// truth between samples would average its noise and favour half-sample shifts. Timing is a nuisance of the fit: the geometry fitted on runs whose truth
/// is re-sampled at t - d (shiftTruth) is not biased by the lag during fast turns.
double estimateTimeOffset(const OdometryRun& run, const OdometryGeometry& g, double max_s = 0.25,
                          double step_s = 0.005);
/// The run with its ground truth re-sampled at t_i - d_s (linear interpolation, clamped).
OdometryRun shiftTruth(const OdometryRun& run, double d_s);

/// Which relative corrections trajectoryCalibration may change: (k_R, k_L, b). `common_scale`
/// ties k_R and k_L to one factor.
struct TrajectoryFit {
  std::array<bool, 3> free{true, true, true};
  bool common_scale = false;
  /// Scale k_R, k_L and b by one factor (keeps the heading rates c = k / b); use with
  /// free = {false, false, false}.
  bool uniform_scale = false;
  bool lever_arm = false;     ///< also fit the ground-truth point's lever arm (absolute, m)
  bool travel_angle = false;  ///< also fit OdometryGeometry::travel_angle_rad (absolute, rad)
  int max_iterations = 30;
  /// The heading error enters the cost as heading_weight_m x error (rad -> m); 0 = position only.
  double heading_weight_m = 0;
};
/// Least-squares fit of the dead-reckoned positions to the ground truth, all runs together.
/// `rms_m` (optional) receives the final RMS of the residuals (m).
OdometryGeometry trajectoryCalibration(const std::vector<OdometryRun>& runs,
                                       const OdometryGeometry& start, const TrajectoryFit& fit,
                                       double* rms_m = nullptr);

}  // namespace wheelchair::identification
