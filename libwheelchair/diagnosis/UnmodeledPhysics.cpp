#include "libwheelchair/diagnosis/UnmodeledPhysics.h"

#include "libwheelchair/stats/Statistics.h"

#include <fmt/format.h>

#include <Eigen/QR>
#include <algorithm>

#include <cmath>
#include <map>

namespace wheelchair::diagnosis {

std::string dependenceOf(const std::string& t) {
  if (t == "1") return "constant";
  if (t == "v" || t == "omega" || t == "|omega|" || t == "|u|") return "rate";
  if (t == "sgn(u)" || t == "sgn(omega)") return "sign_of_rate";
  if (t == "u^2" || t == "v*|v|" || t == "omega*|omega|" || t == "(u_R^3-u_L^3)/l_w")
    return "rate_squared";
  if (t == "v*omega" || t == "omega^2") return "rate_product";
  if (t == "vdot" || t == "omegadot") return "acceleration";
  if (t == "cos(phi)" || t == "sin(phi)") return "heading";
  if (t == "castor_swivel") return "castor_swivel";
  return "command";  // a measured current or command as regressor: the actuator
}

std::string dependenceWords(const std::string& d) {
  static const std::map<std::string, std::string> w = {
      {"constant", "constant -> an offset or a constant load"},
      {"rate", "rate -> viscous"},
      {"sign_of_rate", "sign of a rate -> dry friction"},
      {"rate_squared", "rate squared -> drag"},
      {"rate_product", "product of rates -> centripetal (a mass off the axle)"},
      {"acceleration", "acceleration -> inertia"},
      {"heading", "heading -> a field or slope fixed in the world"},
      {"castor_swivel", "the castors swivelling (turn starts, reversals) -> swivel friction"},
      {"command", "command -> the actuator"}};
  auto it = w.find(d);
  return it == w.end() ? d : it->second;
}

namespace {

/// Uncentred R^2 from which two readings of a component are one ambiguous group (as
/// betterOutOfCatalogue's span condition).
constexpr double kCollinearR2 = 0.9;

bool perSideTerm(const std::string& t) {
  return t == "sgn(u)" || t == "|u|" || t == "u^2";
}

/// Unit of one unit of a term (for "per ..." in the words).
std::string termUnit(const std::string& t) {
  static const std::map<std::string, std::string> u = {{"1", ""},
                                                       {"v", "m/s"},
                                                       {"omega", "rad/s"},
                                                       {"vdot", "m/s^2"},
                                                       {"omegadot", "rad/s^2"},
                                                       {"sgn(u)", ""},
                                                       {"|u|", "m/s"},
                                                       {"u^2", "m^2/s^2"},
                                                       {"v*omega", "m rad/s^2"},
                                                       {"omega^2", "rad^2/s^2"},
                                                       {"v*|v|", "m^2/s^2"},
                                                       {"sgn(omega)", ""},
                                                       {"|omega|", "rad/s"},
                                                       {"omega*|omega|", "rad^2/s^2"},
                                                       {"(u_R^3-u_L^3)/l_w", "m^2/s^3"}};
  auto it = u.find(t);
  return it == u.end() ? "" : it->second;
}

/// The physicist's reading of a load `value` (+- sd) of a dependence class on a channel.
std::string loadReading(const std::string& channel, const std::string& dep, const std::string& term,
                        double value, double sd, const std::string& unit) {
  const bool yaw = channel == "yaw";
  const std::string q = yaw ? "a moment about the axle" : "a force along the heading";
  const std::string num = fmt::format("{:.3g} +- {:.2g} {}", value, sd, unit);
  if (dep == "rate")
    return value > 0 ? fmt::format(
                           "{} opposing the {} in proportion to its rate: {} (viscous: "
                           "{})",
                           q, yaw ? "turn" : "motion", num,
                           yaw ? "castor swivel or tyre damping" : "soft ground, grass")
                     : fmt::format(
                           "{} assisting the {} in proportion to its rate: {} (less "
                           "viscous friction than the model has)",
                           q, yaw ? "turn" : "motion", num);
  if (dep == "sign_of_rate")
    return fmt::format("{} of constant size opposing the {}: {} (dry friction: {})", q,
                       yaw ? "turn" : "motion", num,
                       yaw ? "castor swivels, tyre scrub" : "bearings, rolling resistance");
  if (dep == "rate_squared")
    return fmt::format("{} growing with the rate squared ({}): {} (drag: air, water, tall grass)",
                       q, term, num);
  if (dep == "rate_product")
    return fmt::format(
        "{} proportional to {}: {} (centripetal / Coriolis: a centre of mass off "
        "the axle)",
        q, term, num);
  if (dep == "castor_swivel")
    return fmt::format(
        "{} while the castors swivel round (at the start of a turn, when it reverses or "
        "tightens), acting through the castors' lever: a swivel friction of {} (whatever "
        "resists the castors turning round: dry friction in their swivels, torsional scrub of "
        "their tyres' contact patches, or castors that drag sideways before they align)",
        q, num);
  if (dep == "acceleration")
    return fmt::format("inertia the model lacks: {} ({})", num,
                       yaw ? "a load far from the axle" : "an extra mass");
  if (dep == "constant")
    return fmt::format("a constant {}: {} (a push, or a pull)", yaw ? "moment" : "force", num);
  return fmt::format("{} depending on {}: {}", q, term, num);
}

struct Col {
  int term = 0;
  int mode = 0;  ///< 0 forward ([c_R; c_L]), 1 yaw ([c_R; -c_L]), 2 right only, 3 left only
};

Eigen::VectorXd stacked(const DynamicTermData& d, const Col& c, bool fit) {
  const Eigen::VectorXd R = d.column(c.term, 0, fit), L = d.column(c.term, 1, fit);
  Eigen::VectorXd out(R.size() + L.size());
  const double sr = c.mode == 3 ? 0.0 : 1.0;
  const double sl = c.mode == 0 ? 1.0 : (c.mode == 1 ? -1.0 : (c.mode == 2 ? 0.0 : 1.0));
  out << sr * R, sl * L;
  return out;
}

Eigen::MatrixXd designOf(const DynamicTermData& d, const std::vector<Col>& cols, bool fit) {
  Eigen::MatrixXd A(fit ? d.y_fit.size() : d.y_val.size(), cols.size());
  for (std::size_t k = 0; k < cols.size(); ++k) A.col(k) = stacked(d, cols[k], fit);
  return A;
}

/// Validation RMS of a least-squares fit of `cols` on the fit rows.
double valRms(const DynamicTermData& d, const std::vector<Col>& cols) {
  if (d.y_val.size() == 0) return 0;
  if (cols.empty()) return std::sqrt(d.y_val.squaredNorm() / d.y_val.size());
  const Eigen::VectorXd b = designOf(d, cols, true).colPivHouseholderQr().solve(d.y_fit);
  return std::sqrt((d.y_val - designOf(d, cols, false) * b).squaredNorm() / d.y_val.size());
}

/// One heading component of channel `mode` (0 forward, 1 yaw) from its cos / sin coefficients
/// h {cos, sin, sd, gain}; kF, kM: N and N m per A of one motor.
nlohmann::json headingComponent(int mode, const nlohmann::json& h, double kF, double kM) {
  const double c = h.value("cos", 0.0), s = h.value("sin", 0.0), sd = h.value("sd", 0.0);
  const bool yaw = mode == 1;
  const double kk = yaw ? kM : kF, amp = kk * std::hypot(c, s);
  // Load -kk (c cos phi + s sin phi): largest in the +x / +omega sense at atan2(-s, -c).
  const double towards_deg = std::atan2(-s, -c) * 180 / M_PI;
  const std::string unit = yaw ? "N m" : "N";
  return nlohmann::json(
      {{"channel", yaw ? "yaw" : "forward"},
       {"dependence", "heading"},
       {"dependence_words", dependenceWords("heading")},
       {"term", "cos(phi), sin(phi)"},
       {"coefficient", {c, s}},
       {"sd", sd},
       {"unit", "A per motor"},
       {"heldout_gain_A", h.value("gain", 0.0)},
       {"physical",
        {{"quantity", yaw ? "yaw moment amplitude" : "forward force amplitude"},
         {"value", amp},
         {"sd", kk * sd},
         {"unit", unit},
         {"towards_heading_deg", towards_deg}}},
       {"reading",
        fmt::format("{} fixed in the world: {:.3g} +- {:.2g} {}, {} heading {:.0f} deg (start "
                    "frame; {})",
                    yaw ? "a yaw moment" : "a force along the heading", amp, kk * sd, unit,
                    yaw ? "turning the chair left most at" : "pushing forward most at", towards_deg,
                    yaw ? "wind on the side, or a cross slope on a mass off the axle"
                        : "a slope or a wind")}});
}

}  // namespace

namespace {
/// Channel word of library term `term` in column pattern `mode` (as describeDynamicTerms).
std::string channelOf(const std::string& term, int mode) {
  if (mode == 2) return "current_right";
  if (mode == 3) return "current_left";
  if (perSideTerm(term)) return "wheels";
  return mode == 1 ? "yaw" : "forward";
}

/// Readings the data cannot tell from kept[k] (issue 16 item 5): library terms j outside
/// `kept`, in the forward or yaw pattern (one motor's pattern for a one-motor column), of
/// another channel or dependence class, that span kept[k]'s column together with the other
/// kept columns (uncentred R^2 >= min_r2 over fit and validation rows). Per reading: {channel,
/// dependence, term, r2}, the best first (at most two).
nlohmann::json collinearReadings(const std::vector<Col>& kept, std::size_t k,
                                 const std::vector<std::string>& names, const DynamicTermData& d,
                                 double min_r2) {
  auto allRows = [&](const Col& c) {
    const Eigen::VectorXd a = stacked(d, c, true), b = stacked(d, c, false);
    Eigen::VectorXd x(a.size() + b.size());
    x << a, b;
    return x;
  };
  const Col& c = kept[k];
  const Eigen::VectorXd target = allRows(c);
  const double tt = target.squaredNorm();
  const std::string ch = channelOf(names[c.term], c.mode), dep = dependenceOf(names[c.term]);
  std::vector<std::pair<double, nlohmann::json>> found;
  if (!(tt > 0)) return nlohmann::json::array();
  // The other kept columns, made once (the same in every candidate's design).
  std::vector<Eigen::VectorXd> rest;
  for (std::size_t o = 0; o < kept.size(); ++o)
    if (o != k) rest.push_back(allRows(kept[o]));
  for (int j = 0; j < static_cast<int>(names.size()); ++j) {
    const std::string dj = dependenceOf(names[j]);
    if (dj == "command") continue;  // a measured current is not a reading of a load
    bool in_kept = false;
    for (const Col& o : kept) in_kept |= o.term == j;
    if (in_kept) continue;
    for (int mode : c.mode >= 2 ? std::vector<int>{c.mode} : std::vector<int>{0, 1}) {
      const std::string cj = channelOf(names[j], mode);
      if (cj == ch && dj == dep) continue;
      Eigen::MatrixXd A(target.size(), 1 + rest.size());
      A.col(0) = allRows(Col{j, mode});
      if (!(A.col(0).norm() > 0)) continue;
      for (std::size_t o = 0; o < rest.size(); ++o) A.col(1 + o) = rest[o];
      const Eigen::VectorXd r = target - A * A.colPivHouseholderQr().solve(target);
      const double r2 = 1 - r.squaredNorm() / tt;
      if (r2 >= min_r2)
        found.push_back(
            {r2, {{"channel", cj}, {"dependence", dj}, {"term", names[j]}, {"r2", r2}}});
    }
  }
  std::sort(found.begin(), found.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  nlohmann::json out = nlohmann::json::array();
  for (std::size_t i = 0; i < found.size() && i < 2; ++i) out.push_back(found[i].second);
  return out;
}

/// Step 2 of describeDynamicTerms: the channel of each term from the joint fit f of its forward
/// (column 2a) and yaw (2a + 1) columns: forward, yaw, one motor (mode 2 right, 3 left) or both.
std::vector<Col> termChannels(const stats::LinearFit& f, const std::vector<int>& terms,
                              const std::vector<std::string>& names, double t_threshold) {
  std::vector<Col> kept;
  for (std::size_t a = 0; a < terms.size(); ++a) {
    const double bf = f.beta(2 * a), by = f.beta(2 * a + 1);
    const double sf = std::sqrt(std::max(0.0, f.cov(2 * a, 2 * a)));
    const double sy = std::sqrt(std::max(0.0, f.cov(2 * a + 1, 2 * a + 1)));
    const bool tf = std::abs(bf) >= t_threshold * sf, ty = std::abs(by) >= t_threshold * sy;
    // The castors' column is their yaw moment (castorSwivelMoment): a yaw term only (on MuJoCo
    // its forward twin came with a negative held-out gain).
    if (names[terms[a]] == "castor_swivel") {
      if (ty) kept.push_back({terms[a], 1});
      continue;
    }
    // Per motor: right = f + y, left = f - y. One motor when the other's share is within
    // 2 sigma of zero or below a quarter of it.
    const double sd_m = std::sqrt(sf * sf + sy * sy);
    const double mr = std::abs(bf + by), ml = std::abs(bf - by);
    const double lo = std::min(mr, ml), hi = std::max(mr, ml);
    if (tf && ty && (lo <= 2 * sd_m || lo <= 0.25 * hi))
      kept.push_back({terms[a], mr > ml ? 2 : 3});
    else {
      if (tf) kept.push_back({terms[a], 0});
      if (ty) kept.push_back({terms[a], 1});
    }
  }
  return kept;
}
}  // namespace

namespace {
/// The component of `kept` whose own held-out prediction gets worse (DynamicTermData's rule)
/// the most (lowest realised likelihood ratio), or -1: for component k, the validation RSS of
/// the fit of kept without k (rss0) against kept (rss1), n_eff of the latter's residual,
/// realised LR n_eff log(rss0 / rss1), predicted n_eff log(1 + |p1 - p0|^2 / rss1).
int heldOutWorse(const DynamicTermData& d, const std::vector<Col>& kept,
                 const std::vector<std::string>& names, DroppedComponent& worst) {
  if (d.y_val.size() == 0 || d.groups_val.empty() || kept.empty()) return -1;
  auto prediction = [&](const std::vector<Col>& cols) -> Eigen::VectorXd {
    if (cols.empty()) return Eigen::VectorXd::Zero(d.y_val.size());
    const Eigen::VectorXd b = designOf(d, cols, true).colPivHouseholderQr().solve(d.y_fit);
    return designOf(d, cols, false) * b;
  };
  const Eigen::VectorXd p1 = prediction(kept);
  int out = -1;
  for (std::size_t k = 0; k < kept.size(); ++k) {
    std::vector<Col> without = kept;
    without.erase(without.begin() + static_cast<long>(k));
    const Eigen::VectorXd p0 = prediction(without);
    const stats::HeldOutGain g =
        stats::heldOutGain(d.y_val, p0, (d.y_val - p0).squaredNorm(), p1, d.groups_val, d.lags);
    const bool worse = g.lr_expected >= d.min_expected_lr ? g.lr < 0 : g.lr < -d.worse_lr;
    if (worse && (out < 0 || g.lr < worst.lr))
      out = static_cast<int>(k), worst = {kept[k].term, kept[k].mode, g.lr, g.lr_expected,
                                          channelOf(names[kept[k].term], kept[k].mode)};
  }
  return out;
}
}  // namespace

nlohmann::json describeDynamicTerms(const std::vector<int>& terms,
                                    const std::vector<std::string>& names, const DynamicTermData& d,
                                    const config::WheelchairConfig& cfg,
                                    std::vector<DroppedComponent>* dropped) {
  nlohmann::json out = nlohmann::json::array();
  if (terms.empty() || d.y_fit.size() == 0) return out;
  // 1. Forward and yaw column of every term, jointly.
  std::vector<Col> cols;
  for (int j : terms) cols.push_back({j, 0}), cols.push_back({j, 1});
  stats::LinearFit f = stats::fitLinear(designOf(d, cols, true), d.y_fit, d.groups_fit, d.lags);
  if (!f.ok) return out;
  // 2. Channel per term; a component whose own held-out prediction gets worse is left out.
  std::vector<Col> kept = termChannels(f, terms, names, d.t_threshold);
  for (DroppedComponent w; heldOutWorse(d, kept, names, w) >= 0;) {
    kept.erase(std::find_if(kept.begin(), kept.end(),
                            [&](const Col& c) { return c.term == w.term && c.mode == w.mode; }));
    if (dropped) dropped->push_back(w);
  }
  if (kept.empty()) return out;
  stats::LinearFit g = stats::fitLinear(designOf(d, kept, true), d.y_fit, d.groups_fit, d.lags);
  if (!g.ok) return out;
  const double rms_all = valRms(d, kept);
  // 3. Components (cos and sin of one channel merged into one heading component).
  const auto& v = cfg.vehicle;
  const double alpha = 1.0 / (v.gearbox_efficiency * v.torque_constant_Nm_A);
  const double kF = 2 * v.geom.gear_ratio / (alpha * v.geom.wheel_radius_m);  // N per A
  const double kM = v.geom.track_width_m * v.geom.gear_ratio / (alpha * v.geom.wheel_radius_m);
  std::map<int, nlohmann::json> heading;  // mode -> {cos, sin, sd, gain}
  for (std::size_t k = 0; k < kept.size(); ++k) {
    const Col& c = kept[k];
    const std::string& term = names[c.term];
    const std::string dep = dependenceOf(term);
    const std::string channel = channelOf(term, c.mode);
    std::vector<Col> without = kept;
    without.erase(without.begin() + static_cast<long>(k));
    const double gain = valRms(d, without) - rms_all;
    const double b = g.beta(k), sd = std::sqrt(std::max(0.0, g.cov(k, k)));
    nlohmann::json comp = {
        {"channel", channel},
        {"dependence", dep},
        {"dependence_words", dependenceWords(dep)},
        {"term", term},
        {"coefficient", b},
        {"sd", sd},
        {"unit",
         "A per motor" + (termUnit(term).empty() ? std::string() : " per " + termUnit(term))},
        {"heldout_gain_A", gain}};
    if (const nlohmann::json alt = collinearReadings(kept, k, names, d, kCollinearR2);
        !alt.empty()) {
      comp["ambiguous_with"] = alt;
      comp["ambiguity"] = fmt::format(
          "on these data {} ({}) and {} ({}, R^2 {:.2f}) are nearly collinear: one ambiguous "
          "group; a drive exciting them differently (reversing, turning at several rates, "
          "in place and while driving) tells them apart",
          term, channel, alt[0]["term"].get<std::string>(), alt[0]["channel"].get<std::string>(),
          alt[0]["r2"].get<double>());
    }
    if (dep == "heading" && (channel == "forward" || channel == "yaw")) {
      auto& h = heading[c.mode];
      h[term == "cos(phi)" ? "cos" : "sin"] = b;
      h["sd"] = std::max(h.value("sd", 0.0), sd);
      h["gain"] = h.value("gain", 0.0) + gain;
      continue;
    }
    const bool load = channel == "forward" || channel == "yaw";
    if (load) {
      const double kk = channel == "yaw" ? kM : kF;
      std::string unit = channel == "yaw" ? "N m" : "N";
      if (dep == "acceleration")
        unit = channel == "yaw" ? "kg m^2" : "kg";
      else if (!termUnit(term).empty())
        unit += " per " + termUnit(term);
      // A load opposing the motion (b > 0) as a positive coefficient; inertia as a mass.
      const std::string quantity = dep == "acceleration"
                                       ? (channel == "yaw" ? "yaw inertia" : "mass")
                                       : (channel == "yaw" ? "yaw moment" : "forward force");
      comp["physical"] = {
          {"quantity", quantity}, {"value", kk * b}, {"sd", kk * sd}, {"unit", unit}};
      comp["reading"] = loadReading(channel, dep, term, kk * b, kk * sd, unit);
    } else if (channel == "wheels") {
      comp["reading"] = fmt::format(
          "each drive wheel, on its own speed ({}): {:.3g} +- {:.2g} A per motor ({})", term, b, sd,
          dep == "sign_of_rate" ? "dry friction of the wheels: rolling resistance, bearings"
                                : dependenceWords(dep));
    } else {
      const std::string side = c.mode == 2 ? "right" : "left";
      comp["reading"] =
          dep == "constant"
              ? fmt::format(
                    "only the {} motor's current: an offset of {:.3g} +- {:.2g} A (its "
                    "current sensor's zero, or a constant load on that drive alone)",
                    side, b, sd)
              : fmt::format(
                    "only the {} motor's current, {:.3g} +- {:.2g} A per unit {} ({}: "
                    "that drive alone)",
                    side, b, sd, term, dependenceWords(dep));
    }
    out.push_back(comp);
  }
  for (const auto& [mode, h] : heading) out.push_back(headingComponent(mode, h, kF, kM));
  return out;
}

namespace {

/// Blocked K-fold cross-validation by time of y on A (rows stacked [right; left], n per
/// motor): the out-of-fold residual.
Eigen::VectorXd timeFoldResidual(const Eigen::MatrixXd& A, const Eigen::VectorXd& y, int K) {
  const Eigen::Index n = y.size() / 2;
  Eigen::VectorXd r = y;
  if (A.cols() == 0) return r;
  for (int k = 0; k < K; ++k) {
    const Eigen::Index a = n * k / K, b = n * (k + 1) / K;
    std::vector<Eigen::Index> train, test;
    for (Eigen::Index i = 0; i < 2 * n; ++i)
      ((i % n) >= a && (i % n) < b ? test : train).push_back(i);
    Eigen::MatrixXd At(train.size(), A.cols());
    Eigen::VectorXd yt(train.size());
    for (std::size_t q = 0; q < train.size(); ++q) At.row(q) = A.row(train[q]), yt(q) = y(train[q]);
    const Eigen::VectorXd beta = At.colPivHouseholderQr().solve(yt);
    for (Eigen::Index i : test) r(i) = y(i) - A.row(i).dot(beta);
  }
  return r;
}

}  // namespace

CatalogueAlternative betterOutOfCatalogue(const Eigen::MatrixXd& D, int c,
                                          const std::string& c_dependence,
                                          const std::vector<int>& candidates,
                                          const std::vector<std::string>& names,
                                          const DynamicTermData& d, double crit, double min_r2,
                                          int folds) {
  CatalogueAlternative best;
  const Eigen::Index n = d.y_fit.size() / 2;
  if (n < 10 * folds || c < 0 || c >= D.cols()) return best;
  const Eigen::VectorXd xc = D.col(c);
  const double nr = xc.head(n).squaredNorm(), nl = xc.tail(n).squaredNorm();
  const int pattern = nl <= 1e-12 * nr ? 2 : (nr <= 1e-12 * nl ? 3 : 0);
  Eigen::MatrixXd Dw(D.rows(), D.cols() - 1);  // D without c
  Dw << D.leftCols(c), D.rightCols(D.cols() - c - 1);
  const double sse_D = timeFoldResidual(D, d.y_fit, folds).squaredNorm();
  for (int j : candidates) {
    const Eigen::VectorXd x = stacked(d, Col{j, pattern}, true);
    if (!(x.squaredNorm() > 0)) continue;
    if (!c_dependence.empty() && dependenceOf(names[j]) == c_dependence) continue;
    // A forward drag (v*|v|) or a dry yaw moment (sgn(omega)) loads both motors: not an
    // alternative to a one-motor term (on MuJoCo a v*|v| of one motor replaced a motor
    // asymmetry that the unmodeled search then described as |u| on that motor).
    if (pattern != 0 && (names[j] == "v*|v|" || names[j] == "sgn(omega)")) continue;
    Eigen::MatrixXd A(D.rows(), Dw.cols() + 1);
    A << Dw, x;
    // Only where the fitting order decides: c nearly in the span of the alternative model.
    const Eigen::VectorXd res_c = xc - A * A.colPivHouseholderQr().solve(xc);
    const double r2 = 1 - res_c.squaredNorm() / xc.squaredNorm();
    if (r2 < min_r2) continue;
    const Eigen::VectorXd ra = timeFoldResidual(A, d.y_fit, folds);
    const double sse_a = ra.squaredNorm();
    if (!(sse_a > 0)) continue;
    const double ne = stats::effectiveSampleSize(ra, d.groups_fit, d.lags);
    const double lr_alt = ne * std::log(sse_D / sse_a);
    if (lr_alt < crit || lr_alt <= best.lr_alt) continue;
    Eigen::MatrixXd Ac(D.rows(), A.cols() + 1);
    Ac << A, xc;
    const double lr_c = ne * std::log(sse_a / timeFoldResidual(Ac, d.y_fit, folds).squaredNorm());
    if (lr_c >= crit) continue;
    best = {j, pattern, lr_alt, lr_c, sse_D, sse_a, r2};
  }
  return best;
}

nlohmann::json describeKinematicTerms(const Finding& f) {
  nlohmann::json out = nlohmann::json::array();
  const double gain =
      f.fit_before.value("validation_rms_rad", 0.0) - f.fit_after.value("validation_rms_rad", 0.0);
  for (auto it = f.parameters.begin(); it != f.parameters.end(); ++it) {
    if (!it->is_number()) continue;
    const std::string& term = it.key();
    const std::string dep = dependenceOf(term);
    const double b = it->get<double>(), sd = f.uncertainty.value(term, 0.0);
    const std::string unit =
        "rad/s" + (termUnit(term).empty() ? std::string() : " per " + termUnit(term));
    std::string why = dep == "rate"           ? "a scale error of the odometry or the gyro"
                      : dep == "rate_squared" ? "wheels whose rolling radius changes with speed"
                      : dep == "heading"      ? "a heading-dependent gyro or wheel error"
                      : dep == "rate_product" ? "the chassis slipping sideways in turns"
                                              : dependenceWords(dep);
    out.push_back({{"channel", "gyro_vs_encoders"},
                   {"dependence", dep},
                   {"dependence_words", dependenceWords(dep)},
                   {"term", term},
                   {"coefficient", b},
                   {"sd", sd},
                   {"unit", unit},
                   {"heldout_gain_rad", gain},
                   {"reading", fmt::format("the gyro's turn rate minus the wheels' grows with {}: "
                                           "{:.3g} +- {:.2g} {} ({})",
                                           term, b, sd, unit, why)}});
  }
  return out;
}

std::string physicsSummary(const nlohmann::json& comps) {
  std::string s;
  for (const auto& c : comps)
    s += (s.empty() ? "" : "; ") + c.value("channel", std::string()) + ", " +
         c.value("dependence_words", std::string()) + ": " + c.value("reading", std::string());
  return s;
}

}  // namespace wheelchair::diagnosis
