// Outputs of the estimators (docs/estimation.md, "Outputs").
//
// Every estimate is reported in ONE canonical layout whatever the filter and obstacle form:
//   x = [v, omega, x, y, phi, px, py]   (m/s, rad/s, m, m, rad, m, m)
// with (x, y, phi) the pose of the base frame in the start frame and (px, py) the obstacle in
// the base frame (Cartesian; a polar state is converted with the Jacobian of the change of
// variables), P its 7x7 covariance and sd = sqrt(diag(P)).
#pragma once

#include "libwheelchair/estimation/CdEkf.h"

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace wheelchair::estimation {

constexpr int kCanonicalDim = 7;
using CanonicalState = Eigen::Matrix<double, kCanonicalDim, 1>;
using CanonicalCov = Eigen::Matrix<double, kCanonicalDim, kCanonicalDim>;

/// Sensors whose measurements the filters use (index into EstimationResult::sensors): the
/// wheelchair filters' four, and the command-driven EKF's landmark range-bearing sightings.
enum class Sensor { Encoders = 0, Gyro = 1, Sonar = 2, Pozyx = 3, Landmarks = 4 };
constexpr int kNumSensors = 5;
const char* sensorName(Sensor s);

struct EstimateSample {
  double t_s = 0;
  CanonicalState x = CanonicalState::Zero();
  CanonicalState sd = CanonicalState::Zero();
  CanonicalCov P = CanonicalCov::Zero();
  bool obstacle_initialised = false;
  /// The paper's d_o^M (distance from the axle midpoint) and theta_o^M, with 1 sigma.
  double obstacle_distance_m = 0, obstacle_distance_sd_m = 0;
  double obstacle_bearing_rad = 0, obstacle_bearing_sd_rad = 0;
};

/// A measurement that failed the NIS gate (kept, never silently dropped).
struct RejectedMeasurement {
  double t_s = 0;
  Sensor sensor = Sensor::Encoders;
  double nis = 0;
  int dof = 0;
  double gate = 0;
  Eigen::VectorXd innovation;
};

/// One NIS value (every update attempt, accepted or not).
struct NisRecord {
  double t_s = 0;
  Sensor sensor = Sensor::Encoders;
  double nis = 0;
  int dof = 0;
  bool accepted = false;
};

struct SensorStats {
  long used = 0;               ///< measurement updates applied (and obstacle initialisations)
  long rejected = 0;           ///< failed the NIS gate
  long dropouts = 0;           ///< invalid readings (sonar 0 / out of range, encoder gaps)
  long skipped = 0;            ///< not used by choice (sensor disabled)
  long reinitialisations = 0;  ///< sonar: obstacle re-initialised after repeated rejections
  /// Pozyx: times the position covariance was inflated and a gated reading applied, after
  /// pozyx_inflate_after_rejections consecutive rejections (EkfOptions.h)
  long inflated = 0;
  long dropout_episodes = 0;  ///< runs of consecutive dropouts (a failing sensor's episodes)
  // NIS over the ACCEPTED updates.
  long nis_count = 0;
  double nis_sum = 0;
  long nis_inside95 = 0;  ///< NIS inside the two-sided 95 % band of chi2(dof)
  int dof = 0;

  double meanNis() const { return nis_count ? nis_sum / nis_count : 0.0; }
  double fractionInside95() const { return nis_count ? double(nis_inside95) / nis_count : 0.0; }
  /// Two-sided 95 % band of meanNis() for a consistent filter (independent samples).
  std::pair<double, double> meanNisBand95() const;
};

/// Allocator for large output buffers: blocks of >= 4 MiB are 2 MiB-aligned and advised as
/// transparent huge pages (madvise MADV_HUGEPAGE), so that the first touch of a long run's
/// estimates (~55 MB per 10 recorded minutes) costs tens of 2 MiB page faults instead of
/// ~14 k 4 KiB ones (measured ~14 us each on the reference VM; docs/benchmarks.md). Smaller
/// blocks, and systems where the advice is not taken, behave as std::allocator.
void* allocateLargeBuffer(std::size_t bytes);
void freeLargeBuffer(void* p) noexcept;

template <typename T>
struct LargeBufferAllocator {
  using value_type = T;
  LargeBufferAllocator() noexcept = default;
  template <typename U>
  LargeBufferAllocator(const LargeBufferAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) { return static_cast<T*>(allocateLargeBuffer(n * sizeof(T))); }
  void deallocate(T* p, std::size_t) noexcept { freeLargeBuffer(p); }
  template <typename U>
  bool operator==(const LargeBufferAllocator<U>&) const noexcept {
    return true;
  }
  template <typename U>
  bool operator!=(const LargeBufferAllocator<U>&) const noexcept {
    return false;
  }
};

using EstimateSeries = std::vector<EstimateSample, LargeBufferAllocator<EstimateSample>>;

/// Receives a run's estimates one by one, in the order the filter produces them (strictly
/// increasing time), instead of a vector that grows with the drive: a streaming writer
/// (estimation/EstimateWriters.h, evaluation::TumEstimateSink) or a reducer keeps memory
/// flat whatever the recording's length. add() may throw (e.g. a full disk): the run stops.
class EstimateSink {
 public:
  virtual ~EstimateSink() = default;
  virtual void add(const EstimateSample& s) = 0;
};

/// Sensor-error estimates of the physics filter (mean and 1 sigma; WheelchairEkf.h).
struct SensorErrorEstimate {
  bool present = false;  ///< the filter carries the sensor-error states
  double t_s = 0;
  double encoder_scale_right = 1, encoder_scale_right_sd = 0;  ///< reported / true (-)
  double encoder_scale_left = 1, encoder_scale_left_sd = 0;    ///< reported / true (-)
  double encoder_scale_ratio = 1, encoder_scale_ratio_sd = 0;  ///< k_R / k_L (-)
  double gyro_bias_rad_s = 0, gyro_bias_sd_rad_s = 0;
};

/// A model-health event of the physics filter (estimation/HealthMonitor.h): what the online
/// counterpart of `diagnose` found, in its effect words (effect "encoder_scale", parameter
/// "scale", side "left": reported / true distance).
struct HealthEvent {
  double t_s = 0;      ///< when it was found (recording clock)
  std::string sensor;  ///< "encoders", "gyro", "sonar"
  std::string kind;    ///< "estimate" | "inconsistent" | "dropouts"
  std::string effect;  ///< diagnose's effect id ("encoder_scale", "gyro_bias"); "" for others
  std::string side;    ///< "right" | "left" | ""
  std::string parameter;
  double value = 0, sd = 0;  ///< the parameter and its 1 sigma
  double since_s = 0;        ///< estimated onset (recording clock)
  std::string text;          ///< one readable line
};

struct EstimationResult {
  std::string filter;  ///< "physics", "baseline" or "command"
  /// All estimates (runEstimator without a sink); empty when they went to an EstimateSink.
  EstimateSeries estimates;
  std::size_t n_estimates = 0;  ///< estimates produced (stored or streamed)
  EstimateSample last;          ///< the last one produced (valid when n_estimates > 0)
  std::array<SensorStats, kNumSensors> sensors{};
  std::vector<RejectedMeasurement> rejected;
  std::vector<NisRecord> nis;         ///< every update attempt (runEstimator without a sink only)
  CvodeStats cvode;                   ///< physics filter only
  SensorErrorEstimate sensor_errors;  ///< at the end of the run (physics filter with the states)
  std::vector<HealthEvent> health;    ///< model-health events, in time order
  std::vector<std::string> warnings;  ///< e.g. "no motor currents: input held at 0"

  const SensorStats& stats(Sensor s) const { return sensors[static_cast<int>(s)]; }
  /// Final estimate, stored or streamed (throws std::logic_error when there is none).
  const EstimateSample& final() const;
};

}  // namespace wheelchair::estimation
