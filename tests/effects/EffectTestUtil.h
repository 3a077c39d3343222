// Shared checks of the effect tests (one test file per effect):
//  - forward against inverse: simulate the same drive (same seed) with and without the
//    effect, correct the recording with the effect's inverse (ModelExtensions::apply), and
//    compare with the effect-free recording;
//  - residual terms against numerical differentiation: the change of a diagnosis stage's
//    residual rows between the drive without the effect and with a small one (a finite
//    difference in the parameter) against the term's columns times the coefficient the
//    effect implies (ResidualTerm::coefficientOf).
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/diagnosis/Diagnosis.h"
#include "libwheelchair/diagnosis/Stages.h"
#include "libwheelchair/effects/Effect.h"
#include "libwheelchair/estimation/ModelExtensions.h"
#include "libwheelchair/simulation/Simulator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace wheelchair::effects::test {

inline const config::WheelchairConfig& nominal() {
  static const config::WheelchairConfig cfg;
  return cfg;
}

/// A drive of `duration_s` with the effects (texts), seed 11.
inline io::Recording drive(const std::vector<std::string>& texts,
                           const std::string& scenario = "excite", double duration_s = 40,
                           simulation::SimulationResult* truth = nullptr) {
  std::vector<EffectSpec> e;
  for (const auto& t : texts) e.push_back(parseValidEffect(t));
  simulation::SimulationResult r =
      simulation::simulate(nominal(), scenario, 11, duration_s, e, simulation::SimulationOptions{});
  if (truth) *truth = r;
  return r.recording;
}

/// The recording corrected for one effect by its inverse (through ModelExtensions).
inline io::Recording corrected(const io::Recording& rec, const std::string& text) {
  estimation::ModelExtensions ext;
  ext.effects = {parseValidEffect(text)};
  return ext.apply(rec, nominal());
}

inline double rmsDiff(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size() || a.empty()) throw std::runtime_error("rmsDiff: sizes differ");
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(s / a.size());
}

/// Motor current of one side over a recording (A).
inline std::vector<double> currents(const io::Recording& r, int side) {
  std::vector<double> out;
  for (const auto& m : r.motors) out.push_back(side == 0 ? m.current_right_A : m.current_left_A);
  return out;
}

/// The catalogue term `name` of a stage.
inline diagnosis::Candidate term(Stage stage, const std::string& name) {
  for (const auto& c :
       diagnosis::stageCandidates(stage, {nominal().vehicle.geom.body_mass_kg, true}))
    if (c.name == name) return c;
  throw std::runtime_error("no term " + name);
}

/// The coefficients `text` implies for the term `name`.
inline Eigen::VectorXd coefficientOf(const std::string& text, const std::string& name) {
  const EffectSpec e = parseValidEffect(text);
  for (const auto& t : findEffect(e.id)->residualTerms({nominal().vehicle.geom.body_mass_kg, true}))
    if (t.name == name) return t.coefficientOf(e, nominal());
  throw std::runtime_error("no term " + name);
}

/// Result of a finite-difference check: |dy - X b| / |dy| and |dy| (RMS over rows).
struct TermCheck {
  double relative_error = 1, change_rms = 0;
};

/// Stage 1: rows of the drive without and with the effect (nominal corrections).
inline TermCheck kinematicTermCheck(const std::string& text, const std::string& name) {
  diagnosis::DiagnosisOptions opt;
  const auto s0 = diagnosis::makeStreams(drive({}), nominal());
  const auto s1 = diagnosis::makeStreams(drive({text}), nominal());
  const auto k0 = diagnosis::kinematicRows({s0}, {}, nominal(), opt);
  const auto k1 = diagnosis::kinematicRows({s1}, {}, nominal(), opt);
  // Windows are matched by their encoder stamps (a stream delay may drop some at the ends).
  const Eigen::VectorXd pred0 = k0.X * term(Stage::kinematic, name).S * coefficientOf(text, name);
  double e = 0, n = 0;
  int matched = 0;
  for (Eigen::Index i = 0; i < k1.y.size(); ++i) {
    const auto it = std::lower_bound(k0.t0.begin(), k0.t0.end(), k1.t0[i]);
    if (it == k0.t0.end() || *it != k1.t0[i]) continue;
    const Eigen::Index j = it - k0.t0.begin();
    if (k0.t1[j] != k1.t1[i]) continue;
    const double dy = k1.y(i) - k0.y(j);
    e += (dy - pred0(j)) * (dy - pred0(j)), n += dy * dy, ++matched;
  }
  if (matched < 50) throw std::runtime_error("too few matched windows");
  return {std::sqrt(e / std::max(1e-300, n)), std::sqrt(n / matched)};
}

/// Stage 2: rows of the drive without and with the effect; the effect's rows are matched by
/// time (and motor) to the effect-free ones (linear interpolation on the 50 Hz grid).
inline TermCheck driveTermCheck(const std::string& text, const std::string& name) {
  diagnosis::DiagnosisOptions opt;
  const auto s0 = diagnosis::makeStreams(drive({}), nominal());
  const auto s1 = diagnosis::makeStreams(drive({text}), nominal());
  const auto d0 = diagnosis::dynamicRows({s0}, {}, nominal(), opt);
  const auto d1 = diagnosis::dynamicRows({s1}, {}, nominal(), opt);
  const Eigen::VectorXd pred0 =
      d0.design().times(term(Stage::dynamic, name).S) * coefficientOf(text, name);
  std::vector<double> dy, pr;
  const Eigen::Index n0R = d0.y.size() / 2;   // rows: right motor, then left
  const std::vector<double>& t0 = d0.grid.t;  // per grid sample, shared by both motors' rows
  for (Eigen::Index k = 0; k < d1.y.size(); ++k) {
    const double tk = d1.grid.t[d1.step(static_cast<int>(k))];
    const auto it = std::upper_bound(t0.begin(), t0.end(), tk);
    if (it == t0.begin() || it == t0.end()) continue;
    const Eigen::Index i = (it - t0.begin()) - 1;  // grid sample before tk
    if (t0[i + 1] - t0[i] > 0.05) continue;        // a segment boundary
    const double a = (tk - t0[i]) / (t0[i + 1] - t0[i]);
    const Eigen::Index j = i + (d1.side(static_cast<int>(k)) == 0 ? 0 : n0R);  // d0's row
    dy.push_back(d1.y(k) - (d0.y(j) + a * (d0.y(j + 1) - d0.y(j))));
    pr.push_back(pred0(j) + a * (pred0(j + 1) - pred0(j)));
  }
  if (dy.size() < 100) throw std::runtime_error("too few matched rows");
  double e = 0, n = 0;
  for (std::size_t i = 0; i < dy.size(); ++i)
    e += (dy[i] - pr[i]) * (dy[i] - pr[i]), n += dy[i] * dy[i];
  return {std::sqrt(e / std::max(1e-300, n)), std::sqrt(n / dy.size())};
}

}  // namespace wheelchair::effects::test
