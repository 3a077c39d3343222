// How accurate the CD-EKF's CVODE integration is at the configured settings: the physics
// filter is run twice on one recording, with the configuration's [estimator] cvode_* settings
// and with a tight reference (rel 1e-10, abs 1e-13 state / 1e-15 covariance, CVODE's own
// initial step and corrector settings), and every output estimate is compared in units of its
// own standard deviation. This reproduces the tolerance table of docs/estimation.md ("CVODE
// settings"); edit the cvode_* keys of a copy of the configuration for the other rows.
//
//   build/bench/integration_accuracy [--config F] [--recording DIR_OR_RAWLOG]
//                                    [--max-error-percent P]
//
// Default recording: datasets/excite (60 s, plain-text recording). --max-error-percent: exit 1
// when the worst |dx| / sd or |d sd| / sd exceeds P percent (CTest runs it with 5).
#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/EkfOptions.h"
#include "libwheelchair/estimation/Estimator.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/TextFormat.h"

#include <fmt/core.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>

using namespace wheelchair;

int main(int argc, char** argv) {
  std::string cfg_path = std::string(WHEELCHAIR_SOURCE_DIR) + "/config/wheelchair.ini";
  std::string rec_path = std::string(WHEELCHAIR_SOURCE_DIR) + "/datasets/excite";
  double max_error_percent = -1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      std::cerr << "usage: integration_accuracy [--config F] [--recording DIR_OR_RAWLOG] "
                   "[--max-error-percent P]\n";
      return 2;
    }
    if (a == "--config")
      cfg_path = argv[++i];
    else if (a == "--recording")
      rec_path = argv[++i];
    else if (a == "--max-error-percent")
      max_error_percent = std::stod(argv[++i]);
    else {
      std::cerr << "unknown option " << a << "\n";
      return 2;
    }
  }
  const auto cfg = config::WheelchairConfig::load(cfg_path);
  const io::Recording rec = std::filesystem::is_directory(rec_path)
                                ? io::readTextRecording(rec_path)
                                : io::readRawlog(rec_path);
  estimation::EkfOptions opt;
  opt.loadFromConfig(cfg.ini());
  opt.resolveSensorDefaults(cfg);
  opt.filter = estimation::FilterKind::Physics;
  estimation::EkfOptions ref = opt;
  ref.cvode = estimation::CvodeOptions{};
  ref.cvode.method = opt.cvode.method;
  ref.cvode.restart_at_input_samples = opt.cvode.restart_at_input_samples;
  ref.cvode.rel_tol = 1e-10;
  ref.cvode.abs_tol_state = 1e-13;
  ref.cvode.abs_tol_cov = 1e-15;
  ref.cvode.nonlin_conv_coef = 0.1;
  ref.cvode.adaptive_initial_step = false;
  ref.cvode.max_num_steps = 1000000;

  const auto a = estimation::runEstimator(rec, cfg, opt);
  const auto b = estimation::runEstimator(rec, cfg, ref);
  if (a.estimates.size() != b.estimates.size()) {
    std::cerr << "different numbers of estimates: " << a.estimates.size() << " vs "
              << b.estimates.size() << "\n";
    return 1;
  }
  // Angles are compared wrapped (phi near +-pi).
  const std::array<const char*, 7> names{"v", "omega", "x", "y", "phi", "px", "py"};
  std::array<double, 7> dx{}, dsd{};
  for (std::size_t k = 0; k < a.estimates.size(); ++k) {
    const auto& e = a.estimates[k];
    const auto& r = b.estimates[k];
    for (int i = 0; i < 7; ++i) {
      if (!(r.sd(i) > 0)) continue;
      double d = e.x(i) - r.x(i);
      if (i == 4) d = std::remainder(d, 2 * M_PI);
      dx[i] = std::max(dx[i], std::fabs(d) / r.sd(i));
      dsd[i] = std::max(dsd[i], std::fabs(e.sd(i) - r.sd(i)) / r.sd(i));
    }
  }
  const auto& c = a.cvode;
  fmt::print(
      "{}: {} estimates; configured CVODE: rel {:g}, abs {:g} / {:g}, corrector {:g}, "
      "adaptive initial step {}\n",
      rec_path, a.estimates.size(), opt.cvode.rel_tol, opt.cvode.abs_tol_state,
      opt.cvode.abs_tol_cov, opt.cvode.nonlin_conv_coef,
      opt.cvode.adaptive_initial_step ? "on" : "off");
  fmt::print("{:.2f} steps, {:.2f} f-evaluations, {:.2f} error-test failures per interval\n",
             double(c.steps) / c.intervals, double(c.rhs_evals) / c.intervals,
             double(c.error_test_fails) / c.intervals);
  double worst = 0;
  fmt::print("{:<6} {:>12} {:>12}\n", "state", "max|dx|/sd", "max|dsd|/sd");
  for (int i = 0; i < 7; ++i) {
    fmt::print("{:<6} {:>11.3f}% {:>11.3f}%\n", names[i], 100 * dx[i], 100 * dsd[i]);
    worst = std::max({worst, dx[i], dsd[i]});
  }
  if (max_error_percent >= 0 && 100 * worst > max_error_percent) {
    fmt::print("FAILED: worst {:.3f}% of an sd > {:g}%\n", 100 * worst, max_error_percent);
    return 1;
  }
  return 0;
}
