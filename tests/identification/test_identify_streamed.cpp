// identify on rawlogs read as a stream (identification::identifyStreamed, what `wheelchair
// identify` runs on time-ordered files; docs/benchmarks.md "Memory"): the conditioned rows and
// the result against the in-memory path on the same files, and the blocked zero-phase filter
// against the whole-series one.
#include "../common/TestUtil.h"
#include "DriveGenerator.h"

#include "libwheelchair/identification/Identification.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/sensors/Filtering.h"
#include "libwheelchair/signals/IntervalStream.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

using namespace wheelchair;
namespace fs = std::filesystem;

namespace {

// Two drives as rawlogs: 260 s (one segment longer than two blocks of the streamed filter)
// and 40 s (filtered whole).
struct Drives {
  fs::path dir;
  std::vector<std::string> paths;
  Drives() {
    dir = fs::temp_directory_path() / ("wc_idstream_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const config::WheelchairConfig cfg;
    const auto dt = model::DriveTrain::symmetric(cfg.vehicle);
    int i = 0;
    for (double dur : {260.0, 40.0}) {
      test::GeneratorOptions go;
      go.duration_s = dur;
      go.seed = 11 + i;
      const auto rec = test::generateDrive(cfg, dt, test::excitingDemand(go.seed), go);
      paths.push_back((dir / ("d" + std::to_string(i++) + ".rawlog")).string());
      io::writeRawlog(rec, paths.back(), cfg);
    }
  }
  ~Drives() { fs::remove_all(dir); }
};

const Drives& drives() {
  static const Drives d;
  return d;
}

// Largest relative difference of two JSON documents' numbers (structure must match).
double maxRelDiff(const nlohmann::json& a, const nlohmann::json& b, const std::string& path,
                  std::string* where) {
  double worst = 0;
  if (a.is_object()) {
    EXPECT_TRUE(b.is_object()) << path;
    for (auto it = a.begin(); it != a.end(); ++it) {
      EXPECT_TRUE(b.contains(it.key())) << path << "/" << it.key();
      if (!b.contains(it.key())) continue;
      std::string w;
      const double d = maxRelDiff(*it, b[it.key()], path + "/" + it.key(), &w);
      if (d > worst) worst = d, *where = w;
    }
  } else if (a.is_array()) {
    EXPECT_EQ(a.size(), b.size()) << path;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
      std::string w;
      const double d = maxRelDiff(a[i], b[i], path + "[" + std::to_string(i) + "]", &w);
      if (d > worst) worst = d, *where = w;
    }
  } else if (a.is_number() && b.is_number()) {
    const double x = a.get<double>(), y = b.get<double>();
    if (x != y) worst = std::abs(x - y) / std::max(std::abs(x), std::abs(y)), *where = path;
  } else {
    EXPECT_EQ(a, b) << path;
  }
  return worst;
}

}  // namespace

TEST(IdentifyStreamed, FiltfiltByBlocksEqualsTheWholeSeries) {
  std::mt19937 rng(5);
  std::normal_distribution<double> N(0, 1);
  for (const long n : {30L, 3000L, 20384L, 61234L}) {
    std::vector<double> a(n), b(n);
    double w = 0;
    for (long k = 0; k < n; ++k) w += N(rng), a[k] = w, b[k] = std::sin(0.01 * k) + 0.1 * N(rng);
    const auto ya = sensors::filtfiltButter2(a, 2.0, 100.0);
    const auto yb = sensors::filtfiltButter2(b, 2.0, 100.0);
    long got = 0;
    double worst = 0, scale = 0;
    signals::StreamingFiltfilt f(2, 2.0, 100.0, 0, [&](long j, const double* raw, const double* y) {
      EXPECT_EQ(j, got++);
      EXPECT_EQ(raw[0], a[j]);
      EXPECT_EQ(raw[1], b[j]);
      worst = std::max({worst, std::abs(y[0] - ya[j]), std::abs(y[1] - yb[j])});
      scale = std::max({scale, std::abs(ya[j]), std::abs(yb[j])});
    });
    for (long k = 0; k < n; ++k) {
      const double x[2] = {a[k], b[k]};
      f.push(x);
      EXPECT_LE(got, std::max(0L, k + 1 - f.runIn())) << "emitted before its run-in";
    }
    f.finish();
    EXPECT_EQ(got, n);
    EXPECT_LE(worst, 1e-13 * scale) << "n " << n;
    std::printf("  n %6ld: largest |blocked - whole| %.3g (of %.3g)\n", n, worst, scale);
  }
}

