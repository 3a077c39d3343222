#include "libwheelchair/visualization/DriveData.h"

#include "libwheelchair/estimation/ModelExtensions.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"
#include "libwheelchair/model/Kinematics.h"
#include "libwheelchair/visualization/Plot.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <variant>

namespace wheelchair::visualization {

bool TruthInfo::poseAt(double t, double& x, double& y, double& phi) const {
  if (t_s.empty()) return false;
  if (t <= t_s.front()) {
    x = x_m.front(), y = y_m.front(), phi = phi_rad.front();
    return true;
  }
  if (t >= t_s.back()) {
    x = x_m.back(), y = y_m.back(), phi = phi_rad.back();
    return true;
  }
  const std::size_t k = std::upper_bound(t_s.begin(), t_s.end(), t) - t_s.begin();
  const double a = (t - t_s[k - 1]) / (t_s[k] - t_s[k - 1]);
  x = x_m[k - 1] + a * (x_m[k] - x_m[k - 1]);
  y = y_m[k - 1] + a * (y_m[k] - y_m[k - 1]);
  phi = phi_rad[k - 1] + a * model::wrapAngle(phi_rad[k] - phi_rad[k - 1]);
  return true;
}

std::optional<TruthInfo> readTruthJson(const std::string& path) {
  if (!std::filesystem::exists(path)) return std::nullopt;
  std::ifstream in(path);
  TruthInfo t;
  try {
    // The trajectory's columns (~10 numbers per 100 Hz step: a DOM of a one-hour truth file
    // needs ~1 GB) go straight into the vectors and are discarded from the parsed document;
    // the rest (anchor, obstacles, effects) is parsed as usual.
    const std::map<std::string, std::vector<double>*> wanted{
        {"t_s", &t.t_s},         {"x_m", &t.x_m},     {"y_m", &t.y_m},
        {"phi_rad", &t.phi_rad}, {"v_m_s", &t.v_m_s}, {"omega_rad_s", &t.omega_rad_s}};
    std::string top_key, column;
    const nlohmann::json::parser_callback_t keep = [&](int depth, nlohmann::json::parse_event_t ev,
                                                       nlohmann::json& parsed) {
      using E = nlohmann::json::parse_event_t;
      if (ev == E::key && depth == 1) top_key = parsed.get<std::string>();
      if (ev == E::key && depth == 2) column = parsed.get<std::string>();
      if (top_key != "trajectory" || depth < 3) return true;
      if (ev == E::value && depth == 3) {
        const auto it = wanted.find(column);
        if (it != wanted.end()) it->second->push_back(parsed.get<double>());
      }
      return false;  // nothing of a trajectory column stays in the document
    };
    const auto j = nlohmann::json::parse(in, keep);
    if (!j.contains("trajectory")) throw std::runtime_error("no \"trajectory\"");
    const std::size_t n = t.t_s.size();
    if (t.x_m.size() != n || t.y_m.size() != n || t.phi_rad.size() != n)
      throw std::runtime_error("trajectory columns of unequal length");
    for (const auto& o : j.value("obstacles", nlohmann::json::array()))
      t.obstacles.push_back(
          {o.at("x_m").get<double>(), o.at("y_m").get<double>(), o.value("radius_m", 0.05)});
    if (j.contains("pozyx_anchor")) {
      const auto& a = j.at("pozyx_anchor");
      t.anchor_x_m = a.value("x_m", 0.0);
      t.anchor_y_m = a.value("y_m", 0.0);
      t.anchor_yaw_rad = a.value("yaw_rad", 0.0);
    }
    t.scenario = j.value("scenario", "");
    for (const auto& e : j.value("effects", nlohmann::json::array()))
      t.effects += (t.effects.empty() ? "" : "; ") + e.value("text", std::string());
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": not a readable truth file: " + e.what());
  }
  return t;
}

const estimation::EstimateSample* DriveData::ekfAt(double t) const {
  const auto& v = est.ekf.estimates;
  if (v.empty()) return nullptr;
  auto it =
      std::upper_bound(v.begin(), v.end(), t,
                       [](double tt, const estimation::EstimateSample& s) { return tt < s.t_s; });
  if (it == v.begin()) return &v.front();
  return &*(it - 1);
}

