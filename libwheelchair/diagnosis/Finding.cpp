#include "libwheelchair/diagnosis/Finding.h"

#include <cmath>
#include <sstream>

namespace wheelchair::diagnosis {

namespace {
std::string numText(double v) {
  std::ostringstream os;
  os.precision(6);
  os << v;
  return os.str();
}
}  // namespace

std::string Finding::effectText() const {
  if (effect == "unmodeled" || effect.empty()) return {};
  std::ostringstream os;
  os << effect;
  bool first = true;
  for (auto it = parameters.begin(); it != parameters.end(); ++it) {
    os << (first ? ":" : ",") << it.key() << "=";
    if (it->is_number())
      os << numText(it->get<double>());
    else if (it->is_string())
      os << it->get<std::string>();
    else
      os << it->dump();
    first = false;
  }
  return os.str();
}

nlohmann::json Finding::toJson() const {
  nlohmann::json j;
  j["effect"] = effect;
  j["description"] = description;
  j["channels"] = channels;
  nlohmann::json seg = nlohmann::json::array();
  for (auto& s : segments) seg.push_back({s.first, s.second});
  j["segments"] = seg;
  j["parameters"] = parameters;
  j["uncertainty"] = uncertainty;
  j["evidence"] = evidence;
  j["fit_before"] = fit_before;
  j["fit_after"] = fit_after;
  if (!physics.empty()) j["physics"] = physics;
  if (is_fault) j["fault"] = true;
  if (command_response) j["analyser"] = "command_response";
  return j;
}

void DiagnosisReport::addFinding(Finding f) {
  findings.push_back(std::move(f));
  mismatch = true;
}

const Finding* DiagnosisReport::find(const std::string& effect) const {
  for (auto& f : findings)
    if (f.effect == effect) return &f;
  return nullptr;
}

nlohmann::json DiagnosisReport::toJson() const {
  nlohmann::json j;
  j["mismatch"] = mismatch;
  nlohmann::json fs = nlohmann::json::array();
  for (auto& f : findings) fs.push_back(f.toJson());
  j["findings"] = fs;
  j["config_written"] = config_written;
  if (!fit_before.empty()) j["fit_before"] = fit_before;
  if (!fit_after.empty()) j["fit_after"] = fit_after;
  j["channels"] = channels;
  j["validation"] = validation;
  j["info"] = info;
  return j;
}

}  // namespace wheelchair::diagnosis
