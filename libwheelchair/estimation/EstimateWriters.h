// Streaming writers of the estimators' outputs (docs/estimation.md, "Outputs"). Each row goes
// to the file as the filter produces it, so writing a ten-hour drive needs no more memory than
// a ten-second one; every file goes through util::AtomicFile (complete at its path or absent,
// a write error stops the run early with one line naming the file).
//
// Estimates CSV (one row per estimate, canonical layout of EstimationTypes.h):
//   t_s,v_m_s,omega_rad_s,x_m,y_m,phi_rad,obstacle_x_m,obstacle_y_m,obstacle_distance_m,
//   sd_v_m_s,...,sd_obstacle_distance_m
// t with 6 decimals (fmt's "{:.6f}"), every other number rounded to 10 significant digits
// (relative error <= 5e-10: sub-nanometre on metres, far below any sd the filter reports;
// trailing zeros dropped, e.g. "0.1", "-1.234567891", "3.2e-07"; util::write10Significant).
// Frames: pose in the start frame, obstacle in the body frame (m, rad, m/s, rad/s).
//
// Command-driven EKF CSV (map frame): t_s,x_m,y_m,phi_rad,v_m_s,omega_rad_s,sd_x_m,sd_y_m,
// sd_phi_rad,sd_v_m_s,sd_omega_rad_s,cov_xy_m2.
//
// Example:
//   EstimatesCsvWriter csv("out/est.csv");
//   EstimationResult res = runEstimator(rec, cfg, opt, csv);   // rows streamed
//   csv.commit();                                              // throws on any failure
#pragma once

#include "libwheelchair/estimation/CommandDrivenEkf.h"
#include "libwheelchair/estimation/EstimationTypes.h"
#include "libwheelchair/util/AtomicFile.h"
#include "libwheelchair/util/NumberFormat.h"

#include <cstddef>
#include <string>
#include <vector>

namespace wheelchair::estimation {

/// Longest row of the estimates CSV: t, 16 numbers, 16 commas and the newline.
constexpr std::size_t kMaxEstimateRowChars =
    util::kMaxFixed6Chars + 16 * util::kMaxDoubleChars + 17;

/// One row of the estimates CSV (with its newline) at `p`, which has room for
/// kMaxEstimateRowChars characters; returns the end.
char* writeEstimateRow(char* p, const EstimateSample& e);

/// Estimates CSV (see the header comment), one row per add().
class EstimatesCsvWriter : public EstimateSink {
 public:
  /// Creates the temporary beside `path` and writes the header (throws naming the file).
  explicit EstimatesCsvWriter(const std::string& path);
  void add(const EstimateSample& e) override;
  /// Completes the file (util::AtomicFile::commit); without it nothing appears at `path`.
  void commit();
  std::size_t rows() const { return rows_; }

 private:
  static constexpr std::size_t kBufferBytes = 256 * 1024;
  void flushBuffer();

  util::AtomicFile file_;
  std::vector<char> buf_;  // rows not yet given to file_'s stream
  std::size_t used_ = 0;
  std::size_t rows_ = 0;
};

/// Passes every estimate to each of `sinks` in turn (null entries skipped).
class EstimateFanOut : public EstimateSink {
 public:
  explicit EstimateFanOut(std::vector<EstimateSink*> sinks) : sinks_(std::move(sinks)) {}
  void add(const EstimateSample& e) override {
    for (auto* s : sinks_)
      if (s) s->add(e);
  }

 private:
  std::vector<EstimateSink*> sinks_;
};

/// Command-driven EKF estimates as CSV (see the header comment), atomically.
void writeCommandDrivenCsv(const std::string& path, const std::vector<CommandDrivenEstimate>& est);

}  // namespace wheelchair::estimation
