#include "libwheelchair/diagnosis/RawlogInput.h"

#include <variant>

namespace wheelchair::diagnosis {

void readForDiagnosis(const std::string& path, const io::RecordingSummary& sum,
                      const config::WheelchairConfig& cfg, DiagnosisInput& in) {
  using io::StreamKind;
  io::Recording rec;
  rec.meta = sum.meta;
  // Every vector sized once from the scan's counts (no growth slack: memory).
  rec.encoders.reserve(sum.count(StreamKind::Encoders));
  rec.sonar.reserve(sum.count(StreamKind::Sonar));
  rec.pozyx.reserve(sum.count(StreamKind::Pozyx));
  rec.ground_truth.reserve(sum.count(StreamKind::GroundTruth));
  rec.landmarks.reserve(sum.count(StreamKind::Landmarks));
  StreamColumns cols;
  for (auto* v : {&cols.tg, &cols.gz}) v->reserve(sum.count(StreamKind::Imu));
  for (auto* v : {&cols.tm, &cols.iR, &cols.iL}) v->reserve(sum.count(StreamKind::Motors));
  cols.start_s = sum.start_s;
  cols.end_s = sum.end_s;
  io::RawlogSampleReader reader(path);
  io::AnySample s;
  std::size_t k = 0;
  while (reader.next(s, k)) {
    if (const auto* g = std::get_if<io::ImuSample>(&s))
      cols.tg.push_back(g->t_s), cols.gz.push_back(g->gyro_z_rad_s);
    else if (const auto* m = std::get_if<io::MotorSample>(&s))
      cols.tm.push_back(m->t_s), cols.iR.push_back(m->current_right_A),
          cols.iL.push_back(m->current_left_A);
    else if (io::kindOf(s) != StreamKind::Joystick)
      io::append(rec, s);
  }
  in.streams.push_back(makeStreams(rec, std::move(cols), cfg));
  in.recs.push_back(std::move(rec));
}

}  // namespace wheelchair::diagnosis