// The conditioned rows of the streamed path are those of prepareIntervalMeans, in its order,
// and the noise floors the same; the identification result agrees to rounding.
TEST(IdentifyStreamed, EqualsTheInMemoryPath) {
  const auto& d = drives();
  const config::WheelchairConfig cfg;
  for (const bool gyro : {false, true}) {
    identification::IdentificationOptions opt;
    opt.omega_source = gyro ? "gyro" : "encoders";
    const auto so = opt.intervalSignalOptions();
    std::vector<io::Recording> recs;
    for (const auto& p : d.paths) recs.push_back(io::readRawlog(p));
    const auto mem = signals::prepareIntervalMeans(recs, cfg, so);
    std::vector<signals::IntervalRow> rows;
    signals::IntervalConditioner c(cfg, so,
                                   [&](const signals::IntervalRow& r) { rows.push_back(r); });
    for (std::size_t i = 0; i < d.paths.size(); ++i) {
      io::RawlogSampleReader in(d.paths[i]);
      c.beginRecording(int(i));
      io::AnySample s;
      std::size_t k;
      while (in.next(s, k)) c.add(s);
      c.endRecording();
    }
    const auto str = c.finish();
    ASSERT_EQ(mem.segments.size(), 2u);
    std::size_t q = 0, exact = 0;
    double worst = 0;
    for (std::size_t si = 0; si < mem.segments.size(); ++si)
      for (std::size_t k = 0; k < mem.segments[si].t.size(); ++k, ++q) {
        ASSERT_LT(q, rows.size());
        const auto a = signals::intervalRow(mem.segments[si], int(si), k);
        const auto& b = rows[q];
        ASSERT_EQ(b.segment, a.segment);
        ASSERT_EQ(b.k, a.k);
        ASSERT_EQ(b.recording, a.recording);
        ASSERT_EQ(b.t, a.t);
        ASSERT_EQ(b.interior, a.interior);
        ASSERT_EQ(b.moving, a.moving);
        const double va[10] = {a.u_r,      a.u_l, a.v,   a.omega, a.vdot,
                               a.omegadot, a.i_r, a.i_l, a.U_r,   a.U_l};
        const double vb[10] = {b.u_r,      b.u_l, b.v,   b.omega, b.vdot,
                               b.omegadot, b.i_r, b.i_l, b.U_r,   b.U_l};
        bool same = true;
        for (int j = 0; j < 10; ++j) {
          same = same && va[j] == vb[j];
          worst = std::max(worst, std::abs(va[j] - vb[j]) / std::max(1.0, std::abs(va[j])));
        }
        exact += same;
      }
    EXPECT_EQ(q, rows.size());
    EXPECT_LE(worst, 1e-12);
    std::printf("  gyro %d: %zu rows, %zu bit-identical, largest difference %.3g\n", int(gyro),
                rows.size(), exact, worst);
    EXPECT_NEAR(str.noise_v, mem.noise_v, 1e-12 * mem.noise_v);
    EXPECT_NEAR(str.noise_omegadot, mem.noise_omegadot, 1e-12 * mem.noise_omegadot);
    EXPECT_EQ(str.has_voltage, mem.has_voltage);

    const auto a = identification::identify(recs, cfg, opt, d.paths).toJson();
    const auto b = identification::identifyStreamed(d.paths, cfg, opt, d.paths).toJson();
    std::string where;
    auto ta = a, tb = b;  // rounding-level singular values differ (rank-deficient theta)
    for (auto* j : {&ta, &tb}) {
      (*j)["theta_regression"].erase("singular_values_relative");
      (*j)["theta_regression"].erase("condition_number_scaled");
      for (auto& nd : (*j)["theta_regression"]["not_identifiable_directions"])
        nd.erase("singular_value_relative");
    }
    const double rel = maxRelDiff(ta, tb, "", &where);
    EXPECT_LE(rel, 1e-9) << where;
    EXPECT_EQ(a["theta_regression"]["rank"], b["theta_regression"]["rank"]);
    EXPECT_EQ(a["samples"], b["samples"]);
    EXPECT_EQ(a["quasi_steady_segments"].size(), b["quasi_steady_segments"].size());
    std::printf("  gyro %d: JSON largest relative difference %.3g (%s)\n", int(gyro), rel,
                where.c_str());
  }
}

