// `wheelchair simulate -o OUT.rawlog` without holding the drive in memory: the samples go to
// the rawlog as they are produced (io::TimeOrderedRawlogWriter: the time-ordered merge holds
// back only what it cannot decide yet), the truth samples (beyond ~30 MB) to an anonymous
// scratch file from which the truth file's columns are written at the end. The files are
// byte-identical to simulate() + io::writeRawlog + SimulationResult::writeTruth (rare case: a
// stream whose first sample is not its earliest; the run is then repeated in memory to write the
// header time writeRawlog writes). Both outputs are atomic: on any failure neither is left (nor a
// temporary). Memory does not grow with the drive (docs/benchmarks.md, "Memory").
//
// Example:
//   auto run = simulateToFiles(cfg, "excite", 1, 36000, {}, opt, "d.rawlog",
//   "d.rawlog.truth.json"); run.counts[int(io::StreamKind::Imu)];   // samples written per stream
#pragma once

#include "libwheelchair/io/Samples.h"
#include "libwheelchair/simulation/Simulator.h"

#include <array>
#include <string>
#include <vector>

namespace wheelchair::simulation {

struct StreamedSimulation {
  SimulationResult result;  ///< recording empty; truth.samples holds the last sample only
  std::array<std::size_t, io::kNumStreams> counts{};  ///< samples written per stream
};

StreamedSimulation simulateToFiles(const config::WheelchairConfig& cfg, const std::string& scenario,
                                   uint64_t seed, double duration_s,
                                   const std::vector<effects::EffectSpec>& effects,
                                   const SimulationOptions& options, const std::string& rawlog,
                                   const std::string& truth_path,
                                   std::size_t truth_in_memory = 200000);

}  // namespace wheelchair::simulation
