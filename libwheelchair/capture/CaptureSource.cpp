#include "libwheelchair/capture/CaptureSource.h"

#include "libwheelchair/util/Text.h"

#include "libwheelchair/capture/HostClock.h"
#include "libwheelchair/io/RawlogIO.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace wheelchair::capture {

std::string escapeForLog(std::string_view s) {
  return util::quoteInput(s, 60);
}

CaptureSource::CaptureSource(io::StreamKind kind)
    : kind_(kind), vehicle_(std::make_shared<config::WheelchairConfig>()) {
  m_sensorLabel = io::streamLabel(kind);
}

CaptureSource::~CaptureSource() = default;

void CaptureSource::setVehicleConfig(const config::WheelchairConfig& cfg) {
  vehicle_ = std::make_shared<config::WheelchairConfig>(cfg);
}

void CaptureSource::loadConfig_sensorSpecific(const mrpt::config::CConfigFileBase& ini,
                                              const std::string& section) {
  config_error_.clear();
  try {
    loadCommonConfig(ini, section);
  } catch (const std::exception& e) {
    config_error_ = e.what();
    throw;
  }
}

void CaptureSource::loadCommonConfig(const mrpt::config::CConfigFileBase& ini,
                                     const std::string& section) {
  section_ = section;
  auto where = [&](const char* key) { return fmt::format("[{}] {}", section, key); };
  if (m_sensorLabel != io::streamLabel(kind_))
    throw std::invalid_argument(fmt::format(
        "{}: must be {} for this driver (docs/rawlog-mapping.md): readers recognise a stream "
        "by its label",
        where("sensorLabel"), io::streamLabel(kind_)));
  if (m_process_rate <= 0) m_process_rate = 100;
  const std::string ts = ini.read_string(section, "time_source", "arrival", false);
  if (ts == "arrival")
    time_source_ = TimeSource::Arrival;
  else if (ts == "device")
    time_source_ = TimeSource::Device;
  else if (ts == "device_synced")
    time_source_ = TimeSource::DeviceSynced;
  else
    throw std::invalid_argument(fmt::format("{} = '{}': expected arrival, device or device_synced",
                                            where("time_source"), ts));
  latency_s_ = ini.read_double(section, "latency_s", 0.0, false);
  reconnect_min_s_ = ini.read_double(section, "reconnect_min_s", reconnect_min_s_, false);
  reconnect_max_s_ = ini.read_double(section, "reconnect_max_s", reconnect_max_s_, false);
  stall_timeout_s_ = ini.read_double(section, "stall_timeout_s", stall_timeout_s_, false);
  if (reconnect_min_s_ <= 0 || reconnect_max_s_ < reconnect_min_s_)
    throw std::invalid_argument(
        fmt::format("[{}] need 0 < reconnect_min_s <= reconnect_max_s", section));
  // The mounting pose of the two sensors whose observations carry one (rawlog-mapping.md).
  const bool has_pose = ini.keyExists(section, "pose_x") || ini.keyExists(section, "pose_y") ||
                        ini.keyExists(section, "pose_yaw");
  if (has_pose) {
    const double x = ini.read_double(section, "pose_x", 0.0),
                 y = ini.read_double(section, "pose_y", 0.0),
                 yaw = ini.read_double(section, "pose_yaw", 0.0);
    if (kind_ == io::StreamKind::Sonar) {
      vehicle_->set("sonar", "x_m", fmt::format("{}", x));
      vehicle_->set("sonar", "y_m", fmt::format("{}", y));
      vehicle_->set("sonar", "yaw_deg", fmt::format("{}", yaw));
    } else if (kind_ == io::StreamKind::Pozyx) {
      vehicle_->set("pozyx", "lever_x_m", fmt::format("{}", x));
      vehicle_->set("pozyx", "lever_y_m", fmt::format("{}", y));
    } else {
      throw std::invalid_argument(fmt::format(
          "[{}] pose_*: the {} observation carries no sensor pose (docs/rawlog-mapping.md)",
          section, io::streamLabel(kind_)));
    }
  }
  {
    std::lock_guard lk(mtx_);
    st_.section = section;
    st_.label = m_sensorLabel;
    st_.driver = GetRuntimeClass()->className;
  }
  loadSourceConfig(ini, section);
  std::lock_guard lk(mtx_);
  st_.device = deviceName();
}

SourceStatus CaptureSource::status() const {
  std::lock_guard lk(mtx_);
  return st_;
}

std::vector<CaptureEvent> CaptureSource::takeEvents() {
  std::lock_guard lk(mtx_);
  std::vector<CaptureEvent> out;
  out.swap(events_);
  return out;
}

