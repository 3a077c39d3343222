#include "libwheelchair/simulation/Effects.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

namespace wheelchair::simulation {

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

bool parseDouble(const std::string& text, double& out) {
  const char* s = text.c_str();
  char* end = nullptr;
  errno = 0;
  const double x = std::strtod(s, &end);
  if (end == s || *end != '\0' || errno == ERANGE || !std::isfinite(x)) return false;
  out = x;
  return true;
}

const std::vector<std::string> kSides = {"right", "left"};
const std::vector<std::string> kSidesBoth = {"right", "left", "both"};
const std::vector<std::string> kSensors = {"encoders", "imu",   "motors",
                                           "sonar",    "pozyx", "joystick"};

// Numeric range checks: id.key -> (min, max, min inclusive).
struct Range {
  double lo, hi;
  bool lo_inclusive;
};
const std::map<std::string, Range>& ranges() {
  static const std::map<std::string, Range> r = {
      {"motor_asymmetry.friction_ratio", {0, 100, false}},
      {"motor_asymmetry.km_ratio", {0, 10, false}},
      {"encoder_scale.scale", {0, 10, false}},
      {"encoder_scale.from_s", {0, 1e7, true}},
      {"gyro_bias.bias_rad_s", {-10, 10, true}},
      {"gyro_scale.scale", {0, 10, false}},
      {"coulomb_friction.current_A", {0, 100, true}},
      {"ground_slope.angle_deg", {-30, 30, true}},
      {"ground_slope.downhill_heading_deg", {-360, 360, true}},
      {"sensor_delay.delay_s", {0, 10, true}},
      {"payload_mass.body_mass_kg", {0, 1000, false}},
      {"actuator_lag.delay_s", {0, 10, true}},
      {"actuator_lag.time_constant_s", {0, 10, true}},
      {"sonar_dropout.probability", {0, 1, true}},
      {"sonar_dropout.burst_length", {1, 1000, true}},
      {"pozyx_outliers.rate", {0, 1, true}},
      {"pozyx_outliers.magnitude_m", {0, 1000, true}},
  };
  return r;
}

}  // namespace

const std::vector<EffectInfo>& effectCatalogue() {
  static const std::vector<EffectInfo> cat = {
      {"motor_asymmetry",
       "One drive differs from the other: its gearbox has more viscous friction (B_m times "
       "friction_ratio) and/or its motor torque constant differs (k_m times km_ratio). Fig. 6c.",
       {{"side", "enum", "the drive that differs", "", kSides},
        {"friction_ratio", "-", "true B_m of that side / nominal B_m", "1", {}},
        {"km_ratio",
         "-",
         "true k_m of that side / nominal k_m (also the back-EMF constant)",
         "1",
         {}}}},
      {"encoder_scale",
       "Wrong encoder pulley ratio N_ep/N_mp on one side: the encoder reports scale times the "
       "true wheel rotation.",
       {{"side", "enum", "encoder affected", "", kSidesBoth},
        {"scale", "-", "reported distance / true distance", "", {}},
        {"from_s",
         "s",
         "time since the start from which the scale applies (a step fault; the count stays "
         "continuous)",
         "0",
         {}}}},
      {"gyro_bias",
       "Constant offset of the gyro z reading.",
       {{"bias_rad_s", "rad/s", "added to every gyro z sample", "", {}}}},
      {"gyro_scale",
       "Scale-factor error of the gyro z reading.",
       {{"scale", "-", "reported rate / true rate", "", {}}}},
      {"coulomb_friction",
       "Dry (Coulomb) friction in a drive, expressed as the motor current it costs: "
       "c sgn(u_i) in the torque balance (smoothed with tanh, [simulation] "
       "coulomb_smoothing_m_s).",
       {{"current_A", "A", "dry friction current per affected motor", "", {}},
        {"side", "enum", "drive affected", "both", kSidesBoth}}},
      {"ground_slope",
       "The floor is an inclined plane: gravity pulls along the heading with "
       "(m_b + 2 m_w) g sin(angle) cos(phi - downhill_heading).",
       {{"angle_deg", "deg", "inclination of the floor", "", {}},
        {"downhill_heading_deg",
         "deg",
         "heading in the start frame that points downhill",
         "0",
         {}}}},
      {"sensor_delay",
       "One stream's timestamps lag: a measurement taken at t is stamped t + delay_s.",
       {{"sensor", "enum", "stream affected", "", kSensors},
        {"delay_s", "s", "timestamp lag", "", {}}}},
      {"payload_mass",
       "The true mass of chair body with user differs from the configuration.",
       {{"body_mass_kg", "kg", "true m_b (replaces [vehicle] body_mass_kg)", "", {}}}},
      {"actuator_lag",
       "The power module responds to the joystick more slowly: pure delay plus first-order "
       "lag on the speed references (replace [simulation] actuator_delay_s and "
       "actuator_time_constant_s).",
       {{"delay_s",
         "s",
         "pure delay of the demand (absent: [simulation] actuator_delay_s)",
         "",
         {},
         true},
        {"time_constant_s",
         "s",
         "first-order time constant (absent: [simulation] actuator_time_constant_s)",
         "",
         {},
         true}}},
      {"sonar_dropout",
       "The ultrasonic sensor fails and reports 0, in bursts (Fig. 8).",
       {{"probability", "-", "long-run fraction of readings that are 0", "", {}},
        {"burst_length", "readings", "mean number of consecutive failed readings", "3", {}}}},
      {"pozyx_outliers",
       "Non-line-of-sight / multipath UWB fixes: some Pozyx readings are displaced.",
       {{"rate", "-", "fraction of readings that are outliers", "", {}},
        {"magnitude_m",
         "m",
         "displacement of an outlier (random direction, 0.5..1.5 x)",
         "1",
         {}}}},
  };
  return cat;
}

