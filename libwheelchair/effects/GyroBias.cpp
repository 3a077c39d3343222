// gyro_bias(bias_rad_s): a constant offset of the gyro z reading.
//   truth      gyro_z = omega + b
//   inverse    gyro_z - b
//   residual   stage 1 window: y = int(gyro) - odometric turn = b T  (column T, coefficient b)
#include "libwheelchair/effects/Catalogue.h"

#include <fmt/format.h>

#include <cmath>

namespace wheelchair::effects {
namespace {

constexpr double kRad2Deg = 180.0 / M_PI;

struct GyroBiasParams {
  double bias_rad_s = 0;
  static GyroBiasParams of(const EffectSpec& e) { return {e.number("bias_rad_s")}; }
};

class GyroBias final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{
        "gyro_bias",
        "Constant offset of the gyro z reading.",
        {{"bias_rad_s", "rad/s", "added to every gyro z sample", "", {}, false, -10, 10, true}}};
    return i;
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    t.sensors.gyro_bias_rad_s += GyroBiasParams::of(e).bias_rad_s;
  }
  CorrectionPhase correctionPhase() const override { return CorrectionPhase::sensor; }
  void correct(const EffectSpec& e, io::Recording& rec, const CorrectionContext&) const override {
    const double b = GyroBiasParams::of(e).bias_rad_s;
    for (auto& s : rec.imu) s.gyro_z_rad_s -= b;
  }
  std::vector<KinematicColumn> kinematicColumns() const override {
    return {{"gyro_bias", [](const KinematicWindow& w) { return w.T_s; }}};
  }
  std::vector<ResidualTerm> residualTerms(const TermOptions&) const override {
    return {oneColumnTerm(
        "gyro_bias", Stage::kinematic,
        [](const Eigen::VectorXd& b) { return std::abs(b(0)) < 0.5; },
        [](const EffectSpec& e, const config::WheelchairConfig&) {
          return GyroBiasParams::of(e).bias_rad_s;
        })};
  }
  FindingText describe(const std::string&, const Eigen::VectorXd&, const Eigen::MatrixXd&,
                       const TermFit& fit) const override {
    const double b0 = fit.value("gyro_bias"), sb0 = fit.sd("gyro_bias");
    FindingText t;
    t.parameters = {{"bias_rad_s", b0}};
    t.uncertainty = {{"bias_rad_s", sb0}};
    t.channels = {"gyro"};
    t.description = fmt::format(
        "the gyro reads {:+.4f} rad/s ({:+.2f} deg/s) when the encoders say the chair does not "
        "turn: a "
        "constant gyro bias (+-{:.4f} rad/s); uncorrected it adds {:.1f} deg of heading per "
        "minute",
        b0, b0 * kRad2Deg, sb0, b0 * kRad2Deg * 60);
    return t;
  }
};

}  // namespace

const Effect& gyroBiasEffect() {
  static const GyroBias e;
  return e;
}

}  // namespace wheelchair::effects
