#include "libwheelchair/simulation/StreamedRun.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/util/OutputDir.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

namespace wheelchair::simulation {

namespace {

/// Truth samples in an anonymous temporary file (std::tmpfile: gone when closed, even after
/// a crash), every write and read checked.
class TruthScratch {
 public:
  TruthScratch() : f_(std::tmpfile(), &std::fclose) {
    if (!f_) fail("cannot create");
  }
  void add(const TruthSample& s) {
    if (std::fwrite(&s, sizeof s, 1, f_.get()) != 1) fail("cannot write");
  }
  /// Calls f for every sample in order.
  void replay(const std::function<void(const TruthSample&)>& f) {
    if (std::fflush(f_.get()) != 0) fail("cannot write");
    std::rewind(f_.get());
    std::vector<TruthSample> chunk(4096);
    for (;;) {
      const std::size_t n = std::fread(chunk.data(), sizeof(TruthSample), chunk.size(), f_.get());
      for (std::size_t i = 0; i < n; ++i) f(chunk[i]);
      if (n < chunk.size()) break;
    }
    if (std::ferror(f_.get())) fail("cannot read");
    std::fseek(f_.get(), 0, SEEK_END);
  }

 private:
  [[noreturn]] static void fail(const char* what) {
    throw std::runtime_error(std::string("truth scratch file (temporary directory): ") + what +
                             ": " + std::strerror(errno));
  }
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f_;
};

struct FileSink : SimulationSink {
  io::TimeOrderedRawlogWriter rawlog;
  TruthScratch truth_samples;
  bool ground_truth;
  FileSink(const std::string& path, const config::WheelchairConfig& cfg, bool gt)
      : rawlog(path, cfg, expectedStreams(gt)), ground_truth(gt) {}
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

StreamedSimulation simulateToFiles(const config::WheelchairConfig& cfg,
                                   const std::string& scenario, uint64_t seed, double duration_s,
                                   const std::vector<EffectSpec>& effects,
                                   const SimulationOptions& options, const std::string& rawlog,
                                   const std::string& truth_path) {
  StreamedSimulation out;
  util::RemoveUnlessKept outputs;  // a failed truth file removes the recording again
  {
    FileSink sink(rawlog, cfg, options.record_ground_truth);
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
      sink.truth_samples.replay(f);
    });
  }
  outputs.keep();
  return out;
}

}  // namespace wheelchair::simulation