void CaptureSource::logEvent(const std::string& text, bool error) {
  std::lock_guard lk(mtx_);
  events_.push_back(CaptureEvent{HostClock::now(), section_, text, error});
}

void CaptureSource::emit(io::AnySample sample, double arrival, std::optional<double> device_t) {
  double t = arrival - latency_s_;
  if (time_source_ == TimeSource::Device) {
    t = *device_t;
  } else if (time_source_ == TimeSource::DeviceSynced) {
    // Minimum-delay estimate of device clock -> capture clock since the last (re)connect.
    sync_offset_ = std::min(sync_offset_, arrival - latency_s_ - *device_t);
    t = *device_t + sync_offset_;
  }
  std::visit([t](auto& x) { x.t_s = t; }, sample);
  auto obs = io::toObservation(sample, *vehicle_);
  obs->sensorLabel = m_sensorLabel;
  appendObservation(obs);

  last_data_mono_ = HostClock::monotonic();
  double prev_t;
  {
    std::lock_guard lk(mtx_);
    prev_t = st_.last_t;
    ++st_.records;
    st_.last_t = t;
    st_.last_error.clear();
    if (gap_pending_ || stalled_) ++st_.gaps;
  }
  if (gap_pending_ || stalled_) {
    logEvent(
        fmt::format("data again after {:.3f} s without ({}); gap in {} data: {:.6f} -> {:.6f} "
                    "({:.3f} s)",
                    HostClock::now() - gap_since_host_, stalled_ ? "stall" : "reconnect",
                    m_sensorLabel, prev_t, t, std::isnan(prev_t) ? 0.0 : t - prev_t));
  }
  gap_pending_ = stalled_ = false;
  had_data_ = true;
  backoff_s_ = 0;
}

void CaptureSource::countGarbage(std::string_view line) {
  uint64_t n;
  {
    std::lock_guard lk(mtx_);
    n = ++st_.garbage;
    st_.last_garbage = escapeForLog(line);
  }
  // The first few are worth a log line; after that the live counter says enough.
  if (n <= 3)
    logEvent(fmt::format("skipped malformed line #{}: '{}'", n, escapeForLog(line)));
  else if (n == 4)
    logEvent("more malformed lines: counted, not logged (see the status)");
}

bool CaptureSource::reconnectDue() const {
  return HostClock::monotonic() >= next_attempt_mono_;
}

void CaptureSource::connectFailed(const std::string& error) {
  backoff_s_ = backoff_s_ <= 0 ? reconnect_min_s_ : std::min(2 * backoff_s_, reconnect_max_s_);
  next_attempt_mono_ = HostClock::monotonic() + backoff_s_;
  {
    std::lock_guard lk(mtx_);
    st_.connected = false;
    st_.last_error = error;
  }
  if (!failing_ || error != last_fail_msg_)
    logEvent(fmt::format("{}; retrying (backoff {:.1f} s up to {:.1f} s)", error, reconnect_min_s_,
                         reconnect_max_s_),
             true);
  failing_ = true;
  last_fail_msg_ = error;
}

void CaptureSource::connected() {
  failing_ = false;
  last_fail_msg_.clear();
  sync_offset_ = std::numeric_limits<double>::infinity();  // a replugged device may reset its clock
  last_data_mono_ = HostClock::monotonic();
  {
    std::lock_guard lk(mtx_);
    st_.connected = true;
    st_.last_error.clear();
    ++st_.connects;
  }
  logEvent(fmt::format("connected to {}", deviceName()));
}

void CaptureSource::disconnected(const std::string& error) {
  {
    std::lock_guard lk(mtx_);
    st_.connected = false;
    st_.last_error = error;
    ++st_.disconnects;
  }
  if (!gap_pending_ && !stalled_) gap_since_host_ = HostClock::now();
  gap_pending_ = gap_pending_ || had_data_;
  logEvent(fmt::format("disconnected from {}: {}; reconnecting", deviceName(), error), true);
  backoff_s_ = reconnect_min_s_;
  next_attempt_mono_ = HostClock::monotonic() + backoff_s_;
  failing_ = true;
  last_fail_msg_.clear();
}

void CaptureSource::checkStall() {
  if (stalled_ || !had_data_ || stall_timeout_s_ <= 0) return;
  if (HostClock::monotonic() - last_data_mono_ < stall_timeout_s_) return;
  stalled_ = true;
  gap_since_host_ = HostClock::now() - (HostClock::monotonic() - last_data_mono_);
  logEvent(fmt::format("no data for {:.1f} s (device connected but silent)", stall_timeout_s_),
           true);
}

}  // namespace wheelchair::capture
