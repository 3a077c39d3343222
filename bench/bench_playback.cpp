// Throughput of playback + filtering against merely decoding the same rawlog (issue 4).
//
// A long recording of the reference sensor suite (encoders 50 Hz, gyro 100 Hz, motors 100 Hz,
// sonar 10 Hz, Pozyx 10 Hz, joystick 50 Hz: ~320 measurements per recorded second) is
// simulated once (`excite` scenario), written as a rawlog, then:
//   BM_DecodeRawlog        read + deserialize every record into an io::Recording
//   BM_FilterPhysics       the CVODE-integrated continuous-discrete EKF over the recording
//   BM_FilterBaseline      the kinematic baseline EKF
//   BM_DecodeAndFilter     both, as `wheelchair filter` does
// and the stages of `wheelchair filter D.rawlog [--estimates E.csv]` as the command runs them
// (docs/benchmarks.md, "Third round"):
//   BM_ScanRawlog          io::scanRawlog (counts, lateness, break), decode only: the pass
//                          `filter` makes first only when the file is not time-ordered
//   BM_StreamMerge         the streamed read without the filter: decode + window merge
//   BM_FilterStatesOn      BM_FilterPhysics with the sensor-error states (k_R, k_L, b_g)
//   BM_WriteEstimatesCsv   the estimates CSV of the run (EstimatesCsvWriter), write only
//   BM_FormatRowsFmt       the CSV rows formatted in memory as up to the fourth round (fmt,
//                          compiled "{:.6f},{},...": the reference for the next one)
//   BM_FormatRows          the CSV rows formatted in memory as the writer does now
//                          (estimation::writeEstimateRow: util/NumberFormat.h)
//   BM_ShortestFmt / BM_Shortest   one number of a row, fmt's "{}" / util::writeShortest
//   BM_EndToEnd            the file read once (runEstimatorOnePass: streamed filter, summary
//                          made while reading) + CSV written and committed, states off
//   BM_EndToEndStatesOn    the same with the sensor-error states
//   BM_EndToEndNoOutput    the file read once + streamed filter, no output file
//   BM_EndToEndTwoPass     scan + streamed filter, no output (before issue 17's last round,
//                          and still the path for files out of time order)
// Counters: measurements per second and the multiple of real time, per core.
//
// Run:   build/bench/bench_playback                      (600 s recording)
//        WHEELCHAIR_BENCH_DURATION_S=30 build/bench/bench_playback   (quick)
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/estimation/EstimateWriters.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/simulation/Simulator.h"

#include "libwheelchair/util/NumberFormat.h"

#include <benchmark/benchmark.h>
#include <fmt/compile.h>
#include <fmt/format.h>

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <vector>

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
    cfg = config::WheelchairConfig::load(cfg_env ? std::string(cfg_env)
                                                 : std::string(WHEELCHAIR_SOURCE_DIR) +
                                                       "/config/wheelchair.ini");
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

estimation::EkfOptions options(const Fixture& f, estimation::FilterKind kind,
                               bool sensor_error_states = false) {
  estimation::EkfOptions opt;
  opt.loadFromConfig(f.cfg.ini());
  opt.resolveSensorDefaults(f.cfg);
  opt.filter = kind;
  if (sensor_error_states) {
    opt.estimate_encoder_scales = true;
    opt.estimate_gyro_bias = true;
  }
  return opt;
}

/// Counts the estimates (the sink of a run without output files).
struct CountingSink : estimation::EstimateSink {
  std::size_t n = 0;
  void add(const estimation::EstimateSample&) override { ++n; }
};

/// Keeps the estimates (input of the writer benchmark).
struct KeepingSink : estimation::EstimateSink {
  std::vector<estimation::EstimateSample> all;
  void add(const estimation::EstimateSample& e) override { all.push_back(e); }
};

