// gyro_scale(scale): scale-factor error of the gyro z reading.
//   truth      gyro_z = scale omega
//   inverse    gyro_z / scale
//   residual   stage 1 window: y = (scale - 1) (dR - dL) / l_w  (column (dR - dL)/l_w,
//              coefficient scale - 1)
#include "libwheelchair/effects/Catalogue.h"

#include <cmath>

#include <fmt/format.h>

namespace wheelchair::effects {
namespace {

struct GyroScaleParams {
  double scale = 1;
  static GyroScaleParams of(const EffectSpec& e) { return {e.number("scale")}; }
};

class GyroScale final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{
        "gyro_scale",
        "Scale-factor error of the gyro z reading.",
        {{"scale", "-", "reported rate / true rate", "", {}, false, 0, 10, false}}};
    return i;
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    t.sensors.gyro_scale *= GyroScaleParams::of(e).scale;
  }
  CorrectionPhase correctionPhase() const override { return CorrectionPhase::sensor; }
  void correct(const EffectSpec& e, io::Recording& rec, const CorrectionContext&) const override {
    const double g = GyroScaleParams::of(e).scale;
    if (g > 0)
      for (auto& s : rec.imu) s.gyro_z_rad_s /= g;
  }
  std::vector<KinematicColumn> kinematicColumns() const override {
    return {{"gyro_scale", [](const KinematicWindow& w) { return (w.dR_m - w.dL_m) / w.track_m; }}};
  }
  std::vector<ResidualTerm> residualTerms(const TermOptions&) const override {
    return {oneColumnTerm(
        "gyro_scale", Stage::kinematic,
        [](const Eigen::VectorXd& b) { return 1 + b(0) > 0.5 && 1 + b(0) < 2.0; },
        [](const EffectSpec& e, const config::WheelchairConfig&) {
          return GyroScaleParams::of(e).scale - 1;
        })};
  }
  FindingText describe(const std::string&, const Eigen::VectorXd&, const Eigen::MatrixXd&,
                       const TermFit& fit) const override {
    const double bg = fit.value("gyro_scale"), sbg = fit.sd("gyro_scale");
    const double g = 1 + bg;
    FindingText t;
    t.parameters = {{"scale", g}};
    t.uncertainty = {{"scale", sbg}};
    t.channels = {"gyro"};
    t.description = fmt::format(
        "the gyro reports {:.2f}% {} turn than both encoders agree on (scale {:.4f} +- "
        "{:.4f}): a gyro "
        "scale-factor error (symmetric in both wheels, so not an encoder fault)",
        std::abs(bg) * 100, bg > 0 ? "more" : "less", g, sbg);
    return t;
  }
};

}  // namespace

const Effect& gyroScaleEffect() {
  static const GyroScale e;
  return e;
}

}  // namespace wheelchair::effects
