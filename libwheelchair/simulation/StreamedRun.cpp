#include "libwheelchair/simulation/StreamedRun.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/util/OutputDir.h"
#include "libwheelchair/util/ScratchRecords.h"

#include <stdexcept>

namespace wheelchair::simulation {

namespace {

struct FileSink : SimulationSink {
  io::TimeOrderedRawlogWriter rawlog;
  /// Truth samples: in memory up to `in_memory` samples (default 200000, ~30 MB: a drive of
  /// ~35 min at 100 Hz), beyond that in an anonymous temporary file (util::ScratchRecords);
  /// errors name the truth file being produced.
  util::ScratchRecords<TruthSample> truth_samples;
  bool ground_truth;
  FileSink(const std::string& path, const std::string& truth_path, std::size_t in_memory,
           const config::WheelchairConfig& cfg, bool gt)
      : rawlog(path, cfg, expectedStreams(gt)),
        truth_samples(truth_path + ": the truth samples", in_memory),
        ground_truth(gt) {}
  static std::vector<io::StreamKind> expectedStreams(bool gt) {
    using io::StreamKind;
    std::vector<StreamKind> k = {StreamKind::Encoders, StreamKind::Imu,   StreamKind::Motors,
                                 StreamKind::Sonar,    StreamKind::Pozyx, StreamKind::Joystick};
    if (gt) k.push_back(StreamKind::GroundTruth);
    return k;
  }
  void meta(const std::map<std::string, std::string>& m) override { rawlog.setMeta(m); }
  void sample(const io::AnySample& s) override { rawlog.add(s); }
  void truth(const TruthSample& s) override {
    truth_samples.add(s);
    if (ground_truth) rawlog.add(io::GroundTruthPoseSample{s.t_s, s.x_m, s.y_m, s.phi_rad});
  }
};

}  // namespace

StreamedSimulation simulateToFiles(const config::WheelchairConfig& cfg, const std::string& scenario,
                                   uint64_t seed, double duration_s,
                                   const std::vector<effects::EffectSpec>& effects,
                                   const SimulationOptions& options, const std::string& rawlog,
                                   const std::string& truth_path, std::size_t truth_in_memory) {
  StreamedSimulation out;
  util::RemoveUnlessKept outputs;  // a failed truth file removes the recording again
  {
    FileSink sink(rawlog, truth_path, truth_in_memory, cfg, options.record_ground_truth);
    SimulationOptions opt = options;
    opt.sink = &sink;
    out.result = simulate(cfg, scenario, seed, duration_s, effects, opt);
    out.counts = sink.rawlog.counts();
    try {
      sink.rawlog.commit();
    } catch (const io::TimeOrderedRawlogWriter::HeaderTimeMismatch&) {
      // The header time writeRawlog would write is not known before the end: repeat the
      // (deterministic) run in memory.
      SimulationResult res = simulate(cfg, scenario, seed, duration_s, effects, options);
      io::writeRawlog(res.recording, rawlog, cfg);
      outputs.add(rawlog);
      res.writeTruth(truth_path);
      outputs.keep();
      res.recording = io::Recording{};
      out.result = std::move(res);
      return out;
    }
    outputs.add(rawlog);
    out.result.writeTruth(truth_path, [&](const std::function<void(const TruthSample&)>& f) {
      sink.truth_samples.replay(0, sink.truth_samples.size(), f);
    });
  }
  outputs.keep();
  return out;
}

}  // namespace wheelchair::simulation
