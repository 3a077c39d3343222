// sensor_delay(sensor, delay_s): one stream's timestamps lag: a measurement taken at t is
// stamped t + delay_s.
//   truth      that stream's stamps + delay_s
//   inverse    that stream's stamps - delay_s
//   residual   linearised in the delay d: stage 1 (gyro against encoders) window
//              y(d) ~ -d (omega_g(t1) - omega_g(t0)); stage 2 (currents against encoders)
//              y(d) ~ -d d(model current)/dt; coefficient +d for the imu / motors, -d when the
//              encoders lag instead (the diagnosis refines it by re-stamping)
#include "libwheelchair/effects/Catalogue.h"

#include <fmt/format.h>

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
  /// The refined delay: sensor_delay/imu (gyro against encoders) or sensor_delay/motors
  /// (currents against encoders); a negative delay means the encoders lag instead.
  FindingText describe(const std::string& term, const Eigen::VectorXd&, const Eigen::MatrixXd& C,
                       const TermFit& fit) const override {
    const double delay = fit.delay_s;
    FindingText t;
    if (term == "sensor_delay/imu") {
      const std::string sensor = delay >= 0 ? "imu" : "encoders";
      const double sdel = fit.sd(term);
      t.parameters = {{"sensor", sensor}, {"delay_s", std::abs(delay)}};
      t.uncertainty = {{"delay_s", sdel}};
      t.channels = {sensor == "imu" ? "gyro" : "encoders"};
      t.description = fmt::format(
          "the {} stream is time-stamped {:.1f} ms late relative to the {} (+- {:.1f} ms): the "
          "gyro integral "
          "lags the odometric heading change whenever the turn rate changes",
          sensor == "imu" ? "gyro" : "encoder", 1000 * std::abs(delay),
          sensor == "imu" ? "encoders" : "gyro", 1000 * sdel);
      return t;
    }
    const std::string sensor = delay >= 0 ? "motors" : "encoders";
    t.parameters = {{"sensor", sensor}, {"delay_s", std::abs(delay)}};
    t.uncertainty = {{"delay_s", std::sqrt(C(0, 0))}};
    t.channels = {sensor == "motors" ? "currents" : "encoders"};
    t.description = fmt::format(
        "the {} are time-stamped {:.1f} ms (+- {:.1f}) late relative to the {}: {}",
        sensor == "motors" ? "motor currents" : "encoder counts", 1000 * std::abs(delay),
        1000 * std::sqrt(C(0, 0)), sensor == "motors" ? "encoders" : "motor currents",
        sensor == "motors" ? "the current leads the acceleration it causes"
                           : "the motion lags the current that causes it");
    return t;
  }
};

}  // namespace

const Effect& sensorDelayEffect() {
  static const SensorDelay e;
  return e;
}

}  // namespace wheelchair::effects
