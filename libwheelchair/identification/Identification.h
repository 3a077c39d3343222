// Parameter identification of the drive model from recordings (issue 5, paper section II.C,
// eq. (2)-(6), Appendix VI). docs/identification.md has the derivations and the rules.
//
// What the currents can tell (derived in docs/identification.md): for every drive,
//   Y_i(v, vdot, omega, omegadot) theta = D1 vdot + s_i D2 omegadot + theta_5 (r_G/r) u_i,
//   D1 = (r/r_G)(m_w + m_b/2) theta_1 + (r_G/r) theta_2 + theta_3/(r r_G)      (= 1/(2 a1))
//   D2 = (r/r_G)(m_w l_w/2 theta_1 + theta_4/l_w) + (l_w/2)((r_G/r) theta_2 + theta_3/(r r_G))
//                                                                             (= 1/(2 a2))
// so the 5 columns of Y span at most 3 dimensions: theta_5, D1 and D2 are identifiable (when
// the drive excites vdot, omegadot and motion), theta_1..theta_4 individually never are.
// a1 = 1/(2 D1), a2 = 1/(2 D2), a3 = -theta_5 r_G/(r D1), a4 = -theta_5 l_w r_G/(2 r D2).
//
// Example:
//   auto cfg = config::WheelchairConfig::load("config/wheelchair.ini");
//   IdentificationOptions opt;  opt.loadFromConfig(cfg.ini());
//   IdentificationResult res = identify({io::readRawlog("drive.rawlog")}, cfg, opt);
//   std::cout << res.toJson().dump(2);
//   identifiedConfig(cfg, res).save("identified.ini");
#pragma once

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/io/Recording.h"
#include "libwheelchair/signals/IntervalSignals.h"
#include "libwheelchair/stats/LeastSquares.h"

#include <nlohmann/json.hpp>

#include <array>
#include <limits>
#include <string>
#include <vector>

namespace wheelchair::identification {

// The HAC least squares of the identification is the library's one (stats/LeastSquares.h).

/// Section [identification] of the configuration (config/wheelchair.ini documents each key).
struct IdentificationOptions {
  double rate_hz = 100.0;                 ///< common time base (Hz)
  double cutoff_hz = 2.0;                 ///< zero-phase Butterworth cut-off (Hz), all signals
  std::string omega_source = "encoders";  ///< "encoders" or "gyro"
  double standstill_speed_m_s = 0.03;     ///< a sample is standstill when both |u_i| are below
  double edge_trim_s = 1.0;               ///< dropped at both ends of every continuous segment
  double max_gap_s = 0.25;                ///< a stream gap longer than this splits a segment
  double min_excitation_snr = 10.0;       ///< rms(signal)/noise floor below which it is unexcited
  double hac_lag_factor = 4.0;            ///< HAC bandwidth = factor * rate_hz / cutoff_hz steps
  double confidence = 0.95;               ///< two-sided level of the reported intervals
  double rank_tol = 1e-9;                 ///< relative singular-value threshold
  double qs_max_vdot_m_s2 = 0.05;         ///< quasi-steady: |vdot| below this ...
  double qs_max_omegadot_rad_s2 = 0.1;    ///< ... and |omegadot| below this ...
  double qs_min_duration_s = 2.0;         ///< ... for at least this long ...
  double qs_min_wheel_speed_m_s = 0.1;    ///< ... with both |u_i| above this
  bool update_torque_constant = true;     ///< --write-config: k_m from the back-EMF fit

