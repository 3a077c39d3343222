// encoder_scale(side, scale[, from_s]): a wrong encoder pulley ratio N_ep/N_mp on one side
// (or both), from the start or (from_s > 0) as a step fault from_s s after the start.
//   truth      that encoder counts scale x the true wheel rotation (after from_s: its count
//              at from_s + scale x the rotation since then)
//   inverse    that side's unwrapped cumulative ticks / scale (re-wrapped; < 1 tick error);
//              with from_s, only the ticks counted after from_s s past the first encoder
//              sample are divided
//   residual   stage 1 window, gyro scale g = 1: y = int(gyro) - (dR - dL)/l_w with
//              dR = scale dR_true: column dR/l_w (right) or -dL/l_w (left), coefficient
//              1/scale - 1 (the diagnosis reports scale = g / (1 + b_g + b))
#include "libwheelchair/effects/Catalogue.h"

#include <fmt/format.h>
#include "libwheelchair/sensors/Encoders.h"

#include <algorithm>
#include <cmath>

namespace wheelchair::effects {
namespace {

constexpr double kRad2Deg = 180.0 / M_PI;

struct EncoderScaleParams {
  std::vector<int> sides;
  double scale = 1;
  double from_s = 0;  ///< s since the start; 0: from the start
  static EncoderScaleParams of(const EffectSpec& e) {
    return {effectSides(e), e.number("scale"), e.has("from_s") ? e.number("from_s") : 0.0};
  }
};

class EncoderScale final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{
        "encoder_scale",
        "Wrong encoder pulley ratio N_ep/N_mp on one side: the encoder reports scale times the "
        "true wheel rotation.",
        {{"side", "enum", "encoder affected", "", sideChoicesBoth()},
         {"scale", "-", "reported distance / true distance", "", {}, false, 0, 10, false},
         {"from_s",
          "s",
          "time since the start from which the scale applies (a step fault; the count stays "
          "continuous)",
          "0",
          {},
          false,
          0,
          1e7,
          true}}};
    return i;
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    const auto p = EncoderScaleParams::of(e);
    for (int s : p.sides) {
      t.sensors.encoder_scale[s] *= p.scale;
      t.sensors.encoder_from_s[s] = std::max(t.sensors.encoder_from_s[s], p.from_s);
    }
  }
  CorrectionPhase correctionPhase() const override { return CorrectionPhase::sensor; }
  void correct(const EffectSpec& e, io::Recording& rec, const CorrectionContext&) const override {
    const auto p = EncoderScaleParams::of(e);
    if (!(p.scale > 0)) return;
    if (rec.encoders.empty()) return;
    const double t_step = rec.encoders.front().t_s + p.from_s;
    for (const int side : p.sides) {
      sensors::TickUnwrapper unwrap;
      bool anchored = p.from_s <= 0;
      double anchor = 0;  // cumulative ticks at the step (0: scaled from the start)
      for (auto& s : rec.encoders) {
        int32_t& raw = side == 0 ? s.right_ticks : s.left_ticks;
        const double c = static_cast<double>(unwrap.unwrap(raw));
        if (!anchored && s.t_s < t_step) continue;  // before the step: true already
        if (!anchored) anchor = c, anchored = true;
        raw = sensors::toHardwareCounter(std::llround(anchor + (c - anchor) / p.scale));
      }
    }
  }
  std::vector<KinematicColumn> kinematicColumns() const override {
    return {{"encoder_scale/right", [](const KinematicWindow& w) { return w.dR_m / w.track_m; }},
            {"encoder_scale/left", [](const KinematicWindow& w) { return -w.dL_m / w.track_m; }}};
  }
  std::vector<ResidualTerm> residualTerms(const TermOptions&) const override {
    return sidedTerms(
        "encoder_scale", Stage::kinematic,
        [](const Eigen::VectorXd& b) { return 1 + b(0) > 0.5 && 1 + b(0) < 2.0; },
        [](const EffectSpec& e) { return 1 / EncoderScaleParams::of(e).scale - 1; });
  }
  /// The diagnosis fits gyro scale b_g and the side's b together: scale = g / (1 + b_g + b).
  FindingText describe(const std::string& term, const Eigen::VectorXd&, const Eigen::MatrixXd&,
                       const TermFit& fit) const override {
    const int s = term == "encoder_scale/right" ? 0 : 1;
    const double lw = fit.cfg->vehicle.geom.track_width_m;
    const double bg = fit.value("gyro_scale"), g = 1 + bg;
    const double b = fit.value(term), sb = fit.sd(term);
    const double ks = g / (1 + bg + b);
    const double sk = sb * std::abs(g) / std::pow(1 + bg + b, 2);
    const std::string side = sideChoices()[s];
    FindingText t;
    t.parameters = {{"side", side}, {"scale", ks}};
    t.uncertainty = {{"scale", sk}};
    t.channels = {"encoders"};
    t.description = fmt::format(
        "the {} encoder reports {:.4f} x the distance its wheel rolls (+- {:.4f}; the gyro and "
        "the other "
        "encoder agree): a wrong pulley ratio on that side; uncorrected, odometry drifts to "
        "the {} by "
        "{:.1f} deg per 10 m driven straight",
        side, ks, sk, (s == 0) == (ks < 1) ? "right" : "left",
        std::abs(10.0 * (1 - ks) / lw) * kRad2Deg);
    return t;
  }
};

}  // namespace

const Effect& encoderScaleEffect() {
  static const EncoderScale e;
  return e;
}

}  // namespace wheelchair::effects
