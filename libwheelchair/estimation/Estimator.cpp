#include "libwheelchair/estimation/Estimator.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/BaselineEkf.h"
#include "libwheelchair/estimation/Measurement.h"
#include "libwheelchair/estimation/WheelchairEkf.h"
#include "libwheelchair/io/MrclamImport.h"
#include "libwheelchair/stats/Distributions.h"

#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <deque>
#include <limits>
#include <optional>
#include <stdexcept>
#include <tuple>

#include <fmt/core.h>

namespace wheelchair::estimation {

// ---------------------------------------------------------------------------------------------
// Result types

void* allocateLargeBuffer(std::size_t bytes) {
  constexpr std::size_t kHuge = std::size_t(2) << 20;  // one x86-64 transparent huge page
  void* p = nullptr;
  if (bytes >= 2 * kHuge) {
    const std::size_t size = (bytes + kHuge - 1) / kHuge * kHuge;
    p = std::aligned_alloc(kHuge, size);
    // Advice only: where THP is off ("never") the pages are simply 4 KiB ones.
    if (p) ::madvise(p, size, MADV_HUGEPAGE);
  } else {
    p = std::malloc(bytes ? bytes : 1);
  }
  if (!p) throw std::bad_alloc();
  return p;
}

void freeLargeBuffer(void* p) noexcept {
  std::free(p);
}

const char* sensorName(Sensor s) {
  switch (s) {
    case Sensor::Encoders:
      return "encoders";
    case Sensor::Gyro:
      return "gyro";
    case Sensor::Sonar:
      return "sonar";
    case Sensor::Pozyx:
      return "pozyx";
    case Sensor::Landmarks:
      return "landmarks";
  }
  return "?";
}

std::pair<double, double> SensorStats::meanNisBand95() const {
  if (nis_count <= 0 || dof <= 0) return {0.0, 0.0};
  return stats::chi2MeanBand(0.95, dof, static_cast<double>(nis_count));
}

const EstimateSample& EstimationResult::final() const {
  if (!estimates.empty()) return estimates.back();
  if (n_estimates > 0) return last;
  throw std::logic_error("EstimationResult: no estimate");
}

// ---------------------------------------------------------------------------------------------
// InputSignal

void InputSignal::setSamples(std::vector<io::MotorSample> s) {
  std::sort(s.begin(), s.end(), io::motorLess);
  t_.clear();
  u_.clear();
  for (const auto& m : s) {
    const Eigen::Vector2d u(m.current_right_A, m.current_left_A);
    if (!t_.empty() && t_.back() == m.t_s) {
      u_.back() = u;
      continue;
    }
    t_.push_back(m.t_s);
    u_.push_back(u);
  }
}

void InputSignal::add(const io::MotorSample& m) {
  const Eigen::Vector2d u(m.current_right_A, m.current_left_A);
  const auto it = std::lower_bound(t_.begin(), t_.end(), m.t_s);
  const auto i = static_cast<std::size_t>(it - t_.begin());
  if (it != t_.end() && *it == m.t_s) {
    u_[i] = u;
    return;
  }
  t_.insert(it, m.t_s);
  u_.insert(u_.begin() + static_cast<std::ptrdiff_t>(i), u);
}

Eigen::Vector2d InputSignal::at(double t) const {
  if (t_.empty()) return Eigen::Vector2d::Zero();
  if (t <= t_.front()) return u_.front();
  if (t >= t_.back()) return u_.back();
  // First sample strictly after t: t_[j - 1] <= t < t_[j]. Try the last interval and its
  // successor before a binary search.
  std::size_t j = hint_ + 1;
  if (!(j < t_.size() && t_[j - 1] <= t && t < t_[j])) {
    if (j + 1 < t_.size() && t_[j] <= t && t < t_[j + 1])
      ++j;
    else
      j = static_cast<std::size_t>(std::upper_bound(t_.begin(), t_.end(), t) - t_.begin());
  }
  hint_ = j - 1;
  const std::size_t i = j - 1;
  if (mode_ == InputInterpolation::Hold) return u_[i];
  const double a = (t - t_[i]) / (t_[j] - t_[i]);
  return (1.0 - a) * u_[i] + a * u_[j];
}

std::vector<double> InputSignal::breakpoints(double t0, double t1) const {
  std::vector<double> out;
  for (auto it = std::upper_bound(t_.begin(), t_.end(), t0); it != t_.end() && *it < t1; ++it)
    out.push_back(*it);
  return out;
}

double InputSignal::nextSampleAfter(double t) const {
  const auto it = std::upper_bound(t_.begin(), t_.end(), t);
  return it == t_.end() ? std::numeric_limits<double>::infinity() : *it;
}

void InputSignal::discardBefore(double t) {
  // Keep the last sample at or before t (u between it and the next one is still needed).
  const auto it = std::upper_bound(t_.begin(), t_.end(), t);
  const auto k = static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, it - t_.begin() - 1));
  if (k < 8192 || 2 * k < t_.size()) return;  // amortised: erase when mostly dead
  t_.erase(t_.begin(), t_.begin() + static_cast<std::ptrdiff_t>(k));
  u_.erase(u_.begin(), u_.begin() + static_cast<std::ptrdiff_t>(k));
  hint_ = hint_ >= k ? hint_ - k : 0;
}

