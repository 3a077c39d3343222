// The recordings of `wheelchair diagnose` read from rawlogs as a stream (memory, issue 13;
// docs/benchmarks.md, "Memory"): instead of whole io::Recordings, whose IMU and motor samples
// are the bulk of a long drive (64 and 40 B a sample, of which the diagnosis reads 16 and 24),
// each rawlog is read once more after its scan (io::scanRawlogSalvaging, which applies the
// salvage rule and counts the samples, so every vector is sized once) with the same sample
// reader `filter`, `identify` and `report` stream with (io::RawlogSampleReader):
//
//   IMU, MOTORS        -> columns (t, gyro z) and (t, i_R, i_L), which become the recording's
//                         Streams (makeStreams(rec, StreamColumns&&, cfg): sample for sample
//                         the streams makeStreams(readRawlog(path), cfg) gives)
//   JOYSTICK           -> not kept (the command-response analyser, which reads it, runs on
//                         recordings without motor currents, which the CLI loads whole)
//   every other stream -> the io::Recording, as io::readRawlog stores it (the kinematic
//                         calibration, the sensor-fault checks and the trajectory check read
//                         the encoders, ground truth, Pozyx and sonar)
//
// diagnose(DiagnosisInput&&, ...) then gives the report diagnose(std::vector<io::Recording>&&)
// gives on the loaded recordings, bit for bit (tests/diagnosis/test_diagnose_streamed.cpp).
//
// Example:
//   std::string warning;
//   const auto sum = io::scanRawlogSalvaging("d.rawlog", salvage, &warning);
//   DiagnosisInput fit;
//   readForDiagnosis("d.rawlog", sum, cfg, fit);
//   DiagnosisReport rep = diagnose(std::move(fit), {}, cfg, opt);
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/diagnosis/Stages.h"
#include "libwheelchair/io/RawlogStream.h"

#include <string>
#include <vector>

namespace wheelchair::diagnosis {

/// Recordings as diagnose() reads them: `recs[i]` without its IMU, motor and joystick samples,
/// `streams[i]` = the streams of the whole recording i (makeStreams).
struct DiagnosisInput {
  std::vector<io::Recording> recs;
  std::vector<Streams> streams;
};

/// Reads the rawlog at `path` as a stream and appends it to `in` (see the header comment).
/// `sum`: its io::scanRawlog / scanRawlogSalvaging (counts and span; the salvage rule is that
/// call's: the read stops where the scan stopped). Throws like io::RawlogSampleReader.
void readForDiagnosis(const std::string& path, const io::RecordingSummary& sum,
                      const config::WheelchairConfig& cfg, DiagnosisInput& in);

/// diagnose() on recordings read by readForDiagnosis (the CLI); `val` empty: the held-out
/// last part of each fit recording. The same report as diagnose() on the loaded recordings.
DiagnosisReport diagnose(DiagnosisInput&& fit, DiagnosisInput&& val,
                         const config::WheelchairConfig& cfg, const DiagnosisOptions& opt);

}  // namespace wheelchair::diagnosis