DriveData loadDrive(const std::string& path, const config::WheelchairConfig& cfg,
                    const evaluation::MetricOptions& metric_options,
                    const std::string& truth_path) {
  return loadDrive(io::readRawlog(path), path, cfg, metric_options, truth_path);
}

namespace {

EkfTracePoint tracePoint(const DriveData& d, const estimation::EstimateSample& e) {
  EkfTracePoint p;
  p.t_s = e.t_s;
  p.v_m_s = e.x(0);
  p.omega_rad_s = e.x(1);
  p.obstacle = predictedSonarRange(d, e, p.range_m, p.range_sd_m);
  return p;
}

// Middle of the first run of valid (non-zero) sonar readings (runs separated by > 2 s of
// dropouts); NaN without any.
double firstSonarRunMiddle(const io::Recording& rec) {
  double a = NAN, b = NAN;
  for (const auto& s : rec.sonar) {
    if (!(s.range_m > 0)) continue;
    if (std::isnan(a)) {
      a = b = s.t_s;
    } else if (s.t_s - b > 2.0) {
      break;
    } else {
      b = s.t_s;
    }
  }
  return std::isnan(a) ? NAN : a + 0.5 * (b - a);
}

// A long time series kept as it comes (time order), thinned to what its figure draws
// (docs/visualization.md, "Long drives"): of each bin of `bin_s` seconds (from `t_start_s`; of
// `fine_bin_s` inside [fine_a_s, fine_b_s], Fig. 8's zoomed window), the first, the last and the
// lowest and highest of each drawn quantity, in their order. A bin also ends where `key`
// changes, so each run of equal key keeps its first and last sample (motion phases, obstacle
// spans: exact), and at a non-finite quantity (kept: it breaks the line). The drawing's own
// rule (Plot::kDecimateAbove: first, lowest, highest, last per 1/3 px column) then keeps the same
// points up to the columns a bin straddles. bin_s <= 0: every sample is kept.
template <class T>
class SeriesThinner {
 public:
  using Value = std::function<double(const T&)>;
  SeriesThinner(std::vector<T>& out, std::vector<Value> values, std::function<int(const T&)> key,
                double t_start_s, double bin_s)
      : out_(out),
        values_(std::move(values)),
        key_(std::move(key)),
        t0_(t_start_s),
        bin_s_(bin_s) {}
  void fineWindow(double a_s, double b_s, double bin_s) {
    fine_a_ = a_s, fine_b_ = b_s, fine_ = bin_s;
  }
  void add(const T& s) {
    if (!(bin_s_ > 0)) {
      out_.push_back(s);
      return;
    }
    bool finite = std::isfinite(s.t_s);
    for (const auto& v : values_) finite = finite && std::isfinite(v(s));
    const int k = key_ ? key_(s) : 0;
    const double b = binOf(s.t_s);
    if (n_ > 0 && (!finite || b != bin_ || k != key_now_)) flush();
    if (!finite) {
      out_.push_back(s);
      return;
    }
    if (n_ == 0) {
      bin_ = b, key_now_ = k, first_ = s;
      lo_.assign(values_.size(), {0, s});
      hi_.assign(values_.size(), {0, s});
      lo_x_.resize(values_.size());
      hi_x_.resize(values_.size());
    }
    for (std::size_t j = 0; j < values_.size(); ++j) {
      const double x = values_[j](s);
      if (n_ == 0) lo_x_[j] = hi_x_[j] = x;
      if (x < lo_x_[j]) lo_[j] = {n_, s}, lo_x_[j] = x;
      if (x > hi_x_[j]) hi_[j] = {n_, s}, hi_x_[j] = x;
    }
    last_ = {n_, s};
    ++n_;
  }
  void finish() { flush(); }

