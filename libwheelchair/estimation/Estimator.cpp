#include "libwheelchair/estimation/Estimator.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/estimation/BaselineEkf.h"
#include "libwheelchair/stats/Distributions.h"
#include "libwheelchair/estimation/WheelchairEkf.h"

#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
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

namespace {
bool motorLess(const io::MotorSample& a, const io::MotorSample& b) {
  return std::tie(a.t_s, a.current_right_A, a.current_left_A, a.vrc_right_V, a.vrc_left_V) <
         std::tie(b.t_s, b.current_right_A, b.current_left_A, b.vrc_right_V, b.vrc_left_V);
}
}  // namespace

void InputSignal::setSamples(std::vector<io::MotorSample> s) {
  std::sort(s.begin(), s.end(), motorLess);
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
  SensorStats& st = stats(s);
  st.dof = r.dof;
  if (keep_nis_records_) res_.nis.push_back({t, s, r.nis, r.dof, r.accepted});
  if (r.accepted) {
    ++st.used;
    ++st.nis_count;
    st.nis_sum += r.nis;
    // Two-sided 95 % band of one chi2(dof) value (cached through gates_ with negative keys).
    auto q = [this](double p, int dof, int key) {
      auto it = gates_.find(key);
      if (it != gates_.end()) return it->second;
      return gates_[key] = stats::chi2Quantile(p, dof);
    };
    const double lo = q(0.025, r.dof, -2 * r.dof), hi = q(0.975, r.dof, -2 * r.dof - 1);
    if (r.nis >= lo && r.nis <= hi) ++st.nis_inside95;
  } else {
    ++st.rejected;
    res_.rejected.push_back({t, s, r.nis, r.dof, g, r.innovation});
  }
}

