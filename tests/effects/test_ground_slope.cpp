#include "EffectTestUtil.h"

namespace wheelchair::effects::test {

TEST(GroundSlopeEffect, TruthActionIsTheColumnsOfTheModel) {
  // No inverse on a recording (it needs the heading): the corrected model carries the slope.
  // Its action on the drive train's inverse dynamics is the residual columns times the
  // coefficients sin(a) (cos h, sin h), at every heading.
  TruthModel t;
  t.drive = model::DriveTrain::symmetric(nominal().vehicle);
  const model::DriveTrain flat = t.drive;
  const std::string text = "ground_slope:angle_deg=3,downhill_heading_deg=40";
  findEffect("ground_slope")->actOnTruth(parseValidEffect(text), t);
  const Eigen::VectorXd b = coefficientOf(text, "ground_slope");
  const auto& v = nominal().vehicle;
  DriveSample s;
  s.alpha = 1.0 / (v.gearbox_efficiency * v.torque_constant_Nm_A);
  s.r_m = v.geom.wheel_radius_m, s.rG = v.geom.gear_ratio;
  s.Mg2_N = (v.geom.body_mass_kg + 2 * v.geom.wheel_mass_kg) * 9.81 / 2.0;
  const auto cols = findEffect("ground_slope")->driveColumns();
  for (double phi = -3; phi < 3; phi += 0.5) {
    const Eigen::Vector2d di =
        t.drive.currents({0.5, 0.1, phi}, 0, 0) - flat.currents({0.5, 0.1, phi}, 0, 0);
    s.cos_phi = std::cos(phi), s.sin_phi = std::sin(phi);
    const double col = cols[0].value(s) * b(0) + cols[1].value(s) * b(1);
    EXPECT_NEAR(di(0), col, 1e-3 * std::abs(col) + 1e-9) << phi;
    EXPECT_NEAR(di(1), col, 1e-3 * std::abs(col) + 1e-9) << phi;
  }
  const auto rec = drive({text}, "excite", 10);
  EXPECT_EQ(currents(corrected(rec, text), 0), currents(rec, 0));
}

TEST(GroundSlopeEffect, ResidualColumnsMatchFiniteDifference) {
  const TermCheck c =
      driveTermCheck("ground_slope:angle_deg=1,downhill_heading_deg=60", "ground_slope");
  EXPECT_GT(c.change_rms, 0.05);
  EXPECT_LT(c.relative_error, 0.35);
}

}  // namespace wheelchair::effects::test