 private:
  double binOf(double t) const {
    if (fine_ > 0 && t >= fine_a_ && t <= fine_b_) return 1e15 + std::floor((t - fine_a_) / fine_);
    return std::floor((t - t0_) / bin_s_);
  }
  void flush() {
    if (n_ == 0) return;
    std::vector<std::pair<std::size_t, T>>& keep = keep_;  // (scratch: no allocation per bin)
    keep.assign({{0, first_}, last_});
    keep.insert(keep.end(), lo_.begin(), lo_.end());
    keep.insert(keep.end(), hi_.begin(), hi_.end());
    std::stable_sort(keep.begin(), keep.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    for (std::size_t i = 0; i < keep.size(); ++i)
      if (i == 0 || keep[i].first != keep[i - 1].first) out_.push_back(keep[i].second);
    n_ = 0;
  }
  std::vector<T>& out_;
  std::vector<Value> values_;
  std::function<int(const T&)> key_;
  double t0_, bin_s_, fine_a_ = NAN, fine_b_ = NAN, fine_ = 0;
  double bin_ = 0;
  int key_now_ = 0;
  std::size_t n_ = 0;  // samples in the current bin
  T first_{};
  std::pair<std::size_t, T> last_{};
  std::vector<std::pair<std::size_t, T>> lo_, hi_, keep_;
  std::vector<double> lo_x_, hi_x_;  // their values (not recomputed per sample)
};

/// Bins a figure's time span is cut into by SeriesThinner on a long drive (~3 per 1/3 px
/// column of the default 1000 px figure).
constexpr double kThinBins = 8192;

// The EKF's estimates of a streamed run (DriveLoadOptions::keep_estimates false): the trace,
// the poses, and the full estimates at the start and at the snapshot time (the last one at or
// before it; `since_start_s` after the first estimate, or the absolute `at_s`).
class ReportEkfSink : public estimation::EstimateSink {
 public:
  ReportEkfSink(const DriveData& d, double since_start_s, double at_s)
      : d_(d), since_start_s_(since_start_s), at_s_(at_s) {}
  /// The trace points go to `f` (a SeriesThinner) instead of being stored.
  void traceTo(std::function<void(const EkfTracePoint&)> f) { trace_to_ = std::move(f); }
  void add(const estimation::EstimateSample& e) override {
    if (trace_to_)
      trace_to_(tracePoint(d_, e));
    else
      d_trace_.push_back(tracePoint(d_, e));
    poses_.add(e);
    if (!first_) {
      first_ = e;
      if (std::isfinite(since_start_s_)) at_s_ = e.t_s + since_start_s_;
    }
    if (e.t_s <= at_s_) snapshot_ = e;
  }
  /// Room for n estimates at once (no doubling slack on a long drive).
  void reserve(std::size_t n) {
    if (!trace_to_) d_trace_.reserve(n);
    poses_.reserve(n);
  }
  std::vector<EkfTracePoint> takeTrace() { return std::move(d_trace_); }
  evaluation::Trajectory takePoses() { return poses_.take(); }
  /// The first estimate and the snapshot (when later), in time order.
  estimation::EstimateSeries kept() const {
    estimation::EstimateSeries v;
    if (first_) v.push_back(*first_);
    if (snapshot_ && (!first_ || snapshot_->t_s > first_->t_s)) v.push_back(*snapshot_);
    return v;
  }

