// estimation::LiveEstimator (the live filter of `wheelchair capture --health`): samples pushed
// one by one in arrival order give the same filter run as runEstimator on the whole
// recording; a sample older than one already released is skipped and counted; a filter
// failure throws naming the sample, as runEstimator does.
#include "../common/TestUtil.h"
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/io/Samples.h"
#include "libwheelchair/io/TextFormat.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

using namespace wheelchair;
using namespace wheelchair::estimation;

namespace {

struct LiveSetup {
  config::WheelchairConfig cfg =
      config::WheelchairConfig::load(wheelchair::test::sourcePath("config/wheelchair.ini"));
  EkfOptions opt;
  LiveSetup() {
    cfg.set("estimator", "estimate_encoder_scales", "1");
    opt.loadFromConfig(cfg.ini());
  }
};

std::vector<io::AnySample> inTimeOrder(const io::Recording& rec) {
  std::vector<io::AnySample> v;
  io::forEachInTimeOrder(rec, [&](const io::AnySample& s) { v.push_back(s); });
  return v;
}

}  // namespace

TEST(LiveEstimator, PushedSamplesGiveTheRunOfTheWholeRecording) {
  LiveSetup su;
  const auto rec =
      io::readTextRecording(wheelchair::test::sourcePath("datasets/three_task_faulty"));
  const auto whole = runEstimator(rec, su.cfg, su.opt);
  ASSERT_FALSE(whole.health.empty());

  LiveEstimator live(su.cfg, su.opt, !rec.motors.empty());
  std::size_t seen_before_end = 0;
  for (const auto& s : inTimeOrder(rec)) {
    live.push(s);
    seen_before_end = live.health().size();
  }
  // The encoder events come while the samples arrive, not only at the end.
  EXPECT_GE(seen_before_end, 2u);
  live.finish();
  EXPECT_EQ(live.late(), 0u);
  EXPECT_DOUBLE_EQ(live.startTime(), rec.startTime());
  const auto& got = live.result();
  ASSERT_EQ(got.health.size(), whole.health.size());
  for (std::size_t i = 0; i < got.health.size(); ++i) {
    EXPECT_EQ(got.health[i].text, whole.health[i].text);
    EXPECT_EQ(got.health[i].t_s, whole.health[i].t_s);
    EXPECT_EQ(got.health[i].value, whole.health[i].value);
  }
  EXPECT_EQ(&live.health(), &got.health);
  // The same final state, bit for bit, and the same sensor bookkeeping.
  EXPECT_EQ(got.last.t_s, whole.final().t_s);
  EXPECT_EQ(got.last.x, whole.final().x);
  for (int s = 0; s < kNumSensors; ++s) {
    EXPECT_EQ(got.sensors[s].used, whole.sensors[s].used) << s;
    EXPECT_EQ(got.sensors[s].rejected, whole.sensors[s].rejected) << s;
  }
}

TEST(LiveEstimator, ALateSampleIsSkippedAndAFailureNamesTheSample) {
  LiveSetup su;
  auto rec = io::readTextRecording(wheelchair::test::sourcePath("datasets/three_task_clean"));
  const auto samples = inTimeOrder(rec);
  {
    LiveEstimator live(su.cfg, su.opt, true);
    for (std::size_t i = 0; i < 200; ++i) live.push(samples[i]);
    live.push(samples[10]);  // arrived after later ones were filtered
    EXPECT_EQ(live.late(), 1u);
    live.finish();
    EXPECT_GT(live.result().sensors[int(Sensor::Encoders)].used, 0);
  }
  // A clock that jumps 1e6 s forward at t = 20 s: CVODE cannot integrate that far.
  LiveEstimator live(su.cfg, su.opt, true);
  const double jump_at = rec.startTime() + 20.0;
  std::string what;
  try {
    for (auto s : samples) {
      std::visit(
          [&](auto& x) {
            if (x.t_s >= jump_at) x.t_s += 1e6;
          },
          s);
      live.push(s);
    }
    live.finish();
  } catch (const std::runtime_error& e) {
    what = e.what();
  }
  EXPECT_NE(what.find(" sample "), std::string::npos) << what;
  EXPECT_NE(what.find("CVODE failed"), std::string::npos) << what;
}