bool InputSignal::isSampleTime(double t) const {
  return std::binary_search(t_.begin(), t_.end(), t);
}

InputFunction InputSignal::segment(double t0, double t1) const {
  const Eigen::Vector2d u0 = at(t0);
  if (mode_ == InputInterpolation::Hold || t1 <= t0) {
    return [u0](double) -> Eigen::VectorXd { return u0; };
  }
  // Linear mode: u is linear on [t0, t1] when no sample lies strictly inside.
  const Eigen::Vector2d u1 = at(t1);
  return [u0, u1, t0, t1](double t) -> Eigen::VectorXd {
    const double a = std::clamp((t - t0) / (t1 - t0), 0.0, 1.0);
    return (1.0 - a) * u0 + a * u1;
  };
}

// ---------------------------------------------------------------------------------------------
// Estimator (shared parts)

Estimator::Estimator(const config::WheelchairConfig& cfg, const EkfOptions& opt) : opt_(opt) {
  opt_.resolveSensorDefaults(cfg);
  opt_.validate();
  wheel_radius_m_ = cfg.vehicle.geom.wheel_radius_m;
  track_width_m_ = cfg.vehicle.geom.track_width_m;
  wheel_rad_per_tick_ = cfg.encoders.params.wheelRadPerTick();
  sonar_min_m_ = cfg.sonar.min_range_m;
  sonar_max_m_ = cfg.sonar.max_range_m;
  sonar_yaw_rad_ = cfg.sonar.yaw_deg * M_PI / 180.0;
  sonar_offset_m_ = Eigen::Vector2d(cfg.sonar.x_m, cfg.sonar.y_m);
  pozyx_lever_m_ = Eigen::Vector2d(cfg.pozyx.lever_x_m, cfg.pozyx.lever_y_m);
  res_.filter = opt_.filter == FilterKind::Physics ? "physics" : "baseline";
}

double Estimator::gate(int dof) const {
  if (!(opt_.gate_probability > 0 && opt_.gate_probability < 1)) return 0.0;
  auto it = gates_.find(dof);
  if (it != gates_.end()) return it->second;
  const double g = stats::chi2Quantile(opt_.gate_probability, dof);
  gates_[dof] = g;
  return g;
}

void Estimator::record(Sensor s, double t, const UpdateResult& r, double g) {
  bookUpdate(res_, s, t, r, g, keep_nis_records_);
}

Eigen::Matrix2d Estimator::encoderNoise(double dt) const {
  double var_u = opt_.encoder_extra_noise_m_s * opt_.encoder_extra_noise_m_s;
  if (opt_.encoder_quantisation) {
    const double tick_m = wheel_radius_m_ * wheel_rad_per_tick_;
    var_u += tick_m * tick_m / 6.0 / (dt * dt);
  }
  return wheelSpeedNoise(var_u);
}

Eigen::Matrix2d Estimator::wheelSpeedNoise(double var_u) const {
  Eigen::Matrix2d R = Eigen::Matrix2d::Zero();
  R(0, 0) = 0.5 * var_u;                                      // v = (uR + uL) / 2
  R(1, 1) = 2.0 * var_u / (track_width_m_ * track_width_m_);  // omega = (uR - uL) / l_w
  return R;
}

Eigen::Vector2d Estimator::sonarPointBody(double range) const {
  return sonar_offset_m_ +
         range * Eigen::Vector2d(std::cos(sonar_yaw_rad_), std::sin(sonar_yaw_rad_));
}

Eigen::Matrix2d Estimator::sonarPointCovBody(double range) const {
  const double sb = opt_.initial_obstacle_bearing_sigma_deg * M_PI / 180.0;
  const double c = std::cos(sonar_yaw_rad_), s = std::sin(sonar_yaw_rad_);
  Eigen::Matrix2d Rot;
  Rot << c, -s, s, c;
  const Eigen::Vector2d var(opt_.sonar_noise_m * opt_.sonar_noise_m,
                            range * range * sb * sb + 1e-6);
  return Rot * var.asDiagonal() * Rot.transpose();
}

