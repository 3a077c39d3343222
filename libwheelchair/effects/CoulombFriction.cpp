// coulomb_friction(current_A[, side]): dry friction in a drive, as the motor current it costs.
//   truth      c sgn(u_i) in that side's torque balance (tanh-smoothed, [simulation]
//              coulomb_smoothing_m_s)
//   inverse    i -= c tanh(u / 0.01 m/s) on the affected motors (u: corrected rim speed)
//   residual   stage 2: c sgn(u) on the affected motors' rows (column tanh(u/eps) filtered,
//              coefficient c); `both` is one coefficient over both sides' columns
#include "libwheelchair/effects/Catalogue.h"

#include <fmt/format.h>

#include <cmath>

namespace wheelchair::effects {
namespace {

struct CoulombFrictionParams {
  std::vector<int> sides;
  double current_A = 0;
  static CoulombFrictionParams of(const EffectSpec& e) {
    return {effectSides(e), e.number("current_A")};
  }
};

class CoulombFriction final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{
        "coulomb_friction",
        "Dry (Coulomb) friction in a drive, expressed as the motor current it costs: "
        "c sgn(u_i) in the torque balance (smoothed with tanh, [simulation] "
        "coulomb_smoothing_m_s).",
        {{"current_A", "A", "dry friction current per affected motor", "", {}, false, 0, 100, true},
         {"side", "enum", "drive affected", "both", sideChoicesBoth()}}};
    return i;
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    const auto p = CoulombFrictionParams::of(e);
    for (int s : p.sides) t.drive.side[s].coulomb_A += p.current_A;
  }
  CorrectionPhase correctionPhase() const override { return CorrectionPhase::drive; }
  void correct(const EffectSpec& e, io::Recording& rec,
               const CorrectionContext& ctx) const override {
    const auto p = CoulombFrictionParams::of(e);
    for (const int side : p.sides)
      for (auto& s : rec.motors) {
        double& i = side == 0 ? s.current_right_A : s.current_left_A;
        i -= p.current_A * std::tanh(ctx.rim_speeds(s.t_s)(side) / 0.01);
      }
  }
  std::vector<DriveColumn> driveColumns() const override {
    std::vector<DriveColumn> c;
    for (int side = 0; side < 2; ++side)
      c.push_back({"coulomb_friction/" + sideChoices()[side],
                   [side](const DriveSample& s) { return s.side == side ? s.sgn_u : 0.0; }});
    return c;
  }
  std::vector<ResidualTerm> residualTerms(const TermOptions&) const override {
    auto ok = [](const Eigen::VectorXd& b) { return b(0) > 0 && b(0) < 10; };
    std::vector<ResidualTerm> out;
    for (const std::string side : {"both", "right", "left"}) {
      ResidualTerm t;
      t.name = "coulomb_friction/" + side;
      t.stage = Stage::dynamic;
      t.coefficients = side == "both"
                           ? std::vector<std::vector<std::string>>{{"coulomb_friction/right",
                                                                    "coulomb_friction/left"}}
                           : oneColumn(t.name);
      if (side == "both") t.conflicts = {"coulomb_friction/right", "coulomb_friction/left"};
      t.plausible = ok;
      t.coefficientOf = [side](const EffectSpec& e, const config::WheelchairConfig&) {
        return Eigen::VectorXd::Constant(1, e.text("side") == side ? e.number("current_A") : 0.0);
      };
      out.push_back(t);
    }
    return out;
  }
  FindingText describe(const std::string& term, const Eigen::VectorXd& b, const Eigen::MatrixXd& C,
                       const TermFit&) const override {
    const std::string side = term.substr(term.find('/') + 1);
    FindingText t;
    t.parameters = {{"current_A", b(0)}, {"side", side}};
    t.uncertainty = {{"current_A", std::sqrt(C(0, 0))}};
    if (side != "both") t.channels = {"current_" + side};
    t.description = fmt::format(
        "{} needs {:.3f} A (+- {:.3f}) more current at any speed, in the direction of "
        "motion: dry "
        "(Coulomb) friction in the drive, not modelled by the viscous term of (6)",
        side == "both" ? "each motor" : "the " + side + " motor", b(0), std::sqrt(C(0, 0)));
    return t;
  }
};

}  // namespace

const Effect& coulombFrictionEffect() {
  static const CoulombFriction e;
  return e;
}

}  // namespace wheelchair::effects