 private:
  const DriveData& d_;
  double since_start_s_, at_s_;
  std::vector<EkfTracePoint> d_trace_;
  std::function<void(const EkfTracePoint&)> trace_to_;
  evaluation::TrajectorySink poses_;
  std::optional<estimation::EstimateSample> first_, snapshot_;
};

/// d.gt_start: the ground truth mapped into the start frame (the simulator's anchor frame for
/// Pozyx, the start frame itself for a simulated ground-truth stream, else the least-squares
/// SE(2) alignment to the EKF trajectory), with d.gt_frame_note saying which.
void groundTruthInStartFrame(DriveData& d, const evaluation::MetricOptions& mo) {
  if (d.gt.samples.empty()) return;
  evaluation::SE2 T_inv;  // gt frame -> start frame
  bool have = false;
  if (d.truth && d.gt.source == evaluation::GroundTruthSource::Pozyx) {
    evaluation::SE2 A{d.truth->anchor_x_m, d.truth->anchor_y_m, d.truth->anchor_yaw_rad};
    T_inv = A.inverse();
    have = true;
    d.gt_frame_note = "mapped into the start frame with the simulator's known anchor frame";
  } else if (d.truth && d.gt.source == evaluation::GroundTruthSource::GroundTruthStream) {
    have = true;
    d.gt_frame_note = "simulated ground-truth stream (start frame)";
  } else if (d.trajectories.count("ekf")) {
    evaluation::MetricOptions se2 = mo;
    se2.alignment = evaluation::Alignment::SE2;
    const auto m = evaluation::computeMetrics(d.trajectories.at("ekf"), d.gt.samples, se2);
    if (m.n_matched > 0) {
      T_inv = m.alignment.inverse();
      have = true;
      d.gt_frame_note = "aligned to the EKF trajectory (least-squares SE(2))";
    }
  }
  if (have)
    for (const auto& s : d.gt.samples) {
      const Eigen::Vector2d p = T_inv.apply({s.x_m, s.y_m});
      d.gt_start.push_back(
          {s.t_s, p.x(), p.y(), s.hasHeading() ? T_inv.applyHeading(s.phi_rad) : s.phi_rad});
    }
}

/// d.metrics' header for `metric_options` (lever arm of d.gt); returns the options to score with.
evaluation::MetricOptions startMetrics(DriveData& d, const evaluation::MetricOptions& mo_in) {
  evaluation::MetricOptions mo = mo_in;
  mo.lever_arm_m = d.gt.lever_arm_m;
  d.metrics.recordings = 1;
  d.metrics.alignment = mo.alignment;
  d.metrics.align_first_s = mo.align_first_s;
  return mo;
}

/// One metrics row of `variant` (error `err`, else the metrics of `take()` against d.gt), and
/// its trajectory in d.trajectories; `lean`: only the points Fig. 5 draws are kept
/// (pathPointsToDraw). Sets d.metrics.failed_recordings when the row has an error.
void scoreVariant(DriveData& d, const evaluation::MetricOptions& mo, bool lean,
                  const std::string& variant, const std::string& err,
                  const std::function<evaluation::Trajectory()>& take) {
  evaluation::BatchRow row;
  row.recording = std::filesystem::path(d.path).filename().string();
  row.variant = variant;
  row.ground_truth = evaluation::toString(d.gt.source);
  row.error = err;
  if (err.empty()) {
    try {
      auto t = take();
      row.n_estimates = t.size();
      row.metrics = evaluation::computeMetrics(t, d.gt.samples, mo);
      if (lean) {  // from here on only drawn: the points drawn (Fig. 5)
        const auto keep = pathPointsToDraw(
            t.size(), [&](std::size_t i) { return t[i].x_m; },
            [&](std::size_t i) { return t[i].y_m; });
        if (keep.size() < t.size()) {
          evaluation::Trajectory drawn;
          drawn.reserve(keep.size());
          for (std::size_t i : keep) drawn.push_back(t[i]);
          t = std::move(drawn);
        }
      }
      d.trajectories[variant] = std::move(t);
    } catch (const std::exception& e) {
      row.error = e.what();
    }
  }
  if (!row.error.empty()) d.metrics.failed_recordings = 1;
  d.metrics.rows.push_back(std::move(row));
}

/// d.t0_s, d.t1_s: the EKF trace's span (else [start_s, end_s]). Lean, no `--at` and no sonar
/// echo: the default Fig. 7 time comes from the obstacle estimates' span; unless it is the start
/// (kept), `rerun_ekf` runs the EKF once more into a sink that keeps the estimate there (an
/// obstacle estimate without any echo: not seen on the bundled drives).
void spanAndSnapshot(DriveData& d, bool lean, const DriveLoadOptions& load, double sonar_t,
                     double start_s, double end_s,
                     const std::function<void(ReportEkfSink&)>& rerun_ekf) {
  if (!d.ekf_trace.empty()) {
    d.t0_s = d.ekf_trace.front().t_s;
    d.t1_s = d.ekf_trace.back().t_s;
  } else {
    d.t0_s = start_s;
    d.t1_s = end_s;
  }
  if (lean && !std::isfinite(load.snapshot_since_start_s) && std::isnan(sonar_t) &&
      !d.ekf_trace.empty()) {
    const double t_at = defaultObstacleTime(d);
    if (t_at > d.t0_s) {
      ReportEkfSink again(d, NAN, t_at);
      rerun_ekf(again);
      d.est.ekf.estimates = again.kept();
    }
  }
}

std::vector<SpeedPoint> speeds(const std::vector<estimation::DeadReckoningSample>& dr) {
  std::vector<SpeedPoint> v;
  v.reserve(dr.size());
  for (const auto& s : dr) v.push_back({s.t_s, s.v_m_s, s.omega_rad_s});
  return v;
}

}  // namespace

DriveData loadDrive(io::Recording rec, const std::string& path, const config::WheelchairConfig& cfg,
                    const evaluation::MetricOptions& metric_options, const std::string& truth_path,
                    const DriveLoadOptions& load) {
  DriveData d;
  d.path = path;
  d.cfg = cfg;
  d.rec = std::move(rec);
  const bool lean = !load.keep_estimates;
  // Lean: the snapshot time is known before the run when given or when the sonar saw something
  // (defaultObstacleTime's first rule); else it is found from the trace afterwards.
  const double sonar_t = firstSonarRunMiddle(d.rec);
  ReportEkfSink ekf_sink(d, load.snapshot_since_start_s, sonar_t);
  evaluation::TrajectorySink baseline_sink;
  if (lean) {  // the filters estimate once per measurement: sized once, without slack
    const auto& r = d.rec;
    const std::size_t n = r.encoders.size() + r.imu.size() + r.sonar.size() + r.pozyx.size() + 2;
    ekf_sink.reserve(n);
    baseline_sink.reserve(n);
  }
  d.est = evaluation::estimateVariants(d.rec, cfg, true, lean ? &ekf_sink : nullptr,
                                       lean ? &baseline_sink : nullptr);
  const bool ekf_failed = !d.est.errors.empty() && !d.est.errors.front().second.empty();
  if (lean && !ekf_failed) {  // (a failed run keeps nothing, as the stored one)
    d.ekf_trace = ekf_sink.takeTrace();
    d.est.ekf.estimates = ekf_sink.kept();
  } else if (!lean) {
    d.ekf_trace.reserve(d.est.ekf.estimates.size());
    for (const auto& e : d.est.ekf.estimates) d.ekf_trace.push_back(tracePoint(d, e));
  }
  spanAndSnapshot(
      d, lean, load, sonar_t, d.rec.startTime(), d.rec.endTime(),
      [&](ReportEkfSink& again) { evaluation::estimateVariants(d.rec, cfg, false, &again); });

  d.gt = evaluation::groundTruthOf(d.rec, cfg);
  const auto& r = d.rec;
  d.counts = {r.encoders.size(), r.imu.size(),   r.motors.size(),
              r.sonar.size(),    r.pozyx.size(), r.ground_truth.size()};
  d.gyro.reserve(r.imu.size());
  for (const auto& s : r.imu) d.gyro.push_back({s.t_s, s.gyro_z_rad_s});
  d.currents.reserve(r.motors.size());
  for (const auto& s : r.motors) d.currents.push_back({s.t_s, s.current_right_A, s.current_left_A});
  if (lean) {  // the figures need only the sonar stream of the recording from here on
    io::Recording kept;
    kept.sonar = std::move(d.rec.sonar);
    d.rec = std::move(kept);
    d.ekf_trace.shrink_to_fit();  // (sized for one estimate per measurement)
  }
  d.encoder_speeds = speeds(d.est.encoders);
  d.phase_speeds = speeds(d.est.encoders_gyro.empty() ? d.est.encoders : d.est.encoders_gyro);
  d.truth = readTruthJson(truth_path.empty() ? path + ".truth.json" : truth_path);

  const auto mo = startMetrics(d, metric_options);
  for (const auto& [variant, err] : d.est.errors)
    scoreVariant(d, mo, lean, variant, err, [&, v = variant] {
      return lean && v == "ekf"        ? ekf_sink.takePoses()
             : lean && v == "baseline" ? baseline_sink.take()
                                       : d.est.trajectory(v);
    });
  if (lean) {  // their trajectories and speeds are taken
    std::vector<estimation::DeadReckoningSample>().swap(d.est.encoders);
    std::vector<estimation::DeadReckoningSample>().swap(d.est.encoders_gyro);
  }
  groundTruthInStartFrame(d, mo);
  return d;
}

namespace {

/// Pass 1 of the streamed load: the counts, the figures' gyro and currents (thinned as they
/// come when a series has more samples than the drawing thins: binFor(count) > 0), the ground
/// truth (from the Pozyx / ground-truth samples) and the sonar (d.rec keeps only it).
template <class BinFor>
DriveData readFigureStreams(const std::string& path, const io::RecordingSummary& sum,
                            const config::WheelchairConfig& cfg, const BinFor& binFor) {
  using io::StreamKind;
  DriveData d;
  d.path = path;
  d.cfg = cfg;
  d.counts = {sum.count(StreamKind::Encoders), sum.count(StreamKind::Imu),
              sum.count(StreamKind::Motors),   sum.count(StreamKind::Sonar),
              sum.count(StreamKind::Pozyx),    sum.count(StreamKind::GroundTruth)};
  SeriesThinner<GyroPoint> gyro(d.gyro, {[](const GyroPoint& g) { return g.gyro_z_rad_s; }}, {},
                                sum.start_s, binFor(d.counts.imu));
  SeriesThinner<CurrentPoint> currents(d.currents,
                                       {[](const CurrentPoint& c) { return c.current_right_A; },
                                        [](const CurrentPoint& c) { return c.current_left_A; }},
                                       {}, sum.start_s, binFor(d.counts.motors));
  if (!(binFor(d.counts.imu) > 0)) d.gyro.reserve(d.counts.imu);
  if (!(binFor(d.counts.motors) > 0)) d.currents.reserve(d.counts.motors);
  io::RawlogSampleReader in(path);
  io::AnySample s;
  std::size_t k = 0;
  while (in.next(s, k)) {
    if (const auto* m = std::get_if<io::ImuSample>(&s)) {
      gyro.add({m->t_s, m->gyro_z_rad_s});
    } else if (const auto* c = std::get_if<io::MotorSample>(&s)) {
      currents.add({c->t_s, c->current_right_A, c->current_left_A});
    } else {
      const auto kind = io::kindOf(s);
      if (kind == StreamKind::Sonar || kind == StreamKind::Pozyx || kind == StreamKind::GroundTruth)
        io::append(d.rec, s);
    }
  }
  gyro.finish();
  currents.finish();
  d.gt = evaluation::groundTruthOf(d.rec, cfg);
  io::Recording kept;  // only the sonar stays (Fig. 7, 8)
  kept.sonar = std::move(d.rec.sonar);
  d.rec = std::move(kept);
  return d;
}

/// First and last time of a valid sonar range (none: no valid reading).
std::optional<std::pair<double, double>> validSonarSpan(const io::Recording& rec) {
  std::optional<std::pair<double, double>> w;
  for (const auto& s : rec.sonar)
    if (s.range_m > 0) w = std::make_pair(w ? w->first : s.t_s, s.t_s);
  return w;
}

}  // namespace

DriveData loadDriveStreamed(const std::string& path, const io::RecordingSummary& sum,
                            const config::WheelchairConfig& cfg,
                            const evaluation::MetricOptions& metric_options,
                            const std::string& truth_path, double snapshot_since_start_s) {
  DriveLoadOptions load;
  load.keep_estimates = false;
  load.snapshot_since_start_s = snapshot_since_start_s;
  if (!estimation::ModelExtensions::fromConfig(cfg.ini()).empty())  // the corrected recording
    return loadDrive(io::readRawlogSalvaging(path, true, nullptr), path, cfg, metric_options,
                     truth_path, load);
  // A series of more samples than the drawing thins (Plot::kDecimateAbove) is thinned as it
  // comes (SeriesThinner): bins of 1/kThinBins of the drive's span.
  const double span_s = sum.end_s - sum.start_s;
  auto binFor = [&](std::size_t n) { return n > Plot::kDecimateAbove ? span_s / kThinBins : 0.0; };
  DriveData d = readFigureStreams(path, sum, cfg, binFor);
  const auto mo = startMetrics(d, metric_options);
  const double sonar_t = firstSonarRunMiddle(d.rec);
  ReportEkfSink ekf_sink(d, snapshot_since_start_s, sonar_t);
  const std::size_t n_estimates =
      d.counts.encoders + d.counts.imu + d.counts.sonar + d.counts.pozyx + 2;
  // The EKF trace: Fig. 6a, 6b (v, omega) and Fig. 8 (range +- sd, obstacle spans), whose
  // window (the valid sonar readings, -2 s .. +4 s) gets bins of its own length's 1/kThinBins.
  SeriesThinner<EkfTracePoint> trace(
      d.ekf_trace,
      {[](const EkfTracePoint& e) { return e.v_m_s; },
       [](const EkfTracePoint& e) { return e.omega_rad_s; },
       [](const EkfTracePoint& e) { return e.range_m; },
       [](const EkfTracePoint& e) { return e.range_m - e.range_sd_m; },
       [](const EkfTracePoint& e) { return e.range_m + e.range_sd_m; }},
      [](const EkfTracePoint& e) { return e.obstacle ? 1 : 0; }, sum.start_s, binFor(n_estimates));
  if (const auto w = validSonarSpan(d.rec))
    trace.fineWindow(w->first - 3.0, w->second + 5.0, (w->second - w->first + 8.0) / kThinBins);
  const bool thin_trace = binFor(n_estimates) > 0;
  if (thin_trace) ekf_sink.traceTo([&](const EkfTracePoint& e) { trace.add(e); });
  ekf_sink.reserve(n_estimates);
  evaluation::TrajectorySink baseline_sink;
  // Each variant is scored as soon as it has run, and then keeps only what Fig. 5 draws; the
  // dead reckonings' speeds are thinned as they come (encoders: Fig. 6a, 6b; the phases: runs
  // of equal motionKind, exact).
  const double dr_bin = binFor(d.counts.encoders);
  std::vector<SpeedPoint> enc_phases;
  const std::vector<SeriesThinner<SpeedPoint>::Value> vw{
      [](const SpeedPoint& p) { return p.v_m_s; },
      [](const SpeedPoint& p) { return p.omega_rad_s; }};
  std::optional<SeriesThinner<SpeedPoint>> speeds_thin, phases_thin;
  auto startDeadReckoning = [&](std::vector<SpeedPoint>* speeds_out,
                                std::vector<SpeedPoint>& phases_out) {
    if (speeds_out) speeds_thin.emplace(*speeds_out, vw, nullptr, sum.start_s, dr_bin);
    if (!speeds_out) speeds_thin.reset();
    phases_thin.emplace(
        phases_out, std::vector<SeriesThinner<SpeedPoint>::Value>{},
        [](const SpeedPoint& p) { return motionKind(p); }, sum.start_s, dr_bin);
  };
  evaluation::Trajectory dr_poses;
  auto deadReckoningSink = [&](const estimation::DeadReckoningSample& s) {
    const SpeedPoint p{s.t_s, s.v_m_s, s.omega_rad_s};
    if (speeds_thin) speeds_thin->add(p);
    phases_thin->add(p);
    dr_poses.push_back({s.t_s, s.x_m, s.y_m, s.phi_rad});
  };
  evaluation::VariantSinks sinks;
  sinks.ekf = &ekf_sink;
  sinks.encoders = deadReckoningSink;
  sinks.encoders_gyro = deadReckoningSink;
  sinks.baseline = &baseline_sink;
  auto done = [&](const std::string& variant, const std::string& err) {
    if (variant == "ekf") {
      // (sized for one estimate per measurement: no shrink_to_fit, whose copy would double it)
      if (thin_trace) trace.finish();
      if (err.empty() && !thin_trace) d.ekf_trace = ekf_sink.takeTrace();
      if (!err.empty()) std::vector<EkfTracePoint>().swap(d.ekf_trace);  // as the stored run
      scoreVariant(d, mo, true, variant, err, [&] { return ekf_sink.takePoses(); });
      startDeadReckoning(&d.encoder_speeds, enc_phases);
      dr_poses.reserve(d.counts.encoders);
    } else if (variant == "baseline") {
      scoreVariant(d, mo, true, variant, err, [&] { return baseline_sink.take(); });
    } else {
      if (speeds_thin) speeds_thin->finish();
      phases_thin->finish();
      if (!err.empty()) {  // (as the stored run: nothing)
        if (variant == "encoders") d.encoder_speeds.clear(), enc_phases.clear();
        if (variant == "encoders_gyro") d.phase_speeds.clear();
      }
      scoreVariant(d, mo, true, variant, err, [&] {
        evaluation::sortByTimeKeepLast(dr_poses);
        return std::move(dr_poses);
      });
      evaluation::Trajectory().swap(dr_poses);
      if (variant == "encoders") {  // encoders_gyro: a sample per encoder sample and gyro time
        startDeadReckoning(nullptr, d.phase_speeds);
        dr_poses.reserve(d.counts.encoders + d.counts.imu);
      }
    }
  };
  d.est = evaluation::streamVariants(path, sum, cfg, sinks, done);
  evaluation::Trajectory().swap(dr_poses);
  if (d.phase_speeds.empty()) d.phase_speeds = std::move(enc_phases);  // no encoder/gyro samples
  const bool ekf_failed = !d.est.errors.empty() && !d.est.errors.front().second.empty();
  if (!ekf_failed) d.est.ekf.estimates = ekf_sink.kept();
  spanAndSnapshot(d, true, load, sonar_t, sum.start_s, sum.end_s, [&](ReportEkfSink& again) {
    evaluation::VariantSinks ekf_only;
    ekf_only.ekf = &again;
    evaluation::streamVariants(path, sum, cfg, ekf_only, {});
  });
  d.truth = readTruthJson(truth_path.empty() ? path + ".truth.json" : truth_path);
  groundTruthInStartFrame(d, mo);
  return d;
}

int motionKind(const SpeedPoint& s) {
  return std::fabs(s.omega_rad_s) >= 0.2 ? 2 : (std::fabs(s.v_m_s) > 0.08 ? 1 : 0);
}

double defaultObstacleTime(const DriveData& d) {
  // Middle of the first run of valid (non-zero) sonar readings: the chair approaches the
  // obstacle and the estimate is in front of it.
  const double t_sonar = firstSonarRunMiddle(d.rec);
  if (!std::isnan(t_sonar)) return t_sonar;
  double e0 = NAN, e1 = NAN;
  for (const auto& e : d.ekf_trace)
    if (e.obstacle) {
      if (std::isnan(e0)) e0 = e.t_s;
      e1 = e.t_s;
    }
  if (std::isnan(e0)) return d.t0_s;
  return e0 + 0.4 * (e1 - e0);
}

bool predictedSonarRange(const DriveData& d, const estimation::EstimateSample& e, double& r,
                         double& sd) {
  if (!e.obstacle_initialised) return false;
  const double dx = e.x(5) - d.cfg.sonar.x_m, dy = e.x(6) - d.cfg.sonar.y_m;
  r = std::hypot(dx, dy);
  if (r < 1e-9) {
    sd = std::sqrt(std::max(0.0, e.P(5, 5)));
    return true;
  }
  const Eigen::RowVector2d J(dx / r, dy / r);
  sd = std::sqrt(std::max(0.0, (J * e.P.block<2, 2>(5, 5) * J.transpose())(0, 0)));
  return true;
}

}  // namespace wheelchair::visualization
