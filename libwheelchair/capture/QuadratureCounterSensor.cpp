#include "libwheelchair/capture/QuadratureCounterSensor.h"

#include "libwheelchair/capture/HostClock.h"

#include <fmt/format.h>

#include <fcntl.h>
#include <linux/spi/spidev.h>
#include <sys/ioctl.h>
#include <unistd.h>
#include <cerrno>
#include <cstring>
#include <thread>

namespace wheelchair::capture {

IMPLEMENTS_GENERIC_SENSOR(QuadratureCounterSensor, wheelchair::capture)

// ---------------------------------------------------------------- spidev

SpidevBus::~SpidevBus() {
  if (fd_ >= 0) ::close(fd_);
}

bool SpidevBus::open(const std::string& device, uint32_t speed_hz, uint8_t mode,
                     std::string& error) {
  device_ = device;
  speed_hz_ = speed_hz;
  fd_ = ::open(device.c_str(), O_RDWR | O_CLOEXEC);
  if (fd_ < 0) {
    error = "open " + device + ": " + std::strerror(errno);
    return false;
  }
  uint8_t bits = 8;
  if (ioctl(fd_, SPI_IOC_WR_MODE, &mode) < 0 || ioctl(fd_, SPI_IOC_WR_BITS_PER_WORD, &bits) < 0 ||
      ioctl(fd_, SPI_IOC_WR_MAX_SPEED_HZ, &speed_hz) < 0) {
    error = "configure " + device + ": " + std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
    return false;
  }
  return true;
}

bool SpidevBus::transfer(const uint8_t* tx, uint8_t* rx, std::size_t n, std::string& error) {
  spi_ioc_transfer tr{};
  tr.tx_buf = reinterpret_cast<uintptr_t>(tx);
  tr.rx_buf = reinterpret_cast<uintptr_t>(rx);
  tr.len = static_cast<uint32_t>(n);
  tr.speed_hz = speed_hz_;
  tr.bits_per_word = 8;
  tr.delay_usecs = 0;
  tr.cs_change = 0;
  if (ioctl(fd_, SPI_IOC_MESSAGE(1), &tr) < 0) {
    error = "SPI transfer on " + device_ + ": " + std::strerror(errno);
    return false;
  }
  return true;
}

// ---------------------------------------------------------------- LS7366R

namespace ls7366r {

bool configure(SpiBus& bus, std::string& error) {
  uint8_t rx[2];
  const uint8_t w0[2] = {kWriteMdr0, kMdr0Quadrature4x};
  const uint8_t w1[2] = {kWriteMdr1, kMdr1FourByte};
  const uint8_t r0[2] = {kReadMdr0, 0};
  if (!bus.transfer(w0, rx, 2, error) || !bus.transfer(w1, rx, 2, error) ||
      !bus.transfer(r0, rx, 2, error))
    return false;
  if (rx[1] != kMdr0Quadrature4x) {
    error = fmt::format("counter chip does not answer (MDR0 reads 0x{:02x}, wrote 0x{:02x})", rx[1],
                        kMdr0Quadrature4x);
    return false;
  }
  return true;
}

bool readCounter(SpiBus& bus, int32_t& count, std::string& error) {
  const uint8_t tx[5] = {kReadCntr, 0, 0, 0, 0};
  uint8_t rx[5] = {};
  if (!bus.transfer(tx, rx, 5, error)) return false;
  const uint32_t u =
      (uint32_t(rx[1]) << 24) | (uint32_t(rx[2]) << 16) | (uint32_t(rx[3]) << 8) | uint32_t(rx[4]);
  count = static_cast<int32_t>(u);
  return true;
}

}  // namespace ls7366r

// ---------------------------------------------------------------- sensor

void QuadratureCounterSensor::loadSourceConfig(const mrpt::config::CConfigFileBase& ini,
                                               const std::string& section) {
  const std::string itf = ini.read_string(section, "interface", "spi", false);
  if (itf == "serial") {
    spi_ = false;
    LineSensor::loadSourceConfig(ini, section);
    return;
  }
  if (itf != "spi")
    throw std::invalid_argument(
        fmt::format("[{}] interface = '{}': expected spi or serial", section, itf));
  spi_ = true;
  dev_right_ = ini.read_string(section, "spi_device_right", dev_right_, false);
  dev_left_ = ini.read_string(section, "spi_device_left", dev_left_, false);
  speed_hz_ = static_cast<uint32_t>(ini.read_int(section, "spi_speed_hz", int(speed_hz_), false));
  const int mode = ini.read_int(section, "spi_mode", 0, false);
  if (mode < 0 || mode > 3)
    throw std::invalid_argument(fmt::format("[{}] spi_mode: 0..3", section));
  mode_ = static_cast<uint8_t>(mode);
  configure_ = ini.read_bool(section, "configure_counters", true, false);
  invert_right_ = ini.read_bool(section, "right_invert", false, false);
  invert_left_ = ini.read_bool(section, "left_invert", false, false);
  if (time_source_ != TimeSource::Arrival)
    throw std::invalid_argument(fmt::format(
        "[{}] time_source: the SPI counters have no clock; only arrival is possible", section));
  port_name_ = dev_right_ + "+" + dev_left_;
}

std::string QuadratureCounterSensor::deviceName() const {
  return spi_ ? dev_right_ + " + " + dev_left_ : port_name_;
}

bool QuadratureCounterSensor::openSpi() {
  auto make = [&](const std::string& dev, std::string& err) -> std::unique_ptr<SpiBus> {
    if (factory_) return factory_(dev, err);
    auto b = std::make_unique<SpidevBus>();
    if (!b->open(dev, speed_hz_, mode_, err)) return nullptr;
    return b;
  };
  std::string err;
  right_ = make(dev_right_, err);
  if (right_) left_ = make(dev_left_, err);
  if (right_ && left_ && configure_) {
    if (!ls7366r::configure(*right_, err))
      err = dev_right_ + ": " + err, right_.reset();
    else if (!ls7366r::configure(*left_, err))
      err = dev_left_ + ": " + err, left_.reset();
  }
  if (!right_ || !left_) {
    right_.reset();
    left_.reset();
    connectFailed(err);
    return false;
  }
  connected();
  next_tick_mono_ = HostClock::monotonic();
  return true;
}

void QuadratureCounterSensor::initialize() {
  if (!spi_) return LineSensor::initialize();
  m_state = ssWorking;
  openSpi();
}

void QuadratureCounterSensor::shutdown() {
  if (!spi_) return LineSensor::shutdown();
  right_.reset();
  left_.reset();
}

void QuadratureCounterSensor::doProcess() {
  if (!spi_) return LineSensor::doProcess();
  const double period = 1.0 / std::max(1.0, m_process_rate);
  if (!right_) {
    if (!reconnectDue() || !openSpi()) {
      std::this_thread::sleep_for(std::chrono::duration<double>(std::min(period, 0.05)));
      return;
    }
  }
  // Fixed-rate polling: one read of both counters per period.
  const double wait = next_tick_mono_ - HostClock::monotonic();
  if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait));
  next_tick_mono_ = std::max(next_tick_mono_ + period, HostClock::monotonic() - period);
  int32_t r = 0, l = 0;
  std::string err;
  const double t0 = HostClock::now();
  if (!ls7366r::readCounter(*right_, r, err) || !ls7366r::readCounter(*left_, l, err)) {
    right_.reset();
    left_.reset();
    disconnected(err);
    return;
  }
  const double t1 = HostClock::now();
  auto neg = [](int32_t x) { return static_cast<int32_t>(0u - static_cast<uint32_t>(x)); };
  if (invert_right_) r = neg(r);
  if (invert_left_) l = neg(l);
  emit(io::EncoderSample{0, r, l}, 0.5 * (t0 + t1), std::nullopt);
}

}  // namespace wheelchair::capture
