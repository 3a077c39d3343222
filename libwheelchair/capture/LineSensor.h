// A capture source reading text lines from a serial port (LineFormat does the parsing), and
// the drivers of the wheelchair's serial devices, each an MRPT generic sensor:
//
//   driver                   stream    device (docs/capture.md)
//   ArduinoMotorsSensor      MOTORS    Arduino Mega: ACS758 currents + V_RC, raw ADC counts
//   RazorImuSensor           IMU       SparkFun 9DoF Razor IMU M0, serial text output
//   PozyxSensor              POZYX     Pozyx tag position (through its host logger)
//   SonarSensor              SONAR     ultrasonic range finder
//   JoystickSensor           JOYSTICK  joystick demand
//   (QuadratureCounterSensor ENCODERS, see QuadratureCounterSensor.h, serial fallback here)
//
// Keys (besides CaptureSource's): serial_port, baud_rate, line_format | line_regex +
// line_fields, <field>_gain, <field>_offset, max_line_length.
//
// doProcess() waits at most 1/process_rate for bytes, splits them into lines, parses and
// queues one observation per valid line; every line of one read() shares its arrival time.
// A missing device, a hang-up or a read error closes the port and retries with backoff.
#pragma once

#include "libwheelchair/capture/CaptureSource.h"
#include "libwheelchair/capture/LineFormat.h"
#include "libwheelchair/capture/SerialPort.h"

#include <optional>

namespace wheelchair::capture {

class LineSensor : public CaptureSource {
 public:
  explicit LineSensor(io::StreamKind kind) : CaptureSource(kind) {}
  void initialize() override;
  void doProcess() override;
  void shutdown() override;
  std::string deviceName() const override { return port_name_; }
  const LineFormat& format() const { return *format_; }

  /// Feeds bytes as if read from the device at `arrival` (HostClock seconds). Public for
  /// tests of the line splitting (partial lines across reads, overlong lines).
  void feed(const char* data, std::size_t n, double arrival);

 protected:
  void loadSourceConfig(const mrpt::config::CConfigFileBase& ini,
                        const std::string& section) override;
  void handleLine(std::string_view line, double arrival);
  bool tryOpen();

  std::string port_name_;
  int baud_ = 115200;
  std::optional<LineFormat> format_;
  SerialPort port_;
  std::string partial_;
  bool discarding_ = false;  ///< inside an overlong line, until its end
};

#define WHEELCHAIR_LINE_DRIVER(Name, Kind) \
  class Name : public LineSensor {         \
    DEFINE_GENERIC_SENSOR(Name)            \
   public:                                 \
    Name() : LineSensor(Kind) {}           \
  };

WHEELCHAIR_LINE_DRIVER(ArduinoMotorsSensor, io::StreamKind::Motors)
WHEELCHAIR_LINE_DRIVER(RazorImuSensor, io::StreamKind::Imu)
WHEELCHAIR_LINE_DRIVER(PozyxSensor, io::StreamKind::Pozyx)
WHEELCHAIR_LINE_DRIVER(SonarSensor, io::StreamKind::Sonar)
WHEELCHAIR_LINE_DRIVER(JoystickSensor, io::StreamKind::Joystick)

#undef WHEELCHAIR_LINE_DRIVER

}  // namespace wheelchair::capture
