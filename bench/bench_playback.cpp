// Throughput of playback + filtering against merely decoding the same rawlog (issue 4).
//
// A long recording of the reference sensor suite (encoders 50 Hz, gyro 100 Hz, motors 100 Hz,
// sonar 10 Hz, Pozyx 10 Hz, joystick 50 Hz: ~320 measurements per recorded second) is
// simulated once (`excite` scenario), written as a rawlog, then:
//   BM_DecodeRawlog        read + deserialize every record into an io::Recording
//   BM_FilterPhysics       the CVODE-integrated continuous-discrete EKF over the recording
//   BM_FilterBaseline      the kinematic baseline EKF
//   BM_DecodeAndFilter     both, as `wheelchair filter` does
// Counters: measurements per second and the multiple of real time, per core.
//
// Run:   build/bench/bench_playback                      (600 s recording)
//        WHEELCHAIR_BENCH_DURATION_S=30 build/bench/bench_playback   (quick)
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/simulation/Simulator.h"

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>

using namespace wheelchair;

namespace {

struct Fixture {
  config::WheelchairConfig cfg;
  io::Recording rec;
  std::string path;
  double duration_s = 0;
  std::size_t measurements = 0;

  Fixture() {
    // WHEELCHAIR_BENCH_CONFIG: another configuration (e.g. other CVODE tolerances).
    const char* cfg_env = std::getenv("WHEELCHAIR_BENCH_CONFIG");
    cfg = config::WheelchairConfig::load(
        cfg_env ? std::string(cfg_env)
                : std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini");
    const char* env = std::getenv("WHEELCHAIR_BENCH_DURATION_S");
    const double duration = env ? std::atof(env) : 600.0;
    simulation::SimulationOptions so;
    so.loadFromConfig(cfg.ini());
    rec = simulation::simulate(cfg, "excite", 7, duration, {}, so).recording;
    duration_s = rec.endTime() - rec.startTime();
    measurements = rec.size();
    path = (std::filesystem::temp_directory_path() / "wheelchair_bench_playback.rawlog").string();
    io::writeRawlog(rec, path, cfg);
  }
  ~Fixture() { std::filesystem::remove(path); }
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

void setCounters(benchmark::State& state, const Fixture& f) {
  const double n = static_cast<double>(state.iterations());
  state.counters["measurements_per_s"] =
      benchmark::Counter(n * f.measurements, benchmark::Counter::kIsRate);
  state.counters["x_real_time"] = benchmark::Counter(n * f.duration_s, benchmark::Counter::kIsRate);
}

estimation::EkfOptions options(const Fixture& f, estimation::FilterKind kind) {
  estimation::EkfOptions opt;
  opt.loadFromConfig(f.cfg.ini());
  opt.resolveSensorDefaults(f.cfg);
  opt.filter = kind;
  return opt;
}

void BM_DecodeRawlog(benchmark::State& state) {
  auto& f = fixture();
  for (auto _ : state) benchmark::DoNotOptimize(io::readRawlog(f.path));
  setCounters(state, f);
}

void BM_FilterPhysics(benchmark::State& state) {
  auto& f = fixture();
  const auto opt = options(f, estimation::FilterKind::Physics);
  for (auto _ : state) benchmark::DoNotOptimize(estimation::runEstimator(f.rec, f.cfg, opt));
  setCounters(state, f);
}

void BM_FilterBaseline(benchmark::State& state) {
  auto& f = fixture();
  const auto opt = options(f, estimation::FilterKind::Baseline);
  for (auto _ : state) benchmark::DoNotOptimize(estimation::runEstimator(f.rec, f.cfg, opt));
  setCounters(state, f);
}

void BM_DecodeAndFilter(benchmark::State& state) {
  auto& f = fixture();
  const auto opt = options(f, estimation::FilterKind::Physics);
  for (auto _ : state)
    benchmark::DoNotOptimize(estimation::runEstimator(io::readRawlog(f.path), f.cfg, opt));
  setCounters(state, f);
}

}  // namespace

BENCHMARK(BM_DecodeRawlog)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FilterPhysics)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FilterBaseline)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DecodeAndFilter)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_MAIN();
