#include "libwheelchair/diagnosis/Comparisons.h"

#include <fmt/core.h>

namespace wheelchair::diagnosis {

SensorStreams sensorStreams(const std::vector<io::Recording>& recs) {
  SensorStreams s;
  for (const auto& r : recs) {
    s.encoders |= !r.encoders.empty();
    s.gyro |= !r.imu.empty();
    s.motors |= !r.motors.empty();
    s.ground_truth |= !r.ground_truth.empty();
    s.commands |= !r.joystick.empty();
    s.pozyx |= !r.pozyx.empty();
    s.sonar |= !r.sonar.empty();
  }
  return s;
}

SensorStreams sensorStreams(const std::vector<io::RecordingSummary>& sums) {
  using io::StreamKind;
  SensorStreams s;
  for (const auto& r : sums) {
    s.encoders |= r.count(StreamKind::Encoders) > 0;
    s.gyro |= r.count(StreamKind::Imu) > 0;
    s.motors |= r.count(StreamKind::Motors) > 0;
    s.ground_truth |= r.count(StreamKind::GroundTruth) > 0;
    s.commands |= r.count(StreamKind::Joystick) > 0;
    s.pozyx |= r.count(StreamKind::Pozyx) > 0;
    s.sonar |= r.count(StreamKind::Sonar) > 0;
  }
  return s;
}

namespace {

/// "no X and no Y" for the missing streams of a pair, empty when both are present.
std::string missing(bool a, const char* name_a, bool b, const char* name_b) {
  if (a && b) return {};
  if (!a && !b) return fmt::format("no {} and no {}", name_a, name_b);
  return fmt::format("no {}", a ? name_b : name_a);
}

std::string stringAt(const nlohmann::json& j, const char* k1, const char* k2) {
  if (!j.contains(k1) || !j[k1].is_object() || !j[k1].contains(k2) || !j[k1][k2].is_string())
    return {};
  return j[k1][k2].get<std::string>();
}

}  // namespace

void addComparisons(const SensorStreams& s, DiagnosisReport& rep) {
  const nlohmann::json& info = rep.info;
  nlohmann::json list = nlohmann::json::array();
  auto add = [&](const char* what, bool tested, const std::string& why) {
    nlohmann::json c = {{"comparison", what}, {"tested", tested}};
    if (!tested) c["why"] = why;
    list.push_back(c);
  };
  const char *kEnc = "wheel encoders (ENCODERS)", *kGyro = "gyro stream (IMU)",
             *kMot = "motor currents (MOTORS)", *kGt = "ground-truth poses (GROUND_TRUTH)",
             *kCmd = "command stream (JOYSTICK)";
  // stage 1
  std::string why = missing(s.gyro, kGyro, s.encoders, kEnc);
  const std::string stage1 = stringAt(info, "skipped", "stage1");
  add("gyro vs encoders", why.empty() && stage1.empty(), why.empty() ? stage1 : why);
  // stage 2
  why = missing(s.motors, kMot, s.encoders, kEnc);
  const std::string stage2 = stringAt(info, "skipped", "stage2");
  add("dynamics vs motor currents", why.empty() && stage2.empty(), why.empty() ? stage2 : why);
  // kinematic calibration
  why = missing(s.encoders, kEnc, s.ground_truth, kGt);
  const bool kc = info.contains("kinematic_calibration") &&
                  info["kinematic_calibration"].value("tested", false);
  if (why.empty() && !kc) why = stringAt(info, "kinematic_calibration", "not_tested");
  if (why.empty() && !kc) why = "the kinematic-calibration stage did not run";
  add("encoders vs ground truth (wheel radii, track)", kc, why);
  // command-response analyser
  const bool cr = info.contains("analyser") && info["analyser"] == "command_response";
  why = missing(s.commands, kCmd, s.ground_truth, kGt);
  if (!why.empty() && s.commands && !s.ground_truth)
    why += " (the encoders are not used as the motion reference for the commands)";
  if (why.empty() && s.motors)
    why = "the recordings have motor currents: the commands act through the dynamics (stage 2)";
  if (why.empty() && !cr) why = "not every recording has commands and ground-truth poses";
  add("commands vs motion", cr, why);
  // sensor faults
  const nlohmann::json sf = info.value("sensor_faults", nlohmann::json::object());
  why = missing(s.pozyx, "Pozyx fixes (POZYX)", s.encoders, kEnc);
  const bool pozyx = sf.contains("pozyx") && sf["pozyx"].value("fixes_tested", 0) > 0;
  if (why.empty() && !pozyx) why = "no Pozyx fix could be compared with the odometry";
  add("Pozyx vs odometry (outliers)", pozyx, why);
  const bool sonar = sf.contains("sonar") && sf["sonar"].value("readings", 0) > 0;
  add("sonar readings (dropouts)", sonar,
      s.sonar ? "the sonar readings were not examined" : "no sonar stream (SONAR)");
  rep.info["comparisons"] = list;
  bool any = false;
  for (const auto& c : list) any |= c["tested"].get<bool>();
  if (!any && rep.findings.empty())
    rep.info["insufficient_data"].push_back(
        "no comparison could be made: no stream of these recordings has a reference to be "
        "checked against (see 'not tested'); that nothing was found says nothing about the "
        "vehicle");
}

std::string comparisonsText(const DiagnosisReport& rep) {
  if (!rep.info.contains("comparisons")) return {};
  std::string tested, text;
  for (const auto& c : rep.info["comparisons"]) {
    const std::string what = c.value("comparison", std::string());
    if (c.value("tested", false))
      tested += (tested.empty() ? "" : "; ") + what;
    else
      text += fmt::format("  not tested: {}: {}\n", what, c.value("why", std::string()));
  }
  return (tested.empty() ? std::string("  tested: nothing\n") : "  tested: " + tested + "\n") +
         text;
}

}  // namespace wheelchair::diagnosis
