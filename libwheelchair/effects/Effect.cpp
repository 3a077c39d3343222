#include "libwheelchair/effects/Effect.h"

#include "libwheelchair/effects/Catalogue.h"
#include "libwheelchair/util/Text.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

namespace wheelchair::effects {

namespace {

bool parseDouble(const std::string& text, double& out) {
  const char* s = text.c_str();
  char* end = nullptr;
  errno = 0;
  const double x = std::strtod(s, &end);
  if (end == s || *end != '\0' || errno == ERANGE || !std::isfinite(x)) return false;
  out = x;
  return true;
}

const EffectParamInfo* findParam(const EffectInfo& info, const std::string& key) {
  for (const auto& p : info.params)
    if (p.name == key) return &p;
  return nullptr;
}

}  // namespace

const std::vector<std::string>& streamNames() {
  static const std::vector<std::string> n = {"encoders", "imu",   "motors",
                                             "sonar",    "pozyx", "joystick"};
  return n;
}

int streamIndex(const std::string& name) {
  const auto& n = streamNames();
  for (std::size_t i = 0; i < n.size(); ++i)
    if (n[i] == name) return static_cast<int>(i);
  throw std::invalid_argument("unknown sensor stream '" + name + "'");
}

const std::vector<std::string>& sideChoices() {
  static const std::vector<std::string> s = {"right", "left"};
  return s;
}

const std::vector<std::string>& sideChoicesBoth() {
  static const std::vector<std::string> s = {"right", "left", "both"};
  return s;
}

const std::vector<const Effect*>& effectRegistry() {
  // The diagnosis tries the terms in this order (stage 1: gyro bias, gyro scale, encoder
  // scales, imu delay; stage 2: asymmetry, Coulomb, payload, slope, motors delay).
  static const std::vector<const Effect*> r = {
      &gyroBiasEffect(),       &gyroScaleEffect(),       &encoderScaleEffect(),
      &motorAsymmetryEffect(), &coulombFrictionEffect(), &payloadMassEffect(),
      &groundSlopeEffect(),    &sensorDelayEffect(),     &actuatorLagEffect(),
      &sonarDropoutEffect(),   &pozyxOutliersEffect()};
  return r;
}

const Effect* findEffect(const std::string& id) {
  for (const Effect* e : effectRegistry())
    if (e->id() == id) return e;
  return nullptr;
}

const std::vector<EffectInfo>& effectCatalogue() {
  static const std::vector<EffectInfo> cat = [] {
    std::vector<EffectInfo> c;
    for (const Effect* e : effectRegistry()) c.push_back(e->info());
    return c;
  }();
  return cat;
}

std::string EffectSpec::text(const std::string& key) const {
  auto it = params.find(key);
  if (it != params.end()) return it->second;
  if (const Effect* e = findEffect(id))
    if (const EffectParamInfo* p = findParam(e->info(), key)) return p->default_value;
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
  const std::string text = util::trim(text_in);
  EffectSpec e;
  const auto colon = text.find(':');
  e.id = util::trim(text.substr(0, colon));
  if (e.id.empty()) throw std::invalid_argument("effect '" + text_in + "': missing id");
  if (colon == std::string::npos) return e;
  const std::string rest = text.substr(colon + 1);
  std::size_t pos = 0;
  while (pos <= rest.size()) {
    auto comma = rest.find(',', pos);
    if (comma == std::string::npos) comma = rest.size();
    const std::string tok = util::trim(rest.substr(pos, comma - pos));
    pos = comma + 1;
    if (tok.empty()) {
      if (comma == rest.size()) break;
      throw std::invalid_argument("effect '" + text_in + "': empty parameter");
    }
    const auto eq = tok.find('=');
    if (eq == std::string::npos)
      throw std::invalid_argument("effect '" + text_in + "': '" + tok + "' is not key=value");
    const std::string k = util::trim(tok.substr(0, eq)), v = util::trim(tok.substr(eq + 1));
    if (k.empty() || v.empty())
      throw std::invalid_argument("effect '" + text_in + "': '" + tok + "' is not key=value");
    if (e.params.count(k))
      throw std::invalid_argument("effect '" + text_in + "': parameter '" + k + "' repeated");
    e.params[k] = v;
  }
  return e;
}

void validateAgainst(const EffectInfo& info, const EffectSpec& e) {
  for (const auto& [k, v] : e.params) {
    if (!findParam(info, k)) {
      std::string known;
      for (const auto& p : info.params) known += (known.empty() ? "" : ", ") + p.name;
      throw std::invalid_argument("effect '" + e.id + "': unknown parameter '" + k +
                                  "' (parameters: " + known + ")");
    }
  }
  for (const auto& p : info.params) {
    const auto given = e.params.find(p.name);
    const std::string v = given != e.params.end() ? given->second : p.default_value;
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
    double x = 0;
    if (!parseDouble(v, x))
      throw std::invalid_argument("effect '" + e.id + "': parameter '" + p.name + "' = '" + v +
                                  "' is not a finite number");
    if (p.lo <= p.hi) {
      const bool ok = (p.lo_inclusive ? x >= p.lo : x > p.lo) && x <= p.hi;
      if (!ok)
        throw std::invalid_argument("effect '" + e.id + "': " + p.name + " = " + v +
                                    " out of range " + (p.lo_inclusive ? "[" : "(") +
                                    std::to_string(p.lo) + ", " + std::to_string(p.hi) + "]");
    }
  }
}

void validateEffect(const EffectSpec& e) {
  const Effect* eff = findEffect(e.id);
  if (!eff) {
    std::string known;
    for (const auto& c : effectCatalogue()) known += (known.empty() ? "" : ", ") + c.id;
    throw std::invalid_argument("unknown effect '" + e.id + "' (known: " + known + ")");
  }
  validateAgainst(eff->info(), e);
  eff->validate(e);
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

nlohmann::json effectToJson(const EffectSpec& e) {
  nlohmann::json j;
  j["id"] = e.id;
  j["params"] = e.params;
  j["text"] = formatEffect(e);
  return j;
}

EffectSpec effectFromJson(const nlohmann::json& j) {
  return {j.at("id").get<std::string>(), j.at("params").get<std::map<std::string, std::string>>()};
}

std::vector<int> effectSides(const EffectSpec& e, const std::string& key) {
  const std::string s = e.text(key);
  if (s == "right") return {0};
  if (s == "left") return {1};
  if (s == "both") return {0, 1};
  throw std::invalid_argument("effect '" + e.id + "': " + key + " = '" + s +
                              "' must be right, left or both");
}

void actOnTruth(const std::vector<EffectSpec>& effects, TruthModel& t) {
  for (const auto& e : effects)
    if (const Effect* eff = findEffect(e.id)) eff->actOnTruth(e, t);
}

}  // namespace wheelchair::effects
