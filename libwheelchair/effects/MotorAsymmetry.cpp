// motor_asymmetry(side, friction_ratio[, km_ratio]): one drive differs from the other.
//   truth      that side's B_m x friction_ratio and k_m x km_ratio (also the back-EMF)
//   inverse    the extra viscous current removed from that motor's measured current:
//              i -= (friction_ratio - 1) B_m/k_m (r_G/r) u  (u: corrected rim speed)
//   residual   stage 2, that motor's equation error: (ratio - 1) theta5 (r_G/r) u
//              (column theta5 (r_G/r) u on that side's rows, coefficient friction_ratio - 1)
#include "libwheelchair/effects/Catalogue.h"

#include <cmath>

#include <fmt/format.h>

namespace wheelchair::effects {
namespace {

struct MotorAsymmetryParams {
  std::vector<int> sides;
  double friction_ratio = 1, km_ratio = 1;
  static MotorAsymmetryParams of(const EffectSpec& e) {
    return {effectSides(e), e.number("friction_ratio"), e.number("km_ratio")};
  }
};

class MotorAsymmetry final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{
        "motor_asymmetry",
        "One drive differs from the other: its gearbox has more viscous friction (B_m times "
        "friction_ratio) and/or its motor torque constant differs (k_m times km_ratio). Fig. 6c.",
        {{"side", "enum", "the drive that differs", "", sideChoices()},
         {"friction_ratio",
          "-",
          "true B_m of that side / nominal B_m",
          "1",
          {},
          false,
          0,
          100,
          false},
         {"km_ratio",
          "-",
          "true k_m of that side / nominal k_m (also the back-EMF constant)",
          "1",
          {},
          false,
          0,
          10,
          false}}};
    return i;
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    const auto p = MotorAsymmetryParams::of(e);
    for (int s : p.sides) {
      t.drive.side[s].motor_viscous_Nm_s_rad *= p.friction_ratio;
      t.drive.side[s].torque_constant_Nm_A *= p.km_ratio;
    }
  }
  CorrectionPhase correctionPhase() const override { return CorrectionPhase::drive; }
  void correct(const EffectSpec& e, io::Recording& rec,
               const CorrectionContext& ctx) const override {
    const auto p = MotorAsymmetryParams::of(e);
    const auto& v = ctx.cfg.vehicle;
    const double viscous_A_per_m_s = v.motor_viscous_Nm_s_rad / v.torque_constant_Nm_A *
                                     v.geom.gear_ratio / v.geom.wheel_radius_m;
    for (const int side : p.sides)
      for (auto& s : rec.motors) {
        double& i = side == 0 ? s.current_right_A : s.current_left_A;
        i -= (p.friction_ratio - 1.0) * viscous_A_per_m_s * ctx.rim_speeds(s.t_s)(side);
      }
  }
  std::vector<DriveColumn> driveColumns() const override {
    std::vector<DriveColumn> c;
    for (int side = 0; side < 2; ++side)
      c.push_back({"motor_asymmetry/" + sideChoices()[side], [side](const DriveSample& s) {
                     return s.side == side ? s.theta5 * (s.rG / s.r_m) * s.u_m_s : 0.0;
                   }});
    return c;
  }
  std::vector<ResidualTerm> residualTerms(const TermOptions&) const override {
    return sidedTerms(
        "motor_asymmetry", Stage::dynamic,
        [](const Eigen::VectorXd& b) { return 1 + b(0) > 0.1 && 1 + b(0) < 10; },
        [](const EffectSpec& e) { return MotorAsymmetryParams::of(e).friction_ratio - 1; });
  }
  /// Both sides' terms make one finding: the side with more viscous friction and the ratio.
  FindingText describe(const std::string&, const Eigen::VectorXd&, const Eigen::MatrixXd&,
                       const TermFit& fit) const override {
    const auto& v = fit.cfg->vehicle;
    const double theta5 = v.motor_viscous_Nm_s_rad / v.torque_constant_Nm_A;
    const double rGr = v.geom.gear_ratio / v.geom.wheel_radius_m;
    const double asym[2] = {fit.value("motor_asymmetry/right"), fit.value("motor_asymmetry/left")};
    const double sasym[2] = {fit.sd("motor_asymmetry/right"), fit.sd("motor_asymmetry/left")};
    const bool both = fit.has("motor_asymmetry/right") && fit.has("motor_asymmetry/left");
    const double fr = 1 + asym[0], fl = 1 + asym[1];
    const int side = fr >= fl ? 0 : 1;
    const double ratio = side == 0 ? fr / fl : fl / fr;
    const double sr = ratio * std::hypot(sasym[0] / fr, sasym[1] / fl);
    const std::string& name = sideChoices()[side];
    FindingText t;
    t.parameters = {{"side", name}, {"friction_ratio", ratio}};
    t.uncertainty = {{"friction_ratio", sr}};
    t.channels = {side == 0 ? "current_right" : "current_left"};
    if (both) t.channels = {"current_right", "current_left"};
    const double dI = std::abs(asym[0] - asym[1]) * theta5 * rGr * 0.8;
    t.description = fmt::format(
        "the {} drive needs {:.2f} A more than the {} to go straight at 0.8 m/s: unequal "
        "gearbox "
        "(viscous) friction, {:.0f}% more on the {} (friction ratio {:.3f} +- {:.3f}); the "
        "symmetric "
        "model (6) reads the current difference as a turn",
        name, dI, sideChoices()[1 - side], (ratio - 1) * 100, name, ratio, sr);
    if (both) t.parameters["friction_ratio_right_left"] = {fr, fl};
    return t;
  }
};

}  // namespace

const Effect& motorAsymmetryEffect() {
  static const MotorAsymmetry e;
  return e;
}

}  // namespace wheelchair::effects