Eigen::Matrix2d Estimator::encoderNoise(double dt) const {
  double var_u = opt_.encoder_extra_noise_m_s * opt_.encoder_extra_noise_m_s;
  if (opt_.encoder_quantisation) {
    const double tick_m = wheel_radius_m_ * wheel_rad_per_tick_;
    var_u += tick_m * tick_m / 6.0 / (dt * dt);
  }
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
  record(Sensor::Gyro, t, gyroUpdate(z, opt_.gyro_noise_rad_s * opt_.gyro_noise_rad_s, g), g);
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
  const UpdateResult r = sonarUpdate(range, opt_.sonar_noise_m * opt_.sonar_noise_m, g);
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
  record(Sensor::Pozyx, t, pozyxUpdate(z, R, g), g);
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

struct Event {
  double t;
  int kind;
  std::size_t index;
};

/// The stream itself when it is already in `less` order (the usual, time-ordered recording:
/// no copy; `order` stays empty, meaning the identity), else a stable-sorted copy kept in
/// `store`, with in `order` the index in v of each sorted element (to name a sample as stored
/// when something fails).
template <typename T, typename Less>
const std::vector<T>& sortedView(const std::vector<T>& v, std::vector<T>& store,
                                 std::vector<std::size_t>& order, Less less) {
  if (std::is_sorted(v.begin(), v.end(), less)) return v;
  order.resize(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return less(v[a], v[b]); });
  store.clear();
  store.reserve(v.size());
  for (const std::size_t i : order) store.push_back(v[i]);
  return store;
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

EstimationResult runEstimatorImpl(const io::Recording& rec, const config::WheelchairConfig& cfg,
                                  const EkfOptions& options, EstimateSink* sink,
                                  const std::function<void(double)>& progress) {
  EkfOptions opt = options;
  opt.resolveSensorDefaults(cfg);
  opt.validate();

  InputSignal input(opt.input_interpolation);
  input.setSamples(rec.motors);
  auto est = makeEstimator(cfg, opt, &input);
  est->keepNisRecords(sink == nullptr);
  EstimationResult& res = est->result();

  // Every stream sorted by (time, value): the same multiset of samples gives the same order.
  // order[k][i]: index in the recording's stream of the i-th sorted sample (error messages;
  // empty when the stream was stored in order).
  std::array<std::vector<std::size_t>, 5> order;
  std::vector<io::EncoderSample> enc_store;
  std::vector<io::ImuSample> imu_store;
  std::vector<io::SonarSample> son_store;
  std::vector<io::PozyxSample> poz_store;
  const auto& enc = sortedView(rec.encoders, enc_store, order[kEncStart],
                               [](const io::EncoderSample& a, const io::EncoderSample& b) {
                                 return std::tie(a.t_s, a.right_ticks, a.left_ticks) <
                                        std::tie(b.t_s, b.right_ticks, b.left_ticks);
                               });
  const auto& imu = sortedView(rec.imu, imu_store, order[kGyro],
                               [](const io::ImuSample& a, const io::ImuSample& b) {
                                 return std::tie(a.t_s, a.gyro_z_rad_s) <
                                        std::tie(b.t_s, b.gyro_z_rad_s);
                               });
  const auto& son = sortedView(rec.sonar, son_store, order[kSonar],
                               [](const io::SonarSample& a, const io::SonarSample& b) {
                                 return std::tie(a.t_s, a.range_m) < std::tie(b.t_s, b.range_m);
                               });
  const auto& poz = sortedView(rec.pozyx, poz_store, order[kPozyx],
                               [](const io::PozyxSample& a, const io::PozyxSample& b) {
                                 return std::tie(a.t_s, a.x_m, a.y_m) <
                                        std::tie(b.t_s, b.x_m, b.y_m);
                               });

  std::vector<Event> ev;
  std::vector<sensors::WheelSpeedInterval> iv;
  if (opt.use_encoders) {
    iv = sensors::wheelSpeedsFromTicks(enc, cfg.encoders.params, cfg.vehicle.geom);
    if (!iv.empty()) ev.push_back({iv.front().t0_s, kEncStart, 0});
    for (std::size_t i = 0; i < iv.size(); ++i) ev.push_back({iv[i].t1_s, kEncInterval, i});
  } else {
    res.sensors[int(Sensor::Encoders)].skipped = static_cast<long>(enc.size());
  }
  auto addStream = [&](bool use, std::size_t n, const auto& timeOf, int kind, Sensor s) {
    if (!use) {
      res.sensors[int(s)].skipped = static_cast<long>(n);
      return;
    }
    for (std::size_t i = 0; i < n; ++i) ev.push_back({timeOf(i), kind, i});
  };
  addStream(
      opt.use_gyro, imu.size(), [&](std::size_t i) { return imu[i].t_s; }, kGyro, Sensor::Gyro);
  addStream(
      opt.use_sonar, son.size(), [&](std::size_t i) { return son[i].t_s; }, kSonar, Sensor::Sonar);
  addStream(
      opt.use_pozyx, poz.size(), [&](std::size_t i) { return poz[i].t_s; }, kPozyx, Sensor::Pozyx);
  std::stable_sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) {
    return std::tie(a.t, a.kind, a.index) < std::tie(b.t, b.kind, b.index);
  });
  if (ev.empty()) {
    res.warnings.push_back("no measurements: nothing estimated");
    return std::move(res);
  }
  if (opt.filter == FilterKind::Physics && input.empty())
    res.warnings.push_back("no motor currents: the input is held at 0 A");

  const double t0 = ev.front().t;
  est->start(t0);
  const bool fixed_rate = opt.output_rate_hz > 0;
  // Sized once: growing a vector of ~0.5 kB samples by doubling was a third of the baseline
  // filter's time (copies and first-touch page faults; docs/benchmarks.md). A sink keeps
  // nothing: memory stays flat however long the drive.
  if (!sink) {
    res.estimates.reserve(
        fixed_rate ? static_cast<std::size_t>((ev.back().t - t0) * opt.output_rate_hz) + 2
                   : ev.size());
    res.nis.reserve(ev.size());
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
  const std::size_t progress_every = std::max<std::size_t>(1, ev.size() / 100);
  const auto processEvent = [&](std::size_t e) {
    const Event& E = ev[e];
    if (fixed_rate) {
      while (nextOut() <= E.t) {
        est->predictTo(nextOut());
        EstimateSample s = est->estimate();
        s.t_s = nextOut();
        emit(s);
        ++k_out;
      }
    }
    est->predictTo(E.t);
    switch (E.kind) {
      case kEncStart:
        est->encoderStart(E.t);
        break;
      case kEncInterval:
        est->encoderInterval(iv[E.index]);
        break;
      case kGyro:
        est->gyro(E.t, imu[E.index].gyro_z_rad_s);
        break;
      case kSonar:
        est->sonar(E.t, son[E.index].range_m);
        break;
      case kPozyx:
        est->pozyx(E.t, Eigen::Vector2d(poz[E.index].x_m, poz[E.index].y_m));
        break;
    }
    // One output per measurement time (after all measurements of that time).
    if (!fixed_rate && (e + 1 == ev.size() || ev[e + 1].t != E.t)) emit(est->estimate());
  };
  // Names the measurement being processed when a filter fails (e.g. CVODE after a clock jump):
  // stream, sample index as stored in the recording (0-based) and time.
  const auto describe = [&](const Event& E) {
    std::size_t sorted = E.index;
    if (E.kind == kEncInterval) {
      // The interval ends at an encoder sample: find it among the sorted samples.
      const auto it =
          std::lower_bound(enc.begin(), enc.end(), iv[E.index].t1_s,
                           [](const io::EncoderSample& a, double t) { return a.t_s < t; });
      sorted = static_cast<std::size_t>(it - enc.begin());
    } else if (E.kind == kEncStart) {
      sorted = 0;
    }
    const auto& ord = order[E.kind == kEncInterval ? kEncStart : E.kind];
    const std::size_t stored = sorted < ord.size() ? ord[sorted] : sorted;
    return fmt::format("{} sample {} (t = {:.6f} s)", eventStream(E.kind), stored, E.t);
  };
  for (std::size_t e = 0; e < ev.size(); ++e) {
    const Event& E = ev[e];
    if (progress && e % progress_every == 0) progress(static_cast<double>(e) / ev.size());
    try {
      processEvent(e);
    } catch (const std::exception& ex) {
      throw std::runtime_error(fmt::format("{}: {}", describe(E), ex.what()));
    }
  }
  if (!res.estimates.empty()) res.last = res.estimates.back();
  if (auto* w = dynamic_cast<WheelchairEkf*>(est.get())) {
    res.cvode = w->filter().stats();
    res.sensor_errors = w->sensorErrors();
    res.health = w->healthEvents();
  }
  if (const SensorStats& so = res.stats(Sensor::Sonar); so.dropout_episodes > 0) {
    HealthEvent e;  // a failing sensor: excluded while it fails, its episodes counted
    e.t_s = est->time();
    e.sensor = "sonar";
    e.kind = "dropouts";
    e.parameter = "episodes";
    e.value = static_cast<double>(so.dropout_episodes);
    e.since_s = t0;
    e.text = fmt::format(
        "sonar gave no valid range (0 or out of range) {} times in {} episodes, "
        "excluded while it did",
        so.dropouts, so.dropout_episodes);
    res.health.push_back(e);
  }
  return std::move(res);
}

}  // namespace

EstimationResult runEstimator(const io::Recording& rec, const config::WheelchairConfig& cfg,
                              const EkfOptions& options,
                              const std::function<void(double)>& progress) {
  return runEstimatorImpl(rec, cfg, options, nullptr, progress);
}

EstimationResult runEstimator(const io::Recording& rec, const config::WheelchairConfig& cfg,
                              const EkfOptions& options, EstimateSink& sink,
                              const std::function<void(double)>& progress) {
  return runEstimatorImpl(rec, cfg, options, &sink, progress);
}

}  // namespace wheelchair::estimation
