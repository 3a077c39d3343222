// sensor_delay(sensor, delay_s): one stream's timestamps lag: a measurement taken at t is
// stamped t + delay_s.
//   truth      that stream's stamps + delay_s
//   inverse    that stream's stamps - delay_s
//   residual   linearised in the delay d: stage 1 (gyro against encoders) window
//              y(d) ~ -d (omega_g(t1) - omega_g(t0)); stage 2 (currents against encoders)
//              y(d) ~ -d d(model current)/dt; coefficient +d for the imu / motors, -d when the
//              encoders lag instead (the diagnosis refines it by re-stamping)
#include "libwheelchair/effects/Catalogue.h"

#include <cmath>

namespace wheelchair::effects {
namespace {

struct SensorDelayParams {
  int stream = 0;
  double delay_s = 0;
  static SensorDelayParams of(const EffectSpec& e) {
    return {streamIndex(e.text("sensor")), e.number("delay_s")};
  }
};

template <class Samples>
void shiftStamps(Samples& v, double d) {
  for (auto& s : v) s.t_s -= d;
}

class SensorDelay final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{
        "sensor_delay",
        "One stream's timestamps lag: a measurement taken at t is stamped t + delay_s.",
        {{"sensor", "enum", "stream affected", "", streamNames()},
         {"delay_s", "s", "timestamp lag", "", {}, false, 0, 10, true}}};
    return i;
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    const auto p = SensorDelayParams::of(e);
    t.sensors.delay_s[p.stream] += p.delay_s;
  }
  CorrectionPhase correctionPhase() const override { return CorrectionPhase::sensor; }
  void correct(const EffectSpec& e, io::Recording& rec, const CorrectionContext&) const override {
    const auto p = SensorDelayParams::of(e);
    switch (p.stream) {
      case 0:
        return shiftStamps(rec.encoders, p.delay_s);
      case 1:
        return shiftStamps(rec.imu, p.delay_s);
      case 2:
        return shiftStamps(rec.motors, p.delay_s);
      case 3:
        return shiftStamps(rec.sonar, p.delay_s);
      case 4:
        return shiftStamps(rec.pozyx, p.delay_s);
      case 5:
        return shiftStamps(rec.joystick, p.delay_s);
    }
  }
  std::vector<KinematicColumn> kinematicColumns() const override {
    return {{"sensor_delay/imu", [](const KinematicWindow& w) { return -w.gyro_rate_change; }}};
  }
  std::vector<DriveColumn> driveColumns() const override {
    return {{"sensor_delay/motors", [](const DriveSample& s) { return -s.dpred_A_s; }}};
  }
  std::vector<ResidualTerm> residualTerms(const TermOptions& o) const override {
    if (!o.enable_delay) return {};
    // coefficient +d when the named stream lags, -d when the encoders lag instead
    auto term = [](const char* name, Stage stage, int stream) {
      return oneColumnTerm(
          name, stage, [](const Eigen::VectorXd& b) { return std::abs(b(0)) < 0.5; },
          [stream](const EffectSpec& e, const config::WheelchairConfig&) {
            const auto p = SensorDelayParams::of(e);
            return p.stream == stream ? p.delay_s : p.stream == 0 ? -p.delay_s : 0.0;
          });
    };
    return {term("sensor_delay/imu", Stage::kinematic, 1),
            term("sensor_delay/motors", Stage::dynamic, 2)};
  }
};

}  // namespace

const Effect& sensorDelayEffect() {
  static const SensorDelay e;
  return e;
}

}  // namespace wheelchair::effects
