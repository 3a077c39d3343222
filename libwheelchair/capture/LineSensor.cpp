#include "libwheelchair/capture/LineSensor.h"

#include "libwheelchair/capture/HostClock.h"

#include <fmt/format.h>

#include <algorithm>
#include <thread>

namespace wheelchair::capture {

IMPLEMENTS_GENERIC_SENSOR(ArduinoMotorsSensor, wheelchair::capture)
IMPLEMENTS_GENERIC_SENSOR(RazorImuSensor, wheelchair::capture)
IMPLEMENTS_GENERIC_SENSOR(PozyxSensor, wheelchair::capture)
IMPLEMENTS_GENERIC_SENSOR(SonarSensor, wheelchair::capture)
IMPLEMENTS_GENERIC_SENSOR(JoystickSensor, wheelchair::capture)

void LineSensor::loadSourceConfig(const mrpt::config::CConfigFileBase& ini,
                                  const std::string& section) {
  port_name_ = ini.read_string(section, "serial_port", "", false);
  if (port_name_.empty())
    throw std::invalid_argument(fmt::format("[{}] serial_port: required", section));
  baud_ = ini.read_int(section, "baud_rate", baud_, false);
  if (baud_ != 0 && SerialPort::speedConstant(baud_) < 0)
    throw std::invalid_argument(
        fmt::format("[{}] baud_rate = {}: not a standard rate", section, baud_));
  format_ = LineFormat::fromConfig(ini, section, kind_);
  if (time_source_ != TimeSource::Arrival && !format_->hasDeviceTime())
    throw std::invalid_argument(
        fmt::format("[{}] time_source needs a {{t}} field in the line format ({})", section,
                    format_->describe()));
}

bool LineSensor::tryOpen() {
  std::string err;
  if (!port_.open(port_name_, baud_, err)) {
    connectFailed(err);
    return false;
  }
  partial_.clear();
  discarding_ = false;
  connected();
  return true;
}

void LineSensor::initialize() {
  m_state = ssWorking;  // a missing device is not fatal: doProcess() keeps retrying
  tryOpen();
}

void LineSensor::shutdown() {
  port_.close();
}

void LineSensor::doProcess() {
  const double period = 1.0 / std::max(1.0, m_process_rate);
  if (!port_.isOpen()) {
    if (!reconnectDue() || !tryOpen()) {
      std::this_thread::sleep_for(std::chrono::duration<double>(std::min(period, 0.05)));
      return;
    }
  }
  char buf[4096];
  std::size_t n = 0;
  std::string err;
  // Read everything available, waiting up to one period for the first bytes.
  double wait = period;
  for (int k = 0; k < 64; ++k) {
    const auto r = port_.read(buf, sizeof buf, n, wait, err);
    if (r == SerialPort::ReadResult::Data) {
      feed(buf, n, HostClock::now());
      wait = 0;
      continue;
    }
    if (r == SerialPort::ReadResult::HangUp) {
      port_.close();
      disconnected(err);
    } else {
      checkStall();
    }
    break;
  }
}

void LineSensor::feed(const char* data, std::size_t n, double arrival) {
  const std::size_t max_len = format_->maxLineLength();
  std::size_t b = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (data[i] != '\n') continue;
    if (discarding_) {
      discarding_ = false;
    } else if (partial_.empty()) {
      handleLine(std::string_view(data + b, i - b), arrival);
    } else {
      partial_.append(data + b, i - b);
      handleLine(partial_, arrival);
    }
    partial_.clear();
    b = i + 1;
  }
  if (b < n && !discarding_) {
    partial_.append(data + b, n - b);
    if (partial_.size() > max_len + 1) {  // no end of line in sight: skip to the next one
      countGarbage(partial_);
      partial_.clear();
      discarding_ = true;
    }
  }
}

void LineSensor::handleLine(std::string_view line, double arrival) {
  if (line.find_first_not_of(" \t\r") == std::string_view::npos) return;  // blank line
  ParsedLine p;
  if (!format_->parse(line, p)) {
    countGarbage(line);
    return;
  }
  emit(std::move(p.sample), arrival, p.device_time_s);
}

}  // namespace wheelchair::capture
