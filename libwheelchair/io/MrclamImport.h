// Import of the UTIAS MRCLAM datasets (Leung, Halpern, Barfoot, Liu, IJRR 30(8), 2011):
// real recordings of small differential-drive robots with Vicon ground truth.
//
//   RobotN_Odometry.dat     t, v, omega       -> JOYSTICK (the COMMANDED velocities)
//   RobotN_Groundtruth.dat  t, x, y, phi      -> GROUND_TRUTH (CObservationRobotPose)
//   RobotN_Measurement.dat  t, barcode, r, b  -> LANDMARKS (CObservationBearingRange), the
//                                                barcode mapped to its subject # (Barcodes.dat)
//   Landmark_Groundtruth.dat                  -> meta keys `landmark.<subject> = x y sx sy`
//
// Quirks of the real files, handled deliberately (docs/real-data.md):
//  - duplicated timestamps, some with conflicting values: every row is kept in file order
//    (lossless); consumers take the LAST row of equal timestamps as the value in effect.
//    Their number is reported.
//  - logging gaps (odometry up to ~1.4 s): kept as gaps; the largest is reported.
//  - ground truth that ends before the commands (Robot1): both spans are reported.
//  - isolated one-line (0,0) commands: kept; the command-driven model can skip them
//    (estimation option), their count is reported.
//  - sightings of other robots (subjects 1-5) are kept with their subject id; only
//    subjects with a ground-truth position (landmarks) are used as map features.
#pragma once

#include "libwheelchair/io/Recording.h"

#include <string>

namespace wheelchair::io {

struct MrclamImportReport {
  std::size_t commands = 0, ground_truth = 0, sightings = 0, landmark_sightings = 0;
  std::size_t duplicate_command_times = 0, conflicting_duplicate_commands = 0;
  std::size_t isolated_zero_commands = 0;
  std::size_t unknown_barcodes = 0;
  double largest_command_gap_s = 0, largest_command_gap_at_s = 0;
  double largest_ground_truth_gap_s = 0;
  double commands_start_s = 0, commands_end_s = 0;
  double ground_truth_start_s = 0, ground_truth_end_s = 0;
  std::string summary() const;
};

/// Reads robot `robot` (1-5) of the dataset in `dir`. Throws with file:line on bad rows.
Recording importMrclam(const std::string& dir, int robot, MrclamImportReport* report = nullptr);

/// Landmark map stored in a recording's meta keys: subject -> (x, y, sx, sy) in m.
struct LandmarkPosition {
  int id = 0;
  double x_m = 0, y_m = 0, sx_m = 0, sy_m = 0;
};
std::vector<LandmarkPosition> landmarkMap(const Recording& rec);

}  // namespace wheelchair::io