Eigen::Vector2d Estimator::configObstacle() const {
  return {opt_.initial_obstacle_x_m, opt_.initial_obstacle_y_m};
}

Eigen::Matrix2d Estimator::configObstacleCov() const {
  const Eigen::Vector2d p = configObstacle();
  const double d = std::max(p.norm(), 1e-3), b = std::atan2(p.y(), p.x());
  const double sb = opt_.initial_obstacle_bearing_sigma_deg * M_PI / 180.0;
  const double c = std::cos(b), s = std::sin(b);
  Eigen::Matrix2d Rot;
  Rot << c, -s, s, c;
  const Eigen::Vector2d var(
      opt_.initial_obstacle_range_sigma_m * opt_.initial_obstacle_range_sigma_m,
      d * d * sb * sb + 1e-6);
  return Rot * var.asDiagonal() * Rot.transpose();
}

void Estimator::gyro(double t, double z) {
  if (!opt_.use_gyro) {
    ++stats(Sensor::Gyro).skipped;
    return;
  }
  if (!std::isfinite(z)) {
    ++stats(Sensor::Gyro).dropouts;
    return;
  }
  const double g = gate(1);
  const double R = opt_.gyro_noise_rad_s * opt_.gyro_noise_rad_s;
  record(Sensor::Gyro, t, correct(gyroModel(state(), z, R), g), g);
}

void Estimator::sonar(double t, double range) {
  SensorStats& st = stats(Sensor::Sonar);
  if (!opt_.use_sonar) {
    ++st.skipped;
    return;
  }
  if (!std::isfinite(range) || range <= 0 || range < sonar_min_m_ || range > sonar_max_m_) {
    ++st.dropouts;  // no echo / failed reading: the obstacle coasts on the model
    if (!sonar_failing_) ++st.dropout_episodes;
    sonar_failing_ = true;
    return;
  }
  sonar_failing_ = false;
  if (!obstacleInitialised()) {
    initObstacleFromSonar(range);
    ++st.used;
    consecutive_sonar_rejections_ = 0;
    return;
  }
  const double g = gate(1);
  const double R = opt_.sonar_noise_m * opt_.sonar_noise_m;
  const UpdateResult r = correct(sonarModel(state(), range, R), g);
  record(Sensor::Sonar, t, r, g);
  if (r.accepted) {
    consecutive_sonar_rejections_ = 0;
  } else if (opt_.sonar_reinit_after_rejections > 0 &&
             ++consecutive_sonar_rejections_ >= opt_.sonar_reinit_after_rejections) {
    initObstacleFromSonar(range);
    ++st.reinitialisations;
    consecutive_sonar_rejections_ = 0;
  }
}

