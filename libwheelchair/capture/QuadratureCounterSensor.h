// The encoders' hardware counter (paper Table IV: "2x 32 bit quadrature encoder counter",
// read by the Raspberry Pi): two LS7366R-type 32-bit quadrature counters on SPI, one chip
// select each (Linux spidev: /dev/spidev0.0 = right, /dev/spidev0.1 = left by default).
//
//   interface = spi     polls both counters at process_rate through SPI_IOC_MESSAGE
//                       (opcode RD_CNTR 0x60, then 4 bytes MSB first); stamps = arrival time
//   interface = serial  text fallback (LineSensor): lines "{t},{right_ticks},{left_ticks}" from
//                       a board or a logger that reads the counters, or from the replay
//
// SPI keys: spi_device_right, spi_device_left, spi_speed_hz (1 MHz), spi_mode (0),
// configure_counters (1: write MDR0 = x4 quadrature free-running, MDR1 = 4-byte counter at
// start, and read MDR0 back to detect a missing board; the counts are never cleared, so
// they stay absolute across reconnects), right_invert / left_invert (0: a counter that
// counts down when its wheel rolls forward is negated, modulo 2^32).
#pragma once

#include "libwheelchair/capture/LineSensor.h"

#include <cstdint>
#include <functional>
#include <memory>

namespace wheelchair::capture {

/// One full-duplex SPI transfer per call (chip select held for the whole buffer).
class SpiBus {
 public:
  virtual ~SpiBus() = default;
  virtual bool transfer(const uint8_t* tx, uint8_t* rx, std::size_t n, std::string& error) = 0;
};

/// Linux spidev: open() configures mode, 8 bits per word and the clock; transfer() is one
/// ioctl(SPI_IOC_MESSAGE(1)).
class SpidevBus : public SpiBus {
 public:
  ~SpidevBus() override;
  bool open(const std::string& device, uint32_t speed_hz, uint8_t mode, std::string& error);
  bool transfer(const uint8_t* tx, uint8_t* rx, std::size_t n, std::string& error) override;

 private:
  int fd_ = -1;
  uint32_t speed_hz_ = 0;
  std::string device_;
};

/// LS7366R register protocol (the counter chip of common dual-encoder SPI boards).
namespace ls7366r {
constexpr uint8_t kWriteMdr0 = 0x88, kWriteMdr1 = 0x90, kReadMdr0 = 0x48, kReadCntr = 0x60,
                  kClearCntr = 0x20;
constexpr uint8_t kMdr0Quadrature4x = 0x03;  ///< x4 quadrature, free-running, no index
constexpr uint8_t kMdr1FourByte = 0x00;      ///< 4-byte counter, counting enabled
/// Writes MDR0/MDR1 and reads MDR0 back; false (error set) when the chip does not answer.
bool configure(SpiBus& bus, std::string& error);
/// Reads the 32-bit counter.
bool readCounter(SpiBus& bus, int32_t& count, std::string& error);
}  // namespace ls7366r

class QuadratureCounterSensor : public LineSensor {
  DEFINE_GENERIC_SENSOR(QuadratureCounterSensor)

 public:
  using BusFactory =
      std::function<std::unique_ptr<SpiBus>(const std::string& device, std::string& error)>;
  QuadratureCounterSensor() : LineSensor(io::StreamKind::Encoders) {}
  /// Replaces spidev (tests: an emulated counter). Call before initialize().
  void setBusFactory(BusFactory f) { factory_ = std::move(f); }
  bool usesSpi() const { return spi_; }

  void initialize() override;
  void doProcess() override;
  void shutdown() override;
  std::string deviceName() const override;

 protected:
  void loadSourceConfig(const mrpt::config::CConfigFileBase& ini,
                        const std::string& section) override;

 private:
  bool openSpi();
  bool spi_ = false;
  std::string dev_right_ = "/dev/spidev0.0", dev_left_ = "/dev/spidev0.1";
  uint32_t speed_hz_ = 1000000;
  uint8_t mode_ = 0;
  bool configure_ = true, invert_right_ = false, invert_left_ = false;
  BusFactory factory_;
  std::unique_ptr<SpiBus> right_, left_;
  double next_tick_mono_ = 0;
};

}  // namespace wheelchair::capture
