// ground_slope(angle_deg[, downhill_heading_deg]): the floor is an inclined plane.
//   truth      gravity along the heading: (m_b + 2 m_w) g sin(a) cos(phi - h) in the drive
//   inverse    none on the data (it needs the heading): the corrected model carries it
//              (the diagnosis figures apply actOnTruth to their drive train)
//   residual   stage 2 per motor: -alpha (r/r_G) M g/2 (s_c cos(phi) + s_s sin(phi)) with
//              (s_c, s_s) = sin(a) (cos h, sin h) (two columns, two coefficients)
#include "libwheelchair/effects/Catalogue.h"

#include <Eigen/Core>

#include <fmt/format.h>

#include <cmath>

namespace wheelchair::effects {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kRad2Deg = 180.0 / M_PI;

struct GroundSlopeParams {
  double angle_deg = 0, downhill_heading_deg = 0;
  static GroundSlopeParams of(const EffectSpec& e) {
    return {e.number("angle_deg"), e.number("downhill_heading_deg")};
  }
};

class GroundSlope final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{
        "ground_slope",
        "The floor is an inclined plane: gravity pulls along the heading with "
        "(m_b + 2 m_w) g sin(angle) cos(phi - downhill_heading).",
        {{"angle_deg", "deg", "inclination of the floor", "", {}, false, -30, 30, true},
         {"downhill_heading_deg",
          "deg",
          "heading in the start frame that points downhill",
          "0",
          {},
          false,
          -360,
          360,
          true}}};
    return i;
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    const auto p = GroundSlopeParams::of(e);
    t.drive.slope_rad = p.angle_deg * kDeg;
    t.drive.downhill_heading_rad = p.downhill_heading_deg * kDeg;
  }
  std::vector<DriveColumn> driveColumns() const override {
    return {{"ground_slope/cos",
             [](const DriveSample& s) { return -s.alpha * (s.r_m / s.rG) * s.Mg2_N * s.cos_phi; }},
            {"ground_slope/sin",
             [](const DriveSample& s) { return -s.alpha * (s.r_m / s.rG) * s.Mg2_N * s.sin_phi; }}};
  }
  std::vector<ResidualTerm> residualTerms(const TermOptions&) const override {
    ResidualTerm t;
    t.name = "ground_slope";
    t.stage = Stage::dynamic;
    t.coefficients = {{"ground_slope/cos"}, {"ground_slope/sin"}};
    t.plausible = [](const Eigen::VectorXd& b) {
      return std::hypot(b(0), b(1)) < std::sin(30.0 / kRad2Deg);
    };
    t.coefficientOf = [](const EffectSpec& e, const config::WheelchairConfig&) {
      const auto p = GroundSlopeParams::of(e);
      const double s = std::sin(p.angle_deg * kDeg), h = p.downhill_heading_deg * kDeg;
      return Eigen::Vector2d(s * std::cos(h), s * std::sin(h)).eval();
    };
    return {t};
  }
  /// The slope columns are scaled with the configured mass; when the payload is found too, the
  /// same current means a smaller angle on the heavier chair (sin a = s M_nominal / M).
  FindingText describe(const std::string&, const Eigen::VectorXd& b_in, const Eigen::MatrixXd& C_in,
                       const TermFit& fit) const override {
    const auto& v = fit.cfg->vehicle;
    const double mb = v.geom.body_mass_kg, mw = v.geom.wheel_mass_kg;
    const double slope_mass_scale = (mb + 2 * mw) / (mb + fit.value("payload_mass") + 2 * mw);
    Eigen::VectorXd b = b_in;
    Eigen::MatrixXd C = C_in;
    const double s_current = std::hypot(b(0), b(1));  // in units of the nominal M g / 2
    b *= slope_mass_scale;
    C *= slope_mass_scale * slope_mass_scale;
    const double s = std::hypot(b(0), b(1));
    const double ang = std::asin(std::min(1.0, s)) * kRad2Deg;
    const double head = std::atan2(b(1), b(0)) * kRad2Deg;
    // delta method
    Eigen::RowVector2d ja = Eigen::RowVector2d(b(0), b(1)) / std::max(1e-12, s) /
                            std::sqrt(std::max(1e-12, 1 - s * s)) * kRad2Deg;
    Eigen::RowVector2d jh = Eigen::RowVector2d(-b(1), b(0)) / std::max(1e-24, s * s) * kRad2Deg;
    const double sa = std::sqrt(std::max(0.0, (ja * C * ja.transpose())(0)));
    const double sh = std::sqrt(std::max(0.0, (jh * C * jh.transpose())(0)));
    FindingText t;
    t.parameters = {{"angle_deg", ang}, {"downhill_heading_deg", head}};
    t.uncertainty = {{"angle_deg", sa}, {"downhill_heading_deg", sh}};
    t.description = fmt::format(
        "both motors need less current heading {:.0f} deg and more heading {:.0f} deg (start "
        "frame), "
        "{:.2f} A each at the extremes: the floor slopes by {:.2f} deg (+- {:.2f}) downhill "
        "towards "
        "{:.0f} deg (+- {:.0f})",
        head, head + 180,
        s_current * (v.geom.body_mass_kg + 2 * v.geom.wheel_mass_kg) * 9.81 / 2 *
            v.geom.wheel_radius_m / v.geom.gear_ratio /
            (v.gearbox_efficiency * v.torque_constant_Nm_A),
        ang, sa, head, sh);
    return t;
  }
};

}  // namespace

const Effect& groundSlopeEffect() {
  static const GroundSlope e;
  return e;
}

}  // namespace wheelchair::effects