const EffectInfo* findEffect(const std::string& id) {
  for (const auto& e : effectCatalogue())
    if (e.id == id) return &e;
  return nullptr;
}

static const EffectParamInfo* findParam(const EffectInfo& info, const std::string& key) {
  for (const auto& p : info.params)
    if (p.name == key) return &p;
  return nullptr;
}

std::string EffectSpec::text(const std::string& key) const {
  auto it = params.find(key);
  if (it != params.end()) return it->second;
  if (const EffectInfo* info = findEffect(id))
    if (const EffectParamInfo* p = findParam(*info, key)) return p->default_value;
  return "";
}

double EffectSpec::number(const std::string& key) const {
  const std::string t = text(key);
  if (t.empty())
    throw std::invalid_argument("effect '" + id + "': parameter '" + key + "' is required");
  double x = 0;
  if (!parseDouble(t, x))
    throw std::invalid_argument("effect '" + id + "': parameter '" + key + "' = '" + t +
                                "' is not a finite number");
  return x;
}

EffectSpec parseEffect(const std::string& text_in) {
  const std::string text = trim(text_in);
  EffectSpec e;
  const auto colon = text.find(':');
  e.id = trim(text.substr(0, colon));
  if (e.id.empty()) throw std::invalid_argument("effect '" + text_in + "': missing id");
  if (colon == std::string::npos) return e;
  const std::string rest = text.substr(colon + 1);
  std::size_t pos = 0;
  while (pos <= rest.size()) {
    auto comma = rest.find(',', pos);
    if (comma == std::string::npos) comma = rest.size();
    const std::string tok = trim(rest.substr(pos, comma - pos));
    pos = comma + 1;
    if (tok.empty()) {
      if (comma == rest.size()) break;
      throw std::invalid_argument("effect '" + text_in + "': empty parameter");
    }
    const auto eq = tok.find('=');
    if (eq == std::string::npos)
      throw std::invalid_argument("effect '" + text_in + "': '" + tok + "' is not key=value");
    const std::string k = trim(tok.substr(0, eq)), v = trim(tok.substr(eq + 1));
    if (k.empty() || v.empty())
      throw std::invalid_argument("effect '" + text_in + "': '" + tok + "' is not key=value");
    if (e.params.count(k))
      throw std::invalid_argument("effect '" + text_in + "': parameter '" + k + "' repeated");
    e.params[k] = v;
  }
  return e;
}

void validateEffect(const EffectSpec& e) {
  const EffectInfo* info = findEffect(e.id);
  if (!info) {
    std::string known;
    for (const auto& c : effectCatalogue()) known += (known.empty() ? "" : ", ") + c.id;
    throw std::invalid_argument("unknown effect '" + e.id + "' (known: " + known + ")");
  }
  for (const auto& [k, v] : e.params) {
    if (!findParam(*info, k)) {
      std::string known;
      for (const auto& p : info->params) known += (known.empty() ? "" : ", ") + p.name;
      throw std::invalid_argument("effect '" + e.id + "': unknown parameter '" + k +
                                  "' (parameters: " + known + ")");
    }
  }
  for (const auto& p : info->params) {
    const std::string v = e.text(p.name);
    if (v.empty() && p.optional) continue;
    if (v.empty())
      throw std::invalid_argument("effect '" + e.id + "': parameter '" + p.name + "' is required");
    if (!p.choices.empty()) {
      if (std::find(p.choices.begin(), p.choices.end(), v) == p.choices.end()) {
        std::string ch;
        for (const auto& c : p.choices) ch += (ch.empty() ? "" : "|") + c;
        throw std::invalid_argument("effect '" + e.id + "': " + p.name + " = '" + v +
                                    "' must be one of " + ch);
      }
      continue;
    }
    const double x = e.number(p.name);
    auto it = ranges().find(e.id + "." + p.name);
    if (it != ranges().end()) {
      const Range& r = it->second;
      const bool ok = (r.lo_inclusive ? x >= r.lo : x > r.lo) && x <= r.hi;
      if (!ok)
        throw std::invalid_argument("effect '" + e.id + "': " + p.name + " = " + v +
                                    " out of range " + (r.lo_inclusive ? "[" : "(") +
                                    std::to_string(r.lo) + ", " + std::to_string(r.hi) + "]");
    }
  }
  if (e.id == "actuator_lag" && !e.has("delay_s") && !e.has("time_constant_s"))
    throw std::invalid_argument("effect 'actuator_lag': give delay_s and/or time_constant_s");
  if (e.id == "sonar_dropout" && e.number("probability") >= 1.0)
    throw std::invalid_argument("effect 'sonar_dropout': probability must be < 1");
}

EffectSpec parseValidEffect(const std::string& text) {
  EffectSpec e = parseEffect(text);
  validateEffect(e);
  return e;
}

std::string formatEffect(const EffectSpec& e) {
  std::string s = e.id;
  bool first = true;
  for (const auto& [k, v] : e.params) {
    s += first ? ":" : ",";
    first = false;
    s += k + "=" + v;
  }
  return s;
}

std::vector<int> effectSides(const EffectSpec& e, const std::string& key) {
  const std::string s = e.text(key);
  if (s == "right") return {0};
  if (s == "left") return {1};
  if (s == "both") return {0, 1};
  throw std::invalid_argument("effect '" + e.id + "': " + key + " = '" + s +
                              "' must be right, left or both");
}

}  // namespace wheelchair::simulation
