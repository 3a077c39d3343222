// The quadrature-counter board on SPI (LS7366R protocol through spidev's SPI_IOC_MESSAGE),
// tested against an emulated chip since no hardware is attached.
#include "CaptureTestUtil.h"

#include "libwheelchair/capture/QuadratureCounterSensor.h"

#include <atomic>

using namespace wheelchair;
using namespace wheelchair::capture;

namespace {

// An LS7366R as seen through the SPI bus: MDR0/MDR1 registers and a 32-bit counter.
struct FakeChip {
  std::atomic<int32_t> count{0};
  uint8_t mdr0 = 0, mdr1 = 0;
  bool present = true;
  std::atomic<bool> fail{false};
  int transfers = 0;
};

class FakeBus : public SpiBus {
 public:
  explicit FakeBus(FakeChip& c) : c_(c) {}
  bool transfer(const uint8_t* tx, uint8_t* rx, std::size_t n, std::string& error) override {
    ++c_.transfers;
    if (c_.fail) {
      error = "SPI transfer: Input/output error";
      return false;
    }
    std::fill(rx, rx + n, c_.present ? 0x00 : 0xFF);
    if (!c_.present) return true;  // MISO floats high: reads 0xFF
    switch (tx[0]) {
      case ls7366r::kWriteMdr0:
        c_.mdr0 = tx[1];
        break;
      case ls7366r::kWriteMdr1:
        c_.mdr1 = tx[1];
        break;
      case ls7366r::kReadMdr0:
        rx[1] = c_.mdr0;
        break;
      case ls7366r::kReadCntr: {
        const auto u = static_cast<uint32_t>(c_.count.load());
        for (int i = 0; i < 4; ++i) rx[1 + i] = static_cast<uint8_t>(u >> (24 - 8 * i));
        break;
      }
      default:
        break;
    }
    return true;
  }

 private:
  FakeChip& c_;
};

std::unique_ptr<QuadratureCounterSensor> makeSensor(FakeChip& right, FakeChip& left,
                                                    const std::string& extra = "") {
  auto s = std::make_unique<QuadratureCounterSensor>();
  s->setBusFactory(
      [&right, &left](const std::string& dev, std::string&) -> std::unique_ptr<SpiBus> {
        return std::make_unique<FakeBus>(dev == "/dev/spidev0.0" ? right : left);
      });
  mrpt::config::CConfigFileMemory ini(
      "[encoders]\ndriver = QuadratureCounterSensor\nprocess_rate = 200\n"
      "interface = spi\nreconnect_min_s = 0.01\nreconnect_max_s = 0.02\n" +
      extra);
  s->loadConfig(ini, "encoders");
  return s;
}

std::vector<io::EncoderSample> drain(QuadratureCounterSensor& s) {
  std::vector<io::EncoderSample> v;
  for (auto& [t, o] : s.getObservations()) {
    auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(o);
    EXPECT_EQ(obs->sensorLabel, "ENCODERS");
    v.push_back(std::get<io::EncoderSample>(*io::fromObservation(*obs)));
  }
  return v;
}

}  // namespace

TEST(SpiCounter, ReadsBothCountersMsbFirstIncludingWrapAndNegatives) {
  FakeChip r, l;
  r.count = std::numeric_limits<int32_t>::max();
  l.count = -123456789;
  auto s = makeSensor(r, l);
  EXPECT_TRUE(s->usesSpi());
  s->initialize();
  EXPECT_EQ(r.mdr0, ls7366r::kMdr0Quadrature4x);  // x4 quadrature, free-running
  EXPECT_EQ(l.mdr1, ls7366r::kMdr1FourByte);      // 4-byte counter
  s->doProcess();
  r.count = std::numeric_limits<int32_t>::min();  // wrapped past 2^31
  s->doProcess();
  const auto v = drain(*s);
  ASSERT_EQ(v.size(), 2u);
  EXPECT_EQ(v[0].right_ticks, std::numeric_limits<int32_t>::max());
  EXPECT_EQ(v[0].left_ticks, -123456789);
  EXPECT_EQ(v[1].right_ticks, std::numeric_limits<int32_t>::min());
  EXPECT_LT(v[0].t_s, v[1].t_s);  // arrival stamps at the polling rate
}

