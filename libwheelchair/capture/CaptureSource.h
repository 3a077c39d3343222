// Base of every capture source: an MRPT generic sensor (mrpt::hwdrivers::CGenericSensor,
// rawlog-grabber conventions) that produces the observations of one stream of
// docs/rawlog-mapping.md, stamps them on the session's one clock, reconnects with backoff
// and keeps counters and an event log for the live status.
//
// Keys common to every source section (besides rawlog-grabber's `driver`, `sensorLabel`,
// `process_rate`): time_source (arrival | device | device_synced), latency_s,
// reconnect_min_s, reconnect_max_s, stall_timeout_s, pose_x, pose_y, pose_yaw (sonar and
// Pozyx only). See config/capture.ini and docs/capture.md.
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Samples.h"

#include <mrpt/hwdrivers/CGenericSensor.h>

#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace wheelchair::capture {

enum class TimeSource { Arrival, Device, DeviceSynced };

/// Live counters of one source (a snapshot; see CaptureSource::status()).
struct SourceStatus {
  std::string section, label, driver, device;
  bool connected = false;
  uint64_t records = 0;      ///< valid lines (or SPI reads) turned into observations
  uint64_t garbage = 0;      ///< lines counted and skipped (malformed, partial, too long)
  uint64_t connects = 0;     ///< successful opens
  uint64_t disconnects = 0;  ///< hang-ups / read errors after an open
  uint64_t gaps = 0;         ///< data gaps logged (reconnects and stalls)
  double last_t = std::numeric_limits<double>::quiet_NaN();  ///< last stamp (capture clock)
  std::string last_error;    ///< the last connection error, "" when fine
  std::string last_garbage;  ///< the last skipped line (escaped, shortened)
};

/// Something worth a line in the capture log: connections, hang-ups, gaps, first garbage.
struct CaptureEvent {
  double host_t = 0;  ///< HostClock::now()
  std::string source;
  std::string text;
  bool error = false;
};

class CaptureSource : public mrpt::hwdrivers::CGenericSensor {
 public:
  explicit CaptureSource(io::StreamKind kind);
  ~CaptureSource() override;

  io::StreamKind kind() const { return kind_; }
  /// Sensor geometry used for the observations (toObservation); nominal if never set.
  /// Must be called before loadConfig() (pose_* keys override it).
  void setVehicleConfig(const config::WheelchairConfig& cfg);
  const config::WheelchairConfig& vehicleConfig() const { return *vehicle_; }
  void setSection(const std::string& section) { section_ = section; }
  const std::string& section() const { return section_; }

  SourceStatus status() const;
  /// Takes the events logged since the last call.
  std::vector<CaptureEvent> takeEvents();
  /// Closes the device (called by the session after the last doProcess()).
  virtual void shutdown() {}
  /// Human-readable device name (path) for the status line.
  virtual std::string deviceName() const = 0;
  TimeSource timeSource() const { return time_source_; }
  void logEvent(const std::string& text, bool error = false);
  /// The message of the last configuration error (loadConfig() throws it wrapped by MRPT).
  const std::string& configError() const { return config_error_; }

 protected:
  void loadConfig_sensorSpecific(const mrpt::config::CConfigFileBase& ini,
                                 const std::string& section) override;
  void loadCommonConfig(const mrpt::config::CConfigFileBase& ini, const std::string& section);
  /// Source-specific keys; called by loadConfig_sensorSpecific after the common ones.
  virtual void loadSourceConfig(const mrpt::config::CConfigFileBase& ini,
                                const std::string& section) = 0;

  /// Stamps `sample` (arrival = HostClock::now() when its bytes arrived; device_t = its own
  /// `{t}` field, if any), turns it into the rawlog observation and queues it.
  void emit(io::AnySample sample, double arrival_host_t, std::optional<double> device_t);
  void countGarbage(std::string_view line);
  /// Connection bookkeeping: logs the first failure of a series, arms the backoff.
  void connectFailed(const std::string& error);
  void connected();
  void disconnected(const std::string& error);
  /// True when a (re)connection attempt is due (backoff elapsed).
  bool reconnectDue() const;
  /// Checks for a stall (connected, no data for stall_timeout_s) and logs it once.
  void checkStall();

  io::StreamKind kind_;
  std::string section_;
  std::shared_ptr<config::WheelchairConfig> vehicle_;
  TimeSource time_source_ = TimeSource::Arrival;
  double latency_s_ = 0;
  double reconnect_min_s_ = 0.2, reconnect_max_s_ = 2.0, stall_timeout_s_ = 2.0;
  std::string config_error_;

 private:
  mutable std::mutex mtx_;
  SourceStatus st_;
  std::vector<CaptureEvent> events_;
  // Backoff and gap bookkeeping (sensor thread only).
  double backoff_s_ = 0, next_attempt_mono_ = 0;
  bool failing_ = false;
  std::string last_fail_msg_;
  bool gap_pending_ = false, stalled_ = false;
  double gap_since_host_ = 0, last_data_mono_ = 0;
  double sync_offset_ = std::numeric_limits<double>::infinity();
  bool had_data_ = false;
};

/// Escapes a line for logs: printable ASCII kept, others as \xNN, cut at 60 characters.
std::string escapeForLog(std::string_view s);

/// Registers the capture drivers with MRPT's sensor factory (CGenericSensor::createSensor):
/// ArduinoMotorsSensor, RazorImuSensor, PozyxSensor, SonarSensor, JoystickSensor,
/// QuadratureCounterSensor. Idempotent.
void registerCaptureSensors();

/// Creates a registered capture driver by name; nullptr if unknown or not a capture source.
std::unique_ptr<CaptureSource> createCaptureSource(const std::string& driver);

}  // namespace wheelchair::capture
