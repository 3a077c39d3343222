#include "libwheelchair/capture/CaptureSource.h"
#include "libwheelchair/capture/LineSensor.h"
#include "libwheelchair/capture/QuadratureCounterSensor.h"

#include <mutex>

namespace wheelchair::capture {

void registerCaptureSensors() {
  static std::once_flag once;
  std::call_once(once, [] {
    ArduinoMotorsSensor::doRegister();
    RazorImuSensor::doRegister();
    PozyxSensor::doRegister();
    SonarSensor::doRegister();
    JoystickSensor::doRegister();
    QuadratureCounterSensor::doRegister();
  });
}

std::unique_ptr<CaptureSource> createCaptureSource(const std::string& driver) {
  registerCaptureSensors();
  mrpt::hwdrivers::CGenericSensor* s = mrpt::hwdrivers::CGenericSensor::createSensor(driver);
  if (!s) return nullptr;
  auto* c = dynamic_cast<CaptureSource*>(s);
  if (!c) {
    delete s;
    return nullptr;
  }
  return std::unique_ptr<CaptureSource>(c);
}

}  // namespace wheelchair::capture