TEST(SpiCounter, PolledAtTheProcessRate) {
  FakeChip r, l;
  auto s = makeSensor(r, l);  // process_rate = 200
  s->initialize();
  for (int i = 0; i < 21; ++i) s->doProcess();
  const auto v = drain(*s);
  ASSERT_EQ(v.size(), 21u);
  const double span = v.back().t_s - v.front().t_s;  // 20 periods of 5 ms, give or take one
  EXPECT_GT(span, 0.095);
  EXPECT_LT(span, 0.3);
}

TEST(SpiCounter, InvertedCounterIsNegatedModulo2To32) {
  FakeChip r, l;
  r.count = 10;
  l.count = std::numeric_limits<int32_t>::min();
  auto s = makeSensor(r, l, "left_invert = 1\n");
  s->initialize();
  s->doProcess();
  const auto v = drain(*s);
  ASSERT_EQ(v.size(), 1u);
  EXPECT_EQ(v[0].right_ticks, 10);
  EXPECT_EQ(v[0].left_ticks, std::numeric_limits<int32_t>::min());  // -(-2^31) wraps to itself
}

TEST(SpiCounter, MissingBoardIsRetriedAndATransferErrorReconnects) {
  FakeChip r, l;
  r.present = false;  // board unplugged: MDR0 reads back 0xFF
  auto s = makeSensor(r, l);
  s->initialize();
  EXPECT_FALSE(s->status().connected);
  EXPECT_NE(s->status().last_error.find("does not answer"), std::string::npos);
  s->doProcess();
  EXPECT_TRUE(drain(*s).empty());
  r.present = true;  // plugged in
  for (int i = 0; i < 20 && drain(*s).empty(); ++i) s->doProcess();
  EXPECT_TRUE(s->status().connected);
  r.fail = true;  // the cable comes off mid-drive
  s->doProcess();
  EXPECT_FALSE(s->status().connected);
  EXPECT_EQ(s->status().disconnects, 1u);
  r.fail = false;
  std::vector<io::EncoderSample> v;
  for (int i = 0; i < 20 && v.empty(); ++i) {
    s->doProcess();
    v = drain(*s);
  }
  EXPECT_FALSE(v.empty());
  EXPECT_EQ(s->status().connects, 2u);
  EXPECT_EQ(s->status().gaps, 1u);
  bool gap_logged = false;
  for (const auto& e : s->takeEvents())
    gap_logged = gap_logged || e.text.find("gap in ENCODERS") != std::string::npos;
  EXPECT_TRUE(gap_logged);
}

TEST(SpiCounter, RealSpidevAbsentIsAConnectionErrorNotACrash) {
  auto s = std::make_unique<QuadratureCounterSensor>();
  mrpt::config::CConfigFileMemory ini(
      "[e]\ninterface = spi\nspi_device_right = /nonexistent/spidev9.0\nspi_device_left = "
      "/nonexistent/spidev9.1\n");
  s->loadConfig(ini, "e");
  s->initialize();
  EXPECT_FALSE(s->status().connected);
  EXPECT_NE(s->status().last_error.find("No such file"), std::string::npos);
  s->doProcess();  // retries quietly
}

TEST(SpiCounter, SerialFallbackReadsLines) {
  auto s = std::make_unique<QuadratureCounterSensor>();
  mrpt::config::CConfigFileMemory ini(
      "[e]\ninterface = serial\nserial_port = /nonexistent\ntime_source = device\n");
  s->loadConfig(ini, "e");
  EXPECT_FALSE(s->usesSpi());
  const std::string lines = "1.5,100,-100\n1.52,105,-94\n";
  s->feed(lines.data(), lines.size(), 0.0);
  const auto v = drain(*s);
  ASSERT_EQ(v.size(), 2u);
  EXPECT_EQ(v[1].right_ticks, 105);
  EXPECT_EQ(v[1].t_s, 1.52);
}
