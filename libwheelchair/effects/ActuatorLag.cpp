// actuator_lag([delay_s][, time_constant_s]): the power module responds to the joystick more
// slowly (pure delay + first-order lag of the speed references).
//   truth      replaces [simulation] actuator_delay_s / actuator_time_constant_s
//   inverse    none on the data (it needs the command history)
//   residual   none in the currents-driven diagnosis (the command-response stage sees it)
#include "libwheelchair/effects/Catalogue.h"

#include <stdexcept>

namespace wheelchair::effects {
namespace {

class ActuatorLag final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{
        "actuator_lag",
        "The power module responds to the joystick more slowly: pure delay plus first-order "
        "lag on the speed references (replace [simulation] actuator_delay_s and "
        "actuator_time_constant_s).",
        {{"delay_s",
          "s",
          "pure delay of the demand (absent: [simulation] actuator_delay_s)",
          "",
          {},
          true,
          0,
          10,
          true},
         {"time_constant_s",
          "s",
          "first-order time constant (absent: [simulation] actuator_time_constant_s)",
          "",
          {},
          true,
          0,
          10,
          true}}};
    return i;
  }
  void validate(const EffectSpec& e) const override {
    if (!e.has("delay_s") && !e.has("time_constant_s"))
      throw std::invalid_argument("effect 'actuator_lag': give delay_s and/or time_constant_s");
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    if (e.has("delay_s")) t.actuator_delay_s = e.number("delay_s");
    if (e.has("time_constant_s")) t.actuator_time_constant_s = e.number("time_constant_s");
  }
};

}  // namespace

const Effect& actuatorLagEffect() {
  static const ActuatorLag e;
  return e;
}

}  // namespace wheelchair::effects