// A file whose motor stream goes back in time is refused by the streamed path (the CLI loads
// such files whole).
TEST(IdentifyStreamed, RefusesAStreamOutOfTimeOrder) {
  const config::WheelchairConfig cfg;
  signals::IntervalConditioner c(cfg, {}, [](const signals::IntervalRow&) {});
  c.beginRecording(0);
  io::MotorSample m;
  m.t_s = 1.0;
  c.add(m);
  m.t_s = 0.5;
  EXPECT_THROW(c.add(m), std::invalid_argument);
}

// Through the CLI: a time-ordered rawlog is streamed, the same drive written out of time order
// (every 7th motor sample 0.3 s late: lateness 0.3 s) is loaded whole; both give the same JSON
// (the same collector and solver after the conditioning, which is bit-identical).
TEST(IdentifyStreamed, CliStreamsOrderedFilesAndLoadsOthersWithTheSameResult) {
  if (!fs::exists(WHEELCHAIR_CLI)) GTEST_SKIP() << WHEELCHAIR_CLI << " not built";
  const auto& d = drives();
  const io::Recording rec = io::readRawlog(d.paths[1]);
  // Both files written the same way (the stored stamps are relative to the header's time).
  const auto write = [&](const std::string& path, double late_s) {
    std::vector<std::pair<double, io::AnySample>> v;
    std::size_t mot = 0;
    io::forEachInTimeOrder(rec, [&](const io::AnySample& s) {
      double at = io::timeOf(s);
      if (io::kindOf(s) == io::StreamKind::Motors && mot++ % 7 == 3) at += late_s;
      v.emplace_back(at, s);
    });
    std::stable_sort(v.begin(), v.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    io::RawlogWriter w(path);
    w.writeHeader(rec.meta, config::WheelchairConfig(), rec.startTime());
    for (const auto& [t, s] : v) w.write(s, config::WheelchairConfig());
    w.commit();
  };
  const std::string ordered = (d.dir / "ordered.rawlog").string();
  const std::string late = (d.dir / "late.rawlog").string();
  write(ordered, 0.0);
  write(late, 0.3);
  EXPECT_EQ(io::scanRawlog(ordered).lateness_s, 0.0);
  EXPECT_GT(io::scanRawlog(late).lateness_s, 0.29);
  const std::string ja = (d.dir / "a.json").string(), jb = (d.dir / "b.json").string();
  ASSERT_EQ(test::cli("identify " + ordered + " --json " + ja).exit_code, 0);
  ASSERT_EQ(test::cli("identify " + late + " --json " + jb).exit_code, 0);
  auto a = nlohmann::json::parse(std::ifstream(ja)), b = nlohmann::json::parse(std::ifstream(jb));
  EXPECT_EQ(a["recordings"][0], ordered);
  a.erase("recordings");
  b.erase("recordings");
  EXPECT_TRUE(a == b) << a.dump() << "\n" << b.dump();
}