std::string csvPath() {
  return (std::filesystem::temp_directory_path() / "wheelchair_bench_playback.csv").string();
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

void BM_ScanRawlog(benchmark::State& state) {
  auto& f = fixture();
  for (auto _ : state) benchmark::DoNotOptimize(io::scanRawlog(f.path));
  setCounters(state, f);
}

void BM_StreamMerge(benchmark::State& state) {
  auto& f = fixture();
  const io::RecordingSummary sum = io::scanRawlog(f.path);
  for (auto _ : state) {
    // The window merge of pass 2 (io/RawlogStream.h), each stream in time order.
    io::RawlogWindowReader in(f.path, sum.lateness_s);
    io::SortedStream<io::EncoderSample> enc(io::encoderLess);
    io::SortedStream<io::ImuSample> imu(io::imuLess);
    io::SortedStream<io::MotorSample> mot(io::motorLess);
    double sum_t = 0;
    const auto push = [&](const io::AnySample& s, std::size_t k) {
      if (auto* e = std::get_if<io::EncoderSample>(&s)) enc.push(*e, k);
      if (auto* g = std::get_if<io::ImuSample>(&s)) imu.push(*g, k);
      if (auto* m = std::get_if<io::MotorSample>(&s)) mot.push(*m, k);
    };
    const auto drain = [&](auto& st) {
      while (auto* h = st.head(in.watermark())) {
        sum_t += h->t_s;
        st.pop();
      }
    };
    while (!in.eof()) {
      in.read(push);
      drain(enc);
      drain(imu);
      drain(mot);
    }
    benchmark::DoNotOptimize(sum_t);
  }
  setCounters(state, f);
}

void BM_FilterStatesOn(benchmark::State& state) {
  auto& f = fixture();
  const auto opt = options(f, estimation::FilterKind::Physics, true);
  for (auto _ : state) benchmark::DoNotOptimize(estimation::runEstimator(f.rec, f.cfg, opt));
  setCounters(state, f);
}

void BM_WriteEstimatesCsv(benchmark::State& state) {
  auto& f = fixture();
  KeepingSink keep;
  estimation::runEstimator(f.rec, f.cfg, options(f, estimation::FilterKind::Physics), keep);
  for (auto _ : state) {
    estimation::EstimatesCsvWriter csv(csvPath());
    for (const auto& e : keep.all) csv.add(e);
    csv.commit();
  }
  std::filesystem::remove(csvPath());
  setCounters(state, f);
}

/// The run's estimates (computed once; input of the formatting benchmarks).
const std::vector<estimation::EstimateSample>& keptEstimates() {
  static const std::vector<estimation::EstimateSample> all = [] {
    auto& f = fixture();
    KeepingSink keep;
    estimation::runEstimator(f.rec, f.cfg, options(f, estimation::FilterKind::Physics), keep);
    return keep.all;
  }();
  return all;
}

/// Per-row counters of the formatting benchmarks (rows and characters per CPU second).
void setRowCounters(benchmark::State& state, std::size_t rows, std::size_t chars) {
  const double n = static_cast<double>(state.iterations());
  state.counters["rows_per_s"] = benchmark::Counter(n * rows, benchmark::Counter::kIsRate);
  state.counters["ns_per_row"] =
      benchmark::Counter(n * rows, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["MB_per_s"] = benchmark::Counter(n * chars * 1e-6, benchmark::Counter::kIsRate);
}

/// Formats every row of the run into a reused 1 MB block with `row(p, e) -> end`.
template <typename Row>
void formatRows(benchmark::State& state, Row row) {
  const auto& all = keptEstimates();
  std::vector<char> block(1 << 20);
  std::size_t chars = 0;
  for (auto _ : state) {
    std::size_t used = 0;
    chars = 0;
    for (const auto& e : all) {
      if (block.size() - used < estimation::kMaxEstimateRowChars) {
        chars += used;
        used = 0;
      }
      char* const start = block.data() + used;
      used += static_cast<std::size_t>(row(start, e) - start);
    }
    chars += used;
    benchmark::DoNotOptimize(block.data());
    benchmark::ClobberMemory();
  }
  setRowCounters(state, all.size(), chars);
}

void BM_FormatRowsFmt(benchmark::State& state) {
  formatRows(state, [](char* p, const estimation::EstimateSample& e) {
    const auto& x = e.x;
    const auto& sd = e.sd;
    return fmt::format_to(
        p, FMT_COMPILE("{:.6f},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n"), e.t_s, x(0),
        x(1), x(2), x(3), x(4), x(5), x(6), e.obstacle_distance_m, sd(0), sd(1), sd(2), sd(3),
        sd(4), sd(5), sd(6), e.obstacle_distance_sd_m);
  });
}

void BM_FormatRows(benchmark::State& state) {
  formatRows(state, [](char* p, const estimation::EstimateSample& e) {
    return estimation::writeEstimateRow(p, e);
  });
}

/// The 16 shortest-form numbers of every row, one call per number.
template <typename Num>
void formatNumbers(benchmark::State& state, Num num) {
  const auto& all = keptEstimates();
  std::vector<double> v;
  for (const auto& e : all) {
    for (int i = 0; i < 7; ++i) v.push_back(e.x(i));
    v.push_back(e.obstacle_distance_m);
    for (int i = 0; i < 7; ++i) v.push_back(e.sd(i));
    v.push_back(e.obstacle_distance_sd_m);
  }
  char buf[64];
  for (auto _ : state) {
    for (double x : v) {
      benchmark::DoNotOptimize(num(buf, x));
      benchmark::ClobberMemory();
    }
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["ns_per_number"] =
      benchmark::Counter(n * v.size(), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_ShortestFmt(benchmark::State& state) {
  formatNumbers(state, [](char* p, double x) { return fmt::format_to(p, FMT_COMPILE("{}"), x); });
}

void BM_Shortest(benchmark::State& state) {
  formatNumbers(state, [](char* p, double x) { return util::writeShortest(p, x); });
}

/// `wheelchair filter PATH [--estimates CSV]`: the file read once (or `two_pass`: scanned,
/// then streamed), the streamed filter, the CSV written and committed (the command's own
/// printing aside).
void endToEnd(benchmark::State& state, bool states, bool write_csv, bool two_pass = false) {
  auto& f = fixture();
  const auto opt = options(f, estimation::FilterKind::Physics, states);
  for (auto _ : state) {
    if (!two_pass) {
      io::RecordingSummary sum;
      std::optional<estimation::EstimationResult> res;
      if (write_csv) {
        estimation::EstimatesCsvWriter csv(csvPath());
        res = estimation::runEstimatorOnePass(f.path, f.cfg, opt, csv, sum);
        csv.commit();
      } else {
        CountingSink count;
        res = estimation::runEstimatorOnePass(f.path, f.cfg, opt, count, sum);
      }
      if (!res) state.SkipWithError("the bench drive is not time-ordered");
      benchmark::DoNotOptimize(res);
      continue;
    }
    std::string warning;
    const io::RecordingSummary sum = io::scanRawlogSalvaging(f.path, false, &warning);
    if (write_csv) {
      estimation::EstimatesCsvWriter csv(csvPath());
      benchmark::DoNotOptimize(estimation::runEstimator(f.path, sum, f.cfg, opt, csv));
      csv.commit();
    } else {
      CountingSink count;
      benchmark::DoNotOptimize(estimation::runEstimator(f.path, sum, f.cfg, opt, count));
    }
  }
  std::filesystem::remove(csvPath());
  setCounters(state, f);
}

void BM_EndToEnd(benchmark::State& state) {
  endToEnd(state, false, true);
}
void BM_EndToEndStatesOn(benchmark::State& state) {
  endToEnd(state, true, true);
}
void BM_EndToEndNoOutput(benchmark::State& state) {
  endToEnd(state, false, false);
}
void BM_EndToEndTwoPass(benchmark::State& state) {
  endToEnd(state, false, false, true);
}

}  // namespace

BENCHMARK(BM_DecodeRawlog)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FilterPhysics)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FilterBaseline)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DecodeAndFilter)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ScanRawlog)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_StreamMerge)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FilterStatesOn)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_WriteEstimatesCsv)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FormatRowsFmt)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FormatRows)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ShortestFmt)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Shortest)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EndToEnd)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EndToEndStatesOn)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EndToEndNoOutput)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EndToEndTwoPass)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
