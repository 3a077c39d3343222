// The model-health events of `filter --health` and `capture --health` as JSON lines: one
// object per event (estimation::HealthEvent, estimation/HealthMonitor.h), e.g.
//   {"effect":"encoder_scale","kind":"estimate","parameter":"scale","sd":0.005,
//    "sensor":"encoders","side":"left","since_s":8.0,"t_s":15.3,
//    "text":"left encoder reads 5.0 % short (+-0.5 %) since t = 8.0 s","value":0.95}
// Times t_s and since_s on the recording's clock (s); value and sd in the parameter's unit.
#pragma once

#include "libwheelchair/estimation/EstimationTypes.h"

#include <nlohmann/json.hpp>

#include <string>

namespace wheelchair::cli {

/// One event as one JSON line (without the newline).
inline std::string healthJsonLine(const estimation::HealthEvent& e) {
  return nlohmann::json{{"t_s", e.t_s},       {"sensor", e.sensor}, {"kind", e.kind},
                        {"effect", e.effect}, {"side", e.side},     {"parameter", e.parameter},
                        {"value", e.value},   {"sd", e.sd},         {"since_s", e.since_s},
                        {"text", e.text}}
      .dump();
}

}  // namespace wheelchair::cli
