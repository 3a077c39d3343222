// pozyx_outliers(rate[, magnitude_m]): non-line-of-sight / multipath UWB fixes.
//   truth      a fraction `rate` of the Pozyx readings displaced by magnitude_m x U(0.5, 1.5)
//              in a uniformly random direction
//   inverse    none (a fault: diagnosis/SensorFaults.h detects it, the filter gates it)
#include "libwheelchair/effects/Catalogue.h"

namespace wheelchair::effects {
namespace {

class PozyxOutliers final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{
        "pozyx_outliers",
        "Non-line-of-sight / multipath UWB fixes: some Pozyx readings are displaced.",
        {{"rate", "-", "fraction of readings that are outliers", "", {}, false, 0, 1, true},
         {"magnitude_m",
          "m",
          "displacement of an outlier (random direction, 0.5..1.5 x)",
          "1",
          {},
          false,
          0,
          1000,
          true}}};
    return i;
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    t.sensors.outlier_rate = e.number("rate");
    t.sensors.outlier_magnitude_m = e.number("magnitude_m");
  }
};

}  // namespace

const Effect& pozyxOutliersEffect() {
  static const PozyxOutliers e;
  return e;
}

}  // namespace wheelchair::effects