void Estimator::pozyx(double t, const Eigen::Vector2d& z_anchor) {
  SensorStats& st = stats(Sensor::Pozyx);
  if (!opt_.use_pozyx) {
    ++st.skipped;
    return;
  }
  if (!z_anchor.allFinite()) {
    ++st.dropouts;
    return;
  }
  // p_anchor = R(yaw) p_start + t  =>  p_start = R(yaw)' (p_anchor - t).
  const double yaw = opt_.pozyx_anchor_yaw_deg * M_PI / 180.0;
  const double c = std::cos(yaw), s = std::sin(yaw);
  const Eigen::Vector2d d =
      z_anchor - Eigen::Vector2d(opt_.pozyx_anchor_x_m, opt_.pozyx_anchor_y_m);
  const Eigen::Vector2d z(c * d.x() + s * d.y(), -s * d.x() + c * d.y());
  const Eigen::Matrix2d R = opt_.pozyx_noise_m * opt_.pozyx_noise_m * Eigen::Matrix2d::Identity();
  const double g = gate(2);
  const UpdateResult r = correct(pozyxModel(state(), z, R), g);
  record(Sensor::Pozyx, t, r, g);
  if (r.accepted) {
    consecutive_pozyx_rejections_ = 0;
    pozyx_accepted_ = true;
  } else if (pozyx_accepted_ && opt_.pozyx_inflate_after_rejections > 0 && std::isfinite(r.nis) &&
             ++consecutive_pozyx_rejections_ >= opt_.pozyx_inflate_after_rejections) {
    // The filter, not the tag, has drifted and its position covariance says otherwise: add
    // alpha to the variances of x and y (d tag / d (x, y) = I, so S grows by alpha I), with
    // alpha such that y' (S + alpha I)^-1 y <= |y|^2 / (s_min + alpha) = gate, then apply.
    const Eigen::Matrix2d S = r.S;
    const double tr = S.trace(), det = S(0, 0) * S(1, 1) - S(0, 1) * S(1, 0);
    const double s_min = 0.5 * tr - std::sqrt(std::max(0.0, 0.25 * tr * tr - det));
    inflatePositionCovariance(std::max(0.0, r.innovation.squaredNorm() / g - s_min));
    if (correct(pozyxModel(state(), z, R), 0.0).accepted) {
      ++st.inflated;
      consecutive_pozyx_rejections_ = 0;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Factory and driver

std::unique_ptr<Estimator> makeEstimator(const config::WheelchairConfig& cfg, const EkfOptions& opt,
                                         const InputSignal* input) {
  if (opt.filter == FilterKind::Baseline) return std::make_unique<BaselineEkf>(cfg, opt);
  return std::make_unique<WheelchairEkf>(cfg, opt, input);
}

namespace {

enum EventKind : int { kEncStart = 0, kEncInterval = 1, kGyro = 2, kSonar = 3, kPozyx = 4 };

/// One measurement in the merged order: (t, kind), then the stream's own (time, value) order.
struct Event {
  double t = 0;
  int kind = 0;
  std::size_t stored = 0;  ///< index of the sample (interval: its closing sample) as stored
  sensors::WheelSpeedInterval iv;
  double a = 0, b = 0;  ///< gyro z / sonar range / Pozyx x, y
};

bool eventLess(const Event& x, const Event& y) {
  return std::tie(x.t, x.kind) < std::tie(y.t, y.kind);
}

/// Stream label (as in the rawlog) of an event kind.
const char* eventStream(int kind) {
  switch (kind) {
    case kEncStart:
    case kEncInterval:
      return "ENCODERS";
    case kGyro:
      return "IMU";
    case kSonar:
      return "SONAR";
    default:
      return "POZYX";
  }
}

/// The measurements of every used stream merged into one time-ordered event sequence
/// (header comment of Estimator.h), from in-memory streams or from samples pushed as read.
/// Pushed samples are released only when complete: below the watermark (see
/// io/RawlogStream.h), and only once the input signal is known past them.
class EventMerger {
 public:
  /// `counts`: the samples each stream will deliver in all.
  EventMerger(const config::WheelchairConfig& cfg, const EkfOptions& opt,
              const io::RecordingSummary& counts, InputSignal& input)
      : opt_(opt),
        input_(input),
        conv_(cfg.encoders.params, cfg.vehicle.geom.wheel_radius_m, cfg.vehicle.geom.track_width_m),
        enc_total_(counts.count(io::StreamKind::Encoders)),
        mot_total_(counts.count(io::StreamKind::Motors)) {}

  void attach(const io::Recording& rec) {
    enc_.attach(rec.encoders);
    imu_.attach(rec.imu);
    mot_.attach(rec.motors);
    son_.attach(rec.sonar);
    poz_.attach(rec.pozyx);
  }
  /// A sample as read (file order; index within its stream). Streams not used are dropped.
  void push(const io::AnySample& s, std::size_t stored) {
    if (auto* e = std::get_if<io::EncoderSample>(&s)) {
      if (opt_.use_encoders) {
        enc_.push(*e, stored);
        ++enc_pushed_;
      }
    } else if (auto* g = std::get_if<io::ImuSample>(&s)) {
      if (opt_.use_gyro) imu_.push(*g, stored);
    } else if (auto* m = std::get_if<io::MotorSample>(&s)) {
      mot_.push(*m, stored);
      ++mot_pushed_;
    } else if (auto* r = std::get_if<io::SonarSample>(&s)) {
      if (opt_.use_sonar) son_.push(*r, stored);
    } else if (auto* p = std::get_if<io::PozyxSample>(&s)) {
      if (opt_.use_pozyx) poz_.push(*p, stored);
    }
  }
  /// Everything before `t` has been pushed; `eof`: everything has.
  void setWatermark(double t, bool eof) {
    watermark_ = t;
    eof_ = eof;
  }
  bool eof() const { return eof_; }
  /// Samples pushed and not yet released (the merge window's memory).
  std::size_t buffered() const {
    return enc_.buffered() + imu_.buffered() + mot_.buffered() + son_.buffered() + poz_.buffered() +
           enc_events_.size();
  }
  /// Live input (LiveEstimator): the totals are unknown until the end; endOfInput() then
  /// sets them to what was pushed and releases everything.
  void setOpenEnded(bool motors_expected) {
    enc_total_ = std::numeric_limits<std::size_t>::max();
    mot_total_ = motors_expected ? enc_total_ : 0;
  }
  void endOfInput() {
    enc_total_ = enc_pushed_;
    mot_total_ = mot_pushed_;
    setWatermark(std::numeric_limits<double>::infinity(), true);
  }

  /// The next event if it can be decided from what was pushed so far: false with `more` set
  /// when more samples are needed, false with `more` clear at the end.
  bool next(Event& out, bool& more) {
    pumpMotors();
    pumpEncoders();
    Event best;
    bool have = false;
    const auto consider = [&](const Event& e) {
      if (!have || eventLess(e, best)) {
        best = e;
        have = true;
      }
    };
    if (!enc_events_.empty()) consider(enc_events_.front());
    if (opt_.use_gyro)
      if (const auto* s = imu_.head(watermark_))
        consider({s->t_s, kGyro, imu_.headStored(), {}, s->gyro_z_rad_s, 0});
    if (opt_.use_sonar)
      if (const auto* s = son_.head(watermark_))
        consider({s->t_s, kSonar, son_.headStored(), {}, s->range_m, 0});
    if (opt_.use_pozyx)
      if (const auto* s = poz_.head(watermark_))
        consider({s->t_s, kPozyx, poz_.headStored(), {}, s->x_m, s->y_m});
    more = false;
    if (!have) {
      more = !eof_;
      return false;
    }
    // Anything not yet known comes at or after the watermark; a pending encoder start (first
    // sample seen, no interval yet) would come at its reference time, before same-time events.
    double bound = eof_ ? std::numeric_limits<double>::infinity() : watermark_;
    if (conv_.started() && !first_interval_ && enc_used_ < enc_total_)
      bound = std::min(bound, conv_.referenceTime());
    const bool input_known = motor_t_max_ > best.t || mot_used_ >= mot_total_;
    if (!(best.t < bound) || !input_known) {
      more = true;  // (at the end of the file both conditions hold)
      return false;
    }
    out = best;
    switch (best.kind) {
      case kEncStart:
      case kEncInterval:
        enc_events_.pop_front();
        break;
      case kGyro:
        imu_.pop();
        break;
      case kSonar:
        son_.pop();
        break;
      default:
        poz_.pop();
    }
    return true;
  }

 private:
  void pumpMotors() {
    while (const auto* m = mot_.head(watermark_)) {
      input_.add(*m);
      motor_t_max_ = m->t_s;
      mot_.pop();
      ++mot_used_;
    }
  }
  void pumpEncoders() {
    if (!opt_.use_encoders) return;
    while (enc_events_.empty()) {
      const auto* s = enc_.head(watermark_);
      if (!s) return;
      if (!conv_.started()) start_stored_ = enc_.headStored();
      const std::size_t stored = enc_.headStored();
      const auto iv = conv_.add(*s);
      enc_.pop();
      ++enc_used_;
      if (!iv) continue;
      if (!first_interval_) {
        first_interval_ = true;
        enc_events_.push_back({iv->t0_s, kEncStart, start_stored_, {}, 0, 0});
      }
      enc_events_.push_back({iv->t1_s, kEncInterval, stored, *iv, 0, 0});
    }
  }

  const EkfOptions& opt_;
  InputSignal& input_;
  sensors::WheelSpeedConverter conv_;
  io::SortedStream<io::EncoderSample> enc_{io::encoderLess};
  io::SortedStream<io::ImuSample> imu_{io::imuLess};
  io::SortedStream<io::MotorSample> mot_{io::motorLess};
  io::SortedStream<io::SonarSample> son_{io::sonarLess};
  io::SortedStream<io::PozyxSample> poz_{io::pozyxLess};
  std::deque<Event> enc_events_;
  std::size_t start_stored_ = 0;
  bool first_interval_ = false;
  std::size_t enc_total_, mot_total_, enc_used_ = 0, mot_used_ = 0;
  std::size_t enc_pushed_ = 0, mot_pushed_ = 0;
  double motor_t_max_ = -std::numeric_limits<double>::infinity();
  double watermark_ = std::numeric_limits<double>::infinity();
  bool eof_ = true;
};

/// Where the samples come from: a recording in memory, or a rawlog read as a stream.
struct Source {
  const io::Recording* rec = nullptr;
  const std::string* path = nullptr;
  io::RecordingSummary summary;
  /// One pass (runEstimatorOnePass): `summary` unknown, made while reading into *scanned.
  io::RecordingSummary* scanned = nullptr;
};

/// runEstimatorOnePass cannot guarantee the two-pass result (see Estimator.h).
struct NotOnePass {};

/// A one-pass run gives up (NotOnePass) when the merge holds more samples than this (~6 MB):
/// a file without motor currents, whose measurements all wait for an input that never comes.
constexpr std::size_t kOnePassMaxBuffered = std::size_t(1) << 16;

/// Books the samples of the streams the options leave out as skipped and returns the number
/// of measurements of the others (progress, and the result's size when stored).
std::size_t countStreams(const EkfOptions& opt, const io::RecordingSummary& counts,
                         EstimationResult& res) {
  using io::StreamKind;
  const std::pair<bool, StreamKind> used[] = {{opt.use_encoders, StreamKind::Encoders},
                                              {opt.use_gyro, StreamKind::Imu},
                                              {opt.use_sonar, StreamKind::Sonar},
                                              {opt.use_pozyx, StreamKind::Pozyx}};
  const Sensor sensor[] = {Sensor::Encoders, Sensor::Gyro, Sensor::Sonar, Sensor::Pozyx};
  std::size_t n = 0;
  for (int k = 0; k < 4; ++k) {
    if (used[k].first)
      n += counts.count(used[k].second);
    else
      res.sensors[int(sensor[k])].skipped = long(counts.count(used[k].second));
  }
  return n;
}

/// The measurement update of one event (the state already predicted to its time).
void applyEvent(Estimator& est, const Event& e) {
  switch (e.kind) {
    case kEncStart:
      est.encoderStart(e.t);
      break;
    case kEncInterval:
      est.encoderInterval(e.iv);
      break;
    case kGyro:
      est.gyro(e.t, e.a);
      break;
    case kSonar:
      est.sonar(e.t, e.a);
      break;
    case kPozyx:
      est.pozyx(e.t, Eigen::Vector2d(e.a, e.b));
      break;
  }
}

/// The filter step of one event: predict to its time, then its measurement update.
void stepEvent(Estimator& est, const Event& e) {
  est.predictTo(e.t);
  applyEvent(est, e);
}

/// Runs f(); a failure of the filter (e.g. CVODE after a clock jump) is rethrown naming the
/// measurement being processed: stream, sample index as stored (0-based) and time.
template <typename F>
void namedEvent(const Event& e, const F& f) {
  try {
    f();
  } catch (const std::exception& ex) {
    throw std::runtime_error(fmt::format("{} sample {} (t = {:.6f} s): {}", eventStream(e.kind),
                                         e.stored, e.t, ex.what()));
  }
}

// What the run leaves besides the estimates: the last estimate, the physics filter's CVODE
// statistics, sensor errors and health events, and a failing sonar's dropout episodes.
void finishResult(const Estimator& est, double t0, EstimationResult& res) {
  if (!res.estimates.empty()) res.last = res.estimates.back();
  if (const auto* w = dynamic_cast<const WheelchairEkf*>(&est)) {
    res.cvode = w->filter().stats();
    res.sensor_errors = w->sensorErrors();
    res.health = w->healthEvents();
  }
  if (const SensorStats& so = res.stats(Sensor::Sonar); so.dropout_episodes > 0)
    res.health.push_back(sonarDropoutEvent(so, est.time(), t0));
}

EstimationResult runEstimatorImpl(const Source& src, const config::WheelchairConfig& cfg,
                                  const EkfOptions& options, EstimateSink* sink,
                                  const std::function<void(double)>& progress) {
  EkfOptions opt = options;
  opt.resolveSensorDefaults(cfg);
  opt.validate();
  const auto& counts = src.summary;
  using io::StreamKind;

  InputSignal input(opt.input_interpolation);
  auto est = makeEstimator(cfg, opt, &input);
  est->keepNisRecords(sink == nullptr);
  EstimationResult& res = est->result();
  const std::size_t n_expected = countStreams(opt, counts, res);

  EventMerger merger(cfg, opt, counts, input);
  std::optional<io::RawlogWindowReader> reader;
  const bool one_pass = src.scanned != nullptr;
  if (src.rec) {
    merger.attach(*src.rec);
  } else if (one_pass) {  // totals unknown: as a live run, with the file assumed in order
    reader.emplace(*src.path, 0.0);
    merger.setOpenEnded(true);
    merger.setWatermark(reader->watermark(), false);
  } else {
    reader.emplace(*src.path, counts.lateness_s);
    merger.setWatermark(reader->watermark(), false);
  }
  // Reads a block of samples and moves the watermark.
  const auto feed = [&] {
    reader->read([&](const io::AnySample& s, std::size_t k) { merger.push(s, k); });
    if (one_pass) {
      if (reader->latenessSeen() > 0 || merger.buffered() > kOnePassMaxBuffered) throw NotOnePass{};
      if (reader->eof()) return merger.endOfInput();
    }
    merger.setWatermark(reader->watermark(), reader->eof());
  };
  const auto nextEvent = [&](Event& e) {
    bool more = false;
    while (!merger.next(e, more)) {
      if (!more) return false;
      feed();
    }
    return true;
  };

  Event E, N;
  bool have = nextEvent(E);
  if (!have) {
    if (one_pass) throw NotOnePass{};
    res.warnings.push_back("no measurements: nothing estimated");
    return std::move(res);
  }
  if (opt.filter == FilterKind::Physics && counts.count(StreamKind::Motors) == 0 && !one_pass)
    res.warnings.push_back("no motor currents: the input is held at 0 A");

  const double t0 = E.t;
  est->start(t0);
  const bool fixed_rate = opt.output_rate_hz > 0;
  // Sized once: growing a vector of ~0.5 kB samples by doubling was a third of the baseline
  // filter's time (copies and first-touch page faults; docs/benchmarks.md). A sink keeps
  // nothing: memory stays flat however long the drive.
  if (!sink) {
    res.estimates.reserve(
        fixed_rate ? static_cast<std::size_t>((counts.end_s - t0) * opt.output_rate_hz) + 2
                   : n_expected);
    res.nis.reserve(n_expected);
  }
  const auto emit = [&](const EstimateSample& s) {
    ++res.n_estimates;
    if (sink) {
      sink->add(s);
      res.last = s;
    } else {
      res.estimates.push_back(s);
    }
  };
  long k_out = 0;
  auto nextOut = [&] { return t0 + static_cast<double>(k_out) / opt.output_rate_hz; };
  const auto processEvent = [&](const Event& e) {
    if (fixed_rate) {
      while (nextOut() <= e.t) {
        est->predictTo(nextOut());
        EstimateSample s = est->estimate();
        s.t_s = nextOut();
        emit(s);
        ++k_out;
      }
    }
    stepEvent(*est, e);
  };
  const auto named = [](const Event& e, const auto& f) { namedEvent(e, f); };
  // One pass: the share of the file read (the number of measurements is not known yet).
  const std::size_t progress_every = one_pass ? 4096 : std::max<std::size_t>(1, n_expected / 100);
  std::size_t done = 0;
  while (have) {
    if (progress && done % progress_every == 0)
      progress(one_pass ? reader->fractionRead()
                        : std::min(1.0, static_cast<double>(done) /
                                            std::max<std::size_t>(n_expected, 1)));
    named(E, [&] { processEvent(E); });
    ++done;
    // Samples of the input signal the filter has passed are dropped (streaming only).
    if (reader) input.discardBefore(E.t - 1.0);
    have = nextEvent(N);
    // One output per measurement time (after all measurements of that time).
    if (!fixed_rate && (!have || N.t != E.t)) named(E, [&] { emit(est->estimate()); });
    E = N;
  }
  if (one_pass) {
    *src.scanned = reader->summary();
    // Without motor currents the two-pass run warns before its first measurement.
    if (src.scanned->count(StreamKind::Motors) == 0) throw NotOnePass{};
    countStreams(opt, *src.scanned, res);  // the skipped streams' counts
  }
  finishResult(*est, t0, res);
  return std::move(res);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Live run (capture --health)

struct LiveEstimator::Impl {
  Impl(const config::WheelchairConfig& cfg, const EkfOptions& options, bool motors_expected)
      : opt(resolved(options, cfg)),
        input(opt.input_interpolation),
        est(makeEstimator(cfg, opt, &input)),
        merger(cfg, opt, io::RecordingSummary{}, input) {
    est->keepNisRecords(false);
    merger.setOpenEnded(motors_expected);
    merger.setWatermark(-std::numeric_limits<double>::infinity(), false);
  }
  static EkfOptions resolved(EkfOptions o, const config::WheelchairConfig& cfg) {
    o.resolveSensorDefaults(cfg);
    o.validate();
    return o;
  }
  /// Every event the merger can release now through the filter step (runEstimator's step,
  /// without the estimate outputs: the live run keeps only the last estimate).
  void drain() {
    Event e;
    bool more = false;
    while (merger.next(e, more)) {
      if (!started) {
        t0 = e.t;
        est->start(t0);
        started = true;
      }
      namedEvent(e, [&] { stepEvent(*est, e); });
      input.discardBefore(e.t - 1.0);
    }
  }
  const std::vector<HealthEvent>& health() const {
    static const std::vector<HealthEvent> none;
    if (finished) return est->result().health;
    const auto* w = dynamic_cast<const WheelchairEkf*>(est.get());
    return w ? w->healthEvents() : none;
  }

  EkfOptions opt;
  InputSignal input;
  std::unique_ptr<Estimator> est;
  EventMerger merger;
  std::array<std::size_t, io::kNumStreams> stored{};
  double watermark = -std::numeric_limits<double>::infinity();
  double start_s = std::numeric_limits<double>::infinity(), t0 = 0;
  std::size_t late = 0;
  bool started = false, finished = false;
};

LiveEstimator::LiveEstimator(const config::WheelchairConfig& cfg, const EkfOptions& opt,
                             bool motors_expected)
    : impl_(std::make_unique<Impl>(cfg, opt, motors_expected)) {}

LiveEstimator::~LiveEstimator() = default;

void LiveEstimator::push(const io::AnySample& s) {
  auto& m = *impl_;
  if (m.finished) throw std::logic_error("LiveEstimator::push after finish");
  const double t = io::timeOf(s);
  m.start_s = std::min(m.start_s, t);
  if (t < m.watermark) {  // older than samples already released: cannot be merged any more
    ++m.late;
    return;
  }
  m.merger.push(s, m.stored[s.index()]++);
  if (t > m.watermark) {
    m.watermark = t;
    m.merger.setWatermark(t, false);
    m.drain();
  }
}

void LiveEstimator::finish() {
  auto& m = *impl_;
  if (m.finished) return;
  m.merger.endOfInput();
  m.drain();
  auto& res = m.est->result();
  if (!m.started) {
    res.warnings.push_back("no measurements: nothing estimated");
  } else {
    res.last = m.est->estimate();
    res.n_estimates = 1;
    finishResult(*m.est, m.t0, res);
  }
  m.finished = true;
}

const std::vector<HealthEvent>& LiveEstimator::health() const {
  return impl_->health();
}
double LiveEstimator::startTime() const {
  return impl_->start_s;
}
std::size_t LiveEstimator::late() const {
  return impl_->late;
}
const EstimationResult& LiveEstimator::result() const {
  return impl_->est->result();
}

EstimationResult runEstimator(const io::Recording& rec, const config::WheelchairConfig& cfg,
                              const EkfOptions& options,
                              const std::function<void(double)>& progress) {
  return runEstimatorImpl({&rec, nullptr, io::summarize(rec)}, cfg, options, nullptr, progress);
}

EstimationResult runEstimator(const io::Recording& rec, const config::WheelchairConfig& cfg,
                              const EkfOptions& options, EstimateSink& sink,
                              const std::function<void(double)>& progress) {
  return runEstimatorImpl({&rec, nullptr, io::summarize(rec)}, cfg, options, &sink, progress);
}

EstimationResult runEstimator(const std::string& rawlog, const io::RecordingSummary& summary,
                              const config::WheelchairConfig& cfg, const EkfOptions& options,
                              EstimateSink& sink, const std::function<void(double)>& progress) {
  return runEstimatorImpl({nullptr, &rawlog, summary}, cfg, options, &sink, progress);
}

std::optional<EstimationResult> runEstimatorOnePass(const std::string& rawlog,
                                                    const config::WheelchairConfig& cfg,
                                                    const EkfOptions& options, EstimateSink& sink,
                                                    io::RecordingSummary& summary,
                                                    const std::function<void(double)>& progress) {
  try {
    return runEstimatorImpl({nullptr, &rawlog, {}, &summary}, cfg, options, &sink, progress);
  } catch (const NotOnePass&) {
    return std::nullopt;
  }
}

EstimatorFamily selectEstimator(const io::RecordingSummary& rec, const std::string& forced) {
  if (forced == "command") return EstimatorFamily::CommandDriven;
  if (!forced.empty()) return EstimatorFamily::Wheelchair;
  using io::StreamKind;
  const bool wheelchair_streams = rec.count(StreamKind::Encoders) || rec.count(StreamKind::Imu) ||
                                  rec.count(StreamKind::Sonar) || rec.count(StreamKind::Pozyx);
  io::Recording meta_only;
  meta_only.meta = rec.meta;
  const bool landmarks = rec.count(StreamKind::Landmarks) || !io::landmarkMap(meta_only).empty();
  return landmarks && !wheelchair_streams ? EstimatorFamily::CommandDriven
                                          : EstimatorFamily::Wheelchair;
}

EstimatorFamily selectEstimator(const io::Recording& rec, const std::string& forced) {
  return selectEstimator(io::summarize(rec), forced);
}

}  // namespace wheelchair::estimation
