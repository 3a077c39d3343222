// sonar_dropout(probability[, burst_length]): the ultrasonic sensor fails and reports 0, in
// bursts (Fig. 8): a two-state Markov chain with mean burst length L and long-run failure
// fraction p.
//   truth      the simulator's sonar readings are 0 while in a burst
//   inverse    none (a fault: diagnosis/SensorFaults.h detects it; the readings are lost)
#include "libwheelchair/effects/Catalogue.h"

#include <stdexcept>

namespace wheelchair::effects {
namespace {

class SonarDropout final : public Effect {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo i{"sonar_dropout",
                              "The ultrasonic sensor fails and reports 0, in bursts (Fig. 8).",
                              {{"probability",
                                "-",
                                "long-run fraction of readings that are 0",
                                "",
                                {},
                                false,
                                0,
                                1,
                                true},
                               {"burst_length",
                                "readings",
                                "mean number of consecutive failed readings",
                                "3",
                                {},
                                false,
                                1,
                                1000,
                                true}}};
    return i;
  }
  void validate(const EffectSpec& e) const override {
    if (e.number("probability") >= 1.0)
      throw std::invalid_argument("effect 'sonar_dropout': probability must be < 1");
  }
  void actOnTruth(const EffectSpec& e, TruthModel& t) const override {
    t.sensors.dropout_probability = e.number("probability");
    t.sensors.dropout_burst = e.number("burst_length");
  }
};

}  // namespace

const Effect& sonarDropoutEffect() {
  static const SonarDropout e;
  return e;
}

}  // namespace wheelchair::effects
