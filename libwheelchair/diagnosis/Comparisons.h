// What `diagnose` could and could not test on the recordings it was given (issue 16 item 1:
// "any sensor is a reference for the others; no stage silently disappears because one sensor
// is missing"). Every comparison the tool implements, with the streams it needs:
//
//   gyro vs encoders              stage 1 (kinematic consistency)     IMU + ENCODERS
//   dynamics vs motor currents    stage 2 (dynamics)                  MOTORS + ENCODERS
//   encoders vs ground truth      kinematic calibration               ENCODERS + GROUND_TRUTH
//   commands vs motion            command-response analyser           JOYSTICK + GROUND_TRUTH,
//                                                                     no MOTORS (with currents
//                                                                     the commands act through
//                                                                     the dynamics of stage 2)
//   Pozyx vs odometry             sensor faults (Pozyx outliers)      POZYX + ENCODERS
//   sonar readings                sensor faults (sonar dropouts)      SONAR
//
// addComparisons() writes rep.info["comparisons"] = [{"comparison", "tested": bool, "why"}]
// ("why": what was missing, or why the stage could not run, when not tested) from the streams
// of the recordings and what the stages wrote into rep.info (kinematic_calibration.tested,
// skipped.stage1 / stage2, analyser, sensor_faults). When NONE could be made, it also adds to
// rep.info["insufficient_data"] "no comparison could be made ...": "no mismatch" would
// otherwise read as a confident clean bill (item 5: honest when it cannot tell).
//
// Example:
//   const SensorStreams s = sensorStreams(fit);   // before the recordings are released
//   ... rep = diagnose(...); addCommandResponseFindings(...); ...
//   addComparisons(s, rep);
//   // rep.info["comparisons"][0] = {"comparison": "gyro vs encoders", "tested": false,
//   //   "why": "no gyro stream (IMU)"}
#pragma once

#include "libwheelchair/diagnosis/Finding.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/io/Recording.h"

#include <string>
#include <vector>

namespace wheelchair::diagnosis {

/// Which streams any of the recordings carries (a stream counts when it has a sample).
struct SensorStreams {
  bool encoders = false, gyro = false, motors = false, ground_truth = false, commands = false,
       pozyx = false, sonar = false;
};

SensorStreams sensorStreams(const std::vector<io::Recording>& recs);
/// The same from the recordings' scans (io::scanRawlog: their counts per stream).
SensorStreams sensorStreams(const std::vector<io::RecordingSummary>& sums);

/// rep.info["comparisons"] (and "insufficient_data" when nothing was compared); see header.
void addComparisons(const SensorStreams& s, DiagnosisReport& rep);

/// One line per comparison: "tested: a; b" and "not tested: c (why)"; empty without
/// rep.info["comparisons"].
std::string comparisonsText(const DiagnosisReport& rep);

}  // namespace wheelchair::diagnosis
