// Progress display on stderr shared by the long-running subcommands (filter, diagnose).
//
// Example:
//   Progress progress(!no_progress && isatty(STDERR_FILENO));
//   progress.tick("reading");                  // stage + elapsed seconds, refreshed 5x/s
//   auto rec = io::readRawlog(path);
//   progress.update(0.5, "filtering");         // a bar: [###...] 50%
//   progress.stop();                           // clears the line before normal output
#pragma once

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>

namespace wheelchair::cli {

// Progress on stderr, drawn only when enabled (stderr is a terminal). A bar when the fraction
// is known (update()), else the stage and the elapsed time, refreshed by a ticker thread
// (tick()) while a long call runs.
class Progress {
 public:
  explicit Progress(bool enabled) : enabled_(enabled) {}
  ~Progress() { stop(); }
  bool enabled() const { return enabled_; }

  void update(double fraction, const std::string& stage) {
    if (!enabled_) return;
    const int pct = static_cast<int>(std::floor(100 * std::clamp(fraction, 0.0, 1.0)));
    if (pct == last_pct_ && stage == last_stage_) return;
    last_pct_ = pct;
    last_stage_ = stage;
    const int width = 30, filled = pct * width / 100;
    std::lock_guard<std::mutex> lock(mu_);
    fmt::print(stderr, "\r{:<12.12} [{}{}] {:3d}%", stage, std::string(filled, '#'),
               std::string(width - filled, '.'), pct);
    std::fflush(stderr);
    drawn_ = true;
  }
  /// Shows `stage` with the elapsed time until stop() (or the next tick()/update()).
  void tick(const std::string& stage) {
    if (!enabled_) return;
    stop();
    running_ = true;
    const auto t0 = std::chrono::steady_clock::now();
    ticker_ = std::thread([this, stage, t0] {
      std::unique_lock<std::mutex> lock(mu_);
      while (running_) {
        const double s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        fmt::print(stderr, "\r{:<12.12} ... {:6.1f} s", stage, s);
        std::fflush(stderr);
        drawn_ = true;
        cv_.wait_for(lock, std::chrono::milliseconds(200), [this] { return !running_; });
      }
    });
  }
  /// Ends the ticker and clears the line.
  void stop() {
    if (ticker_.joinable()) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        running_ = false;
      }
      cv_.notify_all();
      ticker_.join();
    }
    if (enabled_ && drawn_) {
      fmt::print(stderr, "\r{:<60}\r", "");
      std::fflush(stderr);
      drawn_ = false;
      last_pct_ = -1;
    }
  }

 private:
  bool enabled_;
  bool drawn_ = false, running_ = false;
  int last_pct_ = -1;
  std::string last_stage_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::thread ticker_;
};

}  // namespace wheelchair::cli