  /// The key table (config/Options.h), bound to this object.
  config::Options options(const std::string& section = "identification");
  /// Reads the keys present (strict numbers, ranges); throws naming file, line and key.
  void loadFromConfig(const mrpt::config::CConfigFileBase& ini,
                      const std::string& section = "identification");
  /// Throws std::runtime_error (message prefixed by `where`) on inconsistent values.
  void validate(const std::string& where = "identification options") const;
  int hacLags() const;
  /// The conditioning options these select (signals::prepareIntervalMeans).
  signals::IntervalSignalOptions intervalSignalOptions() const;
  nlohmann::json toJson() const;
};

/// One identified quantity; `identifiable == false` means value/se are not reported (JSON null)
/// and `reason` says why.
struct Estimate {
  bool identifiable = false;
  double value = std::numeric_limits<double>::quiet_NaN();
  double se = std::numeric_limits<double>::quiet_NaN();        ///< HAC standard error
  double se_naive = std::numeric_limits<double>::quiet_NaN();  ///< iid standard error
  std::string reason;
  nlohmann::json toJson(double z) const;
};

/// How strongly the drive excited one signal (over the samples used).
struct Excitation {
  std::string signal;  ///< "v", "omega", "vdot", "omegadot"
  double rms = 0;      ///< of the filtered signal
  double noise = 0;    ///< estimated rms of its noise after filtering (and differentiation)
  double snr = 0;
  bool excited = false;
};

/// A quasi-steady stretch used for the per-motor constants.
struct QuasiSteadySegment {
  int recording = 0;
  double t_start_s = 0, t_end_s = 0;
  double v_m_s = 0, omega_rad_s = 0;
  std::array<double, 2> current_A{};          ///< mean motor current (right, left)
  std::array<double, 2> voltage_V{};          ///< mean motor voltage U from the V_RC inverse
  std::array<double, 2> motor_speed_rad_s{};  ///< mean omega_m = (r_G/r) u_i
  std::array<bool, 2> used{};                 ///< side's wheel fast enough to use it
};

struct MotorResult {
  Estimate k_over_eta;      ///< eq. (4): U/omega_m (N m/A, = V s/rad)
  Estimate back_emf_k;      ///< U - R_m i = k omega_m (N m/A)
  Estimate D1, D2, theta5;  ///< per-side regression i_i = D1 vdot + s D2 omegadot + theta5 rG/r u_i
  int n_segments = 0;
};

struct RegressionReport {
  std::vector<std::string> columns;
  int rank = 0;
  double condition_number = 0;               ///< equilibrated full problem (inf if deficient)
  double condition_number_identifiable = 0;  ///< equilibrated, retained subspace
  std::vector<double> singular_values_rel;   ///< sigma_k / sigma_max
  stats::ResidualStats residual;
  nlohmann::json toJson() const;
};

struct NullDirection {
  std::vector<double> direction;         ///< unit vector over theta_1..theta_5 (parameter units)
  std::vector<double> direction_scaled;  ///< the right singular vector (equilibrated columns)
  double singular_value_rel = 0;
  std::string description;
};

struct IdentificationResult {
  IdentificationOptions options;
  std::string config_origin;
  std::vector<std::string> sources;  ///< recording names (paths), in input order
  int hac_lags = 0;
  double z = 1.96;  ///< multiplier of the stated confidence
  std::size_t n_grid = 0, n_used = 0, n_standstill = 0, n_edge = 0;
  std::vector<Excitation> excitation;

  RegressionReport theta_regression;  ///< the 5-column form (2), stacked right/left rows
  std::vector<NullDirection> null_directions;
  std::array<Estimate, 5> theta;
  Estimate D1, D2;
  std::array<Estimate, 4> a_from_theta;  ///< a1..a4 via Appendix VI
  std::array<Estimate, 4> a_direct;      ///< a1..a4 regressing (6) directly
  RegressionReport direct_v, direct_omega;
  std::array<MotorResult, 2> motor;  ///< 0 right, 1 left
  RegressionReport per_side[2];
  std::vector<QuasiSteadySegment> segments;
  std::vector<std::string> notes;

  nlohmann::json toJson() const;
};

/// Identifies from one or several recordings (stacked). `sources` names them in the report.
/// Throws std::runtime_error when no usable data remain (message says why).
IdentificationResult identify(const std::vector<io::Recording>& recordings,
                              const config::WheelchairConfig& cfg, const IdentificationOptions& opt,
                              const std::vector<std::string>& sources = {});
/// The same, releasing the recordings once their signals are conditioned (before the fits, the
/// peak of memory: `identify` holds no recording while it fits). Same result.
IdentificationResult identify(std::vector<io::Recording>&& recordings,
                              const config::WheelchairConfig& cfg, const IdentificationOptions& opt,
                              const std::vector<std::string>& sources = {});

/// The same from rawlog files read as a stream (`identify` on long drives: memory does not grow
/// with the drive, docs/benchmarks.md "Memory"): the conditioning runs as the samples come
/// (signals::IntervalConditioner) and the used samples wait in a scratch file for the fits
/// (~100 B each: ~35 MB of temporary disk per recorded hour at 100 Hz). The same result as
/// identify() on the files' recordings (tests/identification) when every file is in time order
/// (io::RecordingSummary::lateness_s == 0; the caller checks); a damaged file is read up to its
/// break (the caller applies the salvage rule first).
IdentificationResult identifyStreamed(const std::vector<std::string>& paths,
                                      const config::WheelchairConfig& cfg,
                                      const IdentificationOptions& opt,
                                      const std::vector<std::string>& sources = {});

/// The input configuration with the identified values written in (docs/identification.md,
/// "Writing the configuration"): [vehicle] gearbox_efficiency, yaw_inertia_kg_m2,
/// motor_viscous_Nm_s_rad, torque_constant_Nm_A change; a new [identified] section records
/// the estimates. `changes` (optional) receives one line per changed key.
config::WheelchairConfig identifiedConfig(const config::WheelchairConfig& base,
                                          const IdentificationResult& res,
                                          std::vector<std::string>* changes = nullptr);

// --- building blocks (exposed for tests) -------------------------------------------------

/// The conditioned signals (signals::prepareIntervalMeans, with intervalSignalOptions()).
using PreparedSegment = signals::IntervalSegment;
using PreparedData = signals::IntervalSignals;

/// Linear functionals of theta: D1, D2 (see above).
Eigen::Matrix<double, 5, 1> d1Weights(const model::Geometry& g);
Eigen::Matrix<double, 5, 1> d2Weights(const model::Geometry& g);

}  // namespace wheelchair::identification
