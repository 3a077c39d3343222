// The raw variants of the paper's Fig. 5: dead reckoning without a filter.
//
//   deadReckoningEncoders     v and omega from each encoder interval (mean speeds), the pose
//                             integrated exactly over the interval with the arc formula
//                             (model::integratePoseArc): for constant (v, omega) the mean
//                             speeds ARE the true increments, so this is the exact odometry.
//   deadReckoningEncoderGyro  v from the encoders, omega from the gyro (linearly interpolated
//                             between its samples); the pose is integrated over every
//                             sub-interval between consecutive encoder/gyro times with the arc
//                             formula and the mean omega of the sub-interval (trapezoid), so
//                             phi is the exact integral of the interpolated gyro.
// Both start at the origin of the start frame at the first encoder sample.
//
// Example:
//   auto dr = deadReckoningEncoders(rec.encoders, cfg.encoders.params, cfg.vehicle.geom);
//   auto eg = deadReckoningEncoderGyro(rec.encoders, rec.imu, cfg.encoders.params,
//   cfg.vehicle.geom);
#pragma once

#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/model/VehicleParams.h"
#include "libwheelchair/sensors/Encoders.h"

#include <functional>
#include <string>
#include <vector>

namespace wheelchair::estimation {

struct DeadReckoningSample {
  double t_s = 0;
  double x_m = 0, y_m = 0, phi_rad = 0;  ///< start frame; phi unwrapped (continuous)
  double v_m_s = 0, omega_rad_s = 0;     ///< speeds used over the interval ending at t_s
};

/// Odometry only. Samples need not be sorted (they are sorted by time here).
std::vector<DeadReckoningSample> deadReckoningEncoders(const std::vector<io::EncoderSample>& enc,
                                                       const sensors::EncoderParams& p,
                                                       const model::Geometry& g);

/// Encoder v + gyro omega. Gyro samples outside the encoder time span are ignored; between the
/// first encoder sample and the first gyro sample the first gyro value is held.
std::vector<DeadReckoningSample> deadReckoningEncoderGyro(const std::vector<io::EncoderSample>& enc,
                                                          const std::vector<io::ImuSample>& imu,
                                                          const sensors::EncoderParams& p,
                                                          const model::Geometry& g);

/// What deadReckonRawlog produced: samples and the path length (pathLength of them).
struct DeadReckoningRun {
  std::size_t samples = 0;
  double path_m = 0;
};

/// deadReckoningEncoders (with_gyro false) or deadReckoningEncoderGyro (true) over a rawlog
/// read as a stream (io/RawlogStream.h; `summary` from io::scanRawlog): each sample goes to `f`
/// as it is produced, bit-identical to the vector functions on io::readRawlog(rawlog), and
/// memory does not grow with the drive. Example:
///   auto run = deadReckonRawlog("d.rawlog", sum, true, enc, geom, [&](auto& s) { tum.add(...); });
DeadReckoningRun deadReckonRawlog(const std::string& rawlog, const io::RecordingSummary& summary,
                                  bool with_gyro, const sensors::EncoderParams& p,
                                  const model::Geometry& g,
                                  const std::function<void(const DeadReckoningSample&)>& f);

/// Length of the travelled path (sum of the distances between consecutive positions), the
/// paper's d_path.
double pathLength(const std::vector<DeadReckoningSample>& traj);

}  // namespace wheelchair::estimation
