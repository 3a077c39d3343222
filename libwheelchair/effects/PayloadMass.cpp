// payload_mass(body_mass_kg): the true mass of chair body with user differs from [vehicle].
//   truth      m_b = body_mass_kg in the drive train
//   inverse    none on the data: [vehicle] body_mass_kg is set in the configuration
//              (adjustConfig)
//   residual   stage 2: dm alpha (r/r_G) vdot / 2 per motor (column alpha (r/r_G) vdot / 2,
//              coefficient body_mass_kg - configured m_b)
#include "libwheelchair/effects/Catalogue.h"

#include <cmath>

#include <fmt/format.h>

namespace wheelchair::effects {
namespace {

struct PayloadMassParams {
  double body_mass_kg = 0;
  static PayloadMassParams of(const EffectSpec& e) { return {e.number("body_mass_kg")}; }
};

class PayloadMass final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{
        "payload_mass",
        "The true mass of chair body with user differs from the configuration.",
        {{"body_mass_kg",
          "kg",
          "true m_b (replaces [vehicle] body_mass_kg)",
          "",
          {},
          false,
          0,
          1000,
          false}}};
    return i;
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    t.drive.geom.body_mass_kg = PayloadMassParams::of(e).body_mass_kg;
  }
  void adjustConfig(const EffectSpec& e, config::WheelchairConfig& c) const override {
    c.set("vehicle", "body_mass_kg", e.text("body_mass_kg"));
  }
  std::vector<DriveColumn> driveColumns() const override {
    return {{"payload_mass",
             [](const DriveSample& s) { return s.alpha * (s.r_m / s.rG) * s.vdot_m_s2 / 2.0; }}};
  }
  std::vector<ResidualTerm> residualTerms(const TermOptions& o) const override {
    const double m = o.body_mass_kg;
    return {oneColumnTerm(
        "payload_mass", Stage::dynamic,
        [m](const Eigen::VectorXd& b) { return m + b(0) > 0.2 * m && m + b(0) < 5 * m; },
        [](const EffectSpec& e, const config::WheelchairConfig& cfg) {
          return PayloadMassParams::of(e).body_mass_kg - cfg.vehicle.geom.body_mass_kg;
        })};
  }
  FindingText describe(const std::string&, const Eigen::VectorXd& b, const Eigen::MatrixXd& C,
                       const TermFit& fit) const override {
    const auto& g = fit.cfg->vehicle.geom;
    const double mb = g.body_mass_kg, m = mb + b(0);
    FindingText t;
    t.parameters = {{"body_mass_kg", m}};
    t.uncertainty = {{"body_mass_kg", std::sqrt(C(0, 0))}};
    t.description = fmt::format(
        "accelerating takes {:.0f}% {} current than the model predicts with the same cruise "
        "current: "
        "the mass of chair and user is {:.1f} kg (+- {:.1f}), not the configured {:.1f} kg",
        std::abs(b(0)) / (mb + 2 * g.wheel_mass_kg + 17.1) * 100, b(0) > 0 ? "more" : "less", m,
        std::sqrt(C(0, 0)), mb);
    return t;
  }
};

}  // namespace

const Effect& payloadMassEffect() {
  static const PayloadMass e;
  return e;
}

}  // namespace wheelchair::effects
