#include "libwheelchair/simulation/MujocoEngine.h"

#include "libwheelchair/config/Options.h"
#include "libwheelchair/simulation/UnknownEffects.h"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

namespace wheelchair::simulation {

namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kGravity_m_s2 = 9.81;

const effects::EffectParamInfo* paramOf(const effects::EffectInfo& info, const std::string& key) {
  for (const auto& p : info.params)
    if (p.name == key) return &p;
  return nullptr;
}

const effects::EffectInfo* findMujocoEffect(const std::string& id) {
  for (const auto& e : mujocoEffectCatalogue())
    if (e.id == id) return &e;
  return nullptr;
}

/// A mujoco-only effect's number (its catalogue default when absent).
double mujocoNumber(const effects::EffectSpec& e, const std::string& key) {
  const effects::EffectInfo* info = findMujocoEffect(e.id);
  const effects::EffectParamInfo* p = info ? paramOf(*info, key) : nullptr;
  std::string t = e.has(key) ? e.params.at(key) : (p ? p->default_value : "");
  const char* s = t.c_str();
  char* end = nullptr;
  errno = 0;
  const double x = std::strtod(s, &end);
  if (t.empty() || end == s || *end != '\0' || errno == ERANGE || !std::isfinite(x))
    throw std::invalid_argument("effect '" + e.id + "': parameter '" + key + "' = '" + t +
                                "' is not a finite number");
  return x;
}

/// MuJoCo's warnings go to the engine (checked after each step) instead of stdout and
/// MUJOCO_LOG.TXT in the working directory.
void quietWarning(const char*) {}

/// Throws if MuJoCo flagged a numerical failure (it then resets the state silently).
void checkWarnings(const mjData* d) {
  for (int w : {mjWARN_BADQPOS, mjWARN_BADQVEL, mjWARN_BADQACC, mjWARN_BADCTRL, mjWARN_INERTIA})
    if (d->warning[w].number > 0)
      throw std::runtime_error(
          "MuJoCo: the chair's simulation became numerically unstable at t = " +
          std::to_string(d->time) + " s (bad state or inertia); check [mujoco] and [vehicle]");
}

std::string num(double x) {
  std::ostringstream s;
  s.precision(10);
  s << x;
  return s.str();
}

/// Everything the MJCF needs, with the effects applied.
struct ChairSpec {
  double r = 0, lw = 0, mw = 0, Iw = 0;
  double gear[2] = {0, 0}, damping[2] = {0, 0}, frictionloss[2] = {0, 0}, armature = 0;
  struct Part {
    const char* name;
    double mass, x, z, izz;
  };
  std::vector<Part> parts;  // chassis, seat, occupant (+ payload)
  double fork_m = 0, castor_m = 0, rc = 0, trail = 0, xc = 0, yc = 0;
  double fork_izz = 0, castor_iyy = 0;
  double swivel_damping = 0, swivel_friction = 0;
  double mu = 1, torsion = 0, rolling = 0, tyre_growth = 0;
  double slope = 0, downhill = 0;
};

ChairSpec makeSpec(const config::WheelchairConfig& cfg, const MujocoOptions& o,
                   const std::vector<effects::EffectSpec>& effects) {
  const auto& v = cfg.vehicle;
  ChairSpec c;
  c.r = v.geom.wheel_radius_m, c.lw = v.geom.track_width_m, c.mw = v.geom.wheel_mass_kg;
  c.Iw = v.wheel_inertia_kg_m2;
  const double rG = v.geom.gear_ratio, eta = v.gearbox_efficiency;
  // The catalogue effects act on the drive train as on the model engine's (effects/).
  effects::TruthModel truth;
  truth.drive = model::DriveTrain::symmetric(v);
  effects::actOnTruth(effects, truth);
  const auto& sd = truth.drive.side;
  const double km[2] = {sd[0].torque_constant_Nm_A, sd[1].torque_constant_Nm_A};
  const double B[2] = {sd[0].motor_viscous_Nm_s_rad, sd[1].motor_viscous_Nm_s_rad};
  const double coulomb_A[2] = {sd[0].coulomb_A, sd[1].coulomb_A};
  const double body_mass = truth.drive.geom.body_mass_kg;
  c.slope = truth.drive.slope_rad;
  c.downhill = truth.drive.downhill_heading_rad;
  c.swivel_damping = o.castor_swivel_damping_Nm_s_rad;
  c.mu = o.tyre_friction;
  // Effects only this engine knows.
  for (const auto& e : effects) {
    if (e.id == "castor_friction") {
      c.swivel_friction = mujocoNumber(e, "swivel_friction_Nm");
      if (e.has("swivel_damping_Nm_s_rad"))
        c.swivel_damping = mujocoNumber(e, "swivel_damping_Nm_s_rad");
    } else if (e.id == "tyre_scrub") {
      c.torsion = mujocoNumber(e, "torsion_m");
    } else if (e.id == "rolling_resistance") {
      c.rolling = mujocoNumber(e, "coefficient_m");
    } else if (e.id == "soft_tyre") {
      c.tyre_growth = mujocoNumber(e, "growth_m");
    } else if (e.id == "tyre_grip") {
      c.mu = mujocoNumber(e, "mu");
    }
  }
  // Drive: wheel torque = eta k r_G i - eta B r_G^2 psidot - eta k r_G c sgn(psidot), the
  // wheel-side form of the torque balance of model/DriveDynamics.h.
  for (int s = 0; s < 2; ++s) {
    c.gear[s] = eta * km[s] * rG;
    c.damping[s] = eta * B[s] * rG * rG;
    c.frictionloss[s] = eta * km[s] * rG * coulomb_A[s];
  }
  c.armature = v.motor_inertia_kg_m2 * rG * rG;
  // Castors.
  c.fork_m = o.castor_fork_mass_kg, c.castor_m = o.castor_wheel_mass_kg;
  c.rc = o.castor_wheel_radius_m, c.trail = o.castor_trail_m;
  c.xc = o.castor_x_m, c.yc = o.castor_half_spacing_m;
  c.fork_izz = c.fork_m * 0.02 * 0.02;
  c.castor_iyy = 0.5 * c.castor_m * c.rc * c.rc;
  // Body parts: the nominal m_b (castors excluded) split into chassis, seat and occupant, with
  // their own izz chosen so that the whole body's yaw inertia about the axle midpoint is the
  // configured I_zz (the castors' share included).
  const double m_nom = v.geom.body_mass_kg - 2 * (c.fork_m + c.castor_m);
  if (!(m_nom > 0))
    throw std::runtime_error("[mujoco] castor masses exceed [vehicle] body_mass_kg");
  const double occ_frac = 1.0 - o.chassis_fraction - o.seat_fraction;
  if (!(occ_frac > 0) || o.chassis_fraction <= 0 || o.seat_fraction < 0)
    throw std::runtime_error("[mujoco] chassis_fraction + seat_fraction must be in (0, 1)");
  c.parts = {{"chassis", o.chassis_fraction * m_nom, o.chassis_com_x_m, o.chassis_com_z_m, 0},
             {"seat", o.seat_fraction * m_nom, o.seat_com_x_m, o.seat_com_z_m, 0},
             {"occupant", occ_frac * m_nom, o.occupant_com_x_m, o.occupant_com_z_m, 0}};
  const double d_fork = std::hypot(c.xc - c.trail / 2, c.yc),
               d_cast = std::hypot(c.xc - c.trail, c.yc);
  double rest =
      v.yaw_inertia_kg_m2 - 2 * (c.fork_m * d_fork * d_fork + c.fork_izz +
                                 c.castor_m * d_cast * d_cast + 0.25 * c.castor_m * c.rc * c.rc);
  for (const auto& p : c.parts) rest -= p.mass * p.x * p.x;
  if (!(rest > 0))
    throw std::runtime_error("[vehicle] yaw_inertia_kg_m2 too small for the [mujoco] layout");
  for (auto& p : c.parts) p.izz = rest * p.mass / m_nom;
  c.parts[0].izz += externalLoad(effects).extra_yaw_inertia_kg_m2;  // UnknownEffects.h
  // Payload: the mass difference as its own body (a 0.3 m cube) ahead of the axle; a lighter
  // body takes the difference off the occupant.
  const double dm = body_mass - v.geom.body_mass_kg;
  if (dm > 0) {
    c.parts.push_back({"payload", dm, o.payload_x_m, o.payload_z_m, dm * 0.3 * 0.3 / 6});
  } else if (dm < 0) {
    auto& occ = c.parts[2];
    if (occ.mass + dm < 1.0)
      throw std::runtime_error("payload_mass: body_mass_kg leaves the occupant below 1 kg");
    occ.izz *= (occ.mass + dm) / occ.mass;
    occ.mass += dm;
  }
  return c;
}

std::string inertial(double x, double y, double z, double m, double ixx, double iyy, double izz) {
  return "<inertial pos=\"" + num(x) + " " + num(y) + " " + num(z) + "\" mass=\"" + num(m) +
         "\" diaginertia=\"" + num(ixx) + " " + num(iyy) + " " + num(izz) + "\"/>\n";
}

std::string tyreGeom(const std::string& name, double radius, const ChairSpec& c) {
  const int condim = c.rolling > 0 ? 6 : (c.torsion > 0 ? 4 : 3);
  return "<geom name=\"" + name + "\" type=\"sphere\" size=\"" + num(radius) +
         "\" contype=\"1\" conaffinity=\"0\" condim=\"" + std::to_string(condim) +
         "\" friction=\"" + num(c.mu) + " " + num(c.torsion) + " " + num(c.rolling) +
         "\" group=\"1\"/>\n";
}

}  // namespace

// ------------------------------------------------------------------------------------------
config::Options MujocoOptions::options(const std::string& sec) {
  using config::Range;
  const Range P = Range::above(0), any = Range::any(), nonneg = Range::atLeast(0);
  return config::Options(sec, "MuJoCo truth engine (simulate --engine mujoco; docs/simulation.md)")
      .real("timestep_s", timestep_s, "MuJoCo step (s)", Range{0, 0.01, true})
      .real("settle_s", settle_s, "standstill before t = 0 for the tyres to settle (s)", nonneg)
      .real("chassis_fraction", chassis_fraction, "share of m_b in the chassis (-)",
            Range{0, 1, true})
      .real("seat_fraction", seat_fraction, "share of m_b in the seat (-)", Range::between(0, 1))
      .real("chassis_com_x_m", chassis_com_x_m, "chassis centre of mass, x (m)", any)
      .real("chassis_com_z_m", chassis_com_z_m, "chassis centre of mass, z (m)", any)
      .real("seat_com_x_m", seat_com_x_m, "seat centre of mass, x (m)", any)
      .real("seat_com_z_m", seat_com_z_m, "seat centre of mass, z (m)", any)
      .real("occupant_com_x_m", occupant_com_x_m, "occupant centre of mass, x (m)", any)
      .real("occupant_com_z_m", occupant_com_z_m, "occupant centre of mass, z (m)", any)
      .real("castor_x_m", castor_x_m, "castor swivel axes, x (m)", P)
      .real("castor_half_spacing_m", castor_half_spacing_m, "castor swivel axes, +-y (m)", P)
      .real("castor_trail_m", castor_trail_m, "castor wheel axle behind the swivel axis (m)", P)
      .real("castor_wheel_radius_m", castor_wheel_radius_m, "castor wheel radius (m)",
            Range{0, 0.5, true, true})
      .real("castor_fork_mass_kg", castor_fork_mass_kg, "castor fork mass (kg)", P)
      .real("castor_wheel_mass_kg", castor_wheel_mass_kg, "castor wheel mass (kg)", P)
      .real("castor_swivel_damping_Nm_s_rad", castor_swivel_damping_Nm_s_rad,
            "castor swivel bearing damping (N m s/rad)", nonneg)
      .real("tyre_friction", tyre_friction, "tyre-floor Coulomb coefficient (-)", P)
      .real("payload_x_m", payload_x_m, "payload_mass effect: body position, x (m)", any)
      .real("payload_z_m", payload_z_m, "payload_mass effect: body position, z (m)", any)
      .real("sonar_height_m", sonar_height_m, "sonar height over the floor (m)", P)
      .integer("sonar_rays", sonar_rays, "rays across the sonar cone (-)", Range::between(2, 1000));
}

void MujocoOptions::loadFromConfig(const mrpt::config::CConfigFileBase& ini,
                                   const std::string& sec) {
  options(sec).load(ini);
}

namespace {
[[maybe_unused]] const bool kRegistered = config::registerOptionsOf<MujocoOptions>("mujoco");
}  // namespace

const std::vector<effects::EffectInfo>& mujocoEffectCatalogue() {
  static const std::vector<effects::EffectInfo> cat = {
      {"castor_friction",
       "(mujoco only) Dry friction and damping in the castor swivel bearings.",
       {{"swivel_friction_Nm", "N m", "dry friction torque of each swivel", "", {}, false, 0, 20},
        {"swivel_damping_Nm_s_rad",
         "N m s/rad",
         "viscous swivel damping (absent: [mujoco] castor_swivel_damping_Nm_s_rad)",
         "",
         {},
         true,
         0,
         20}}},
      {"tyre_scrub",
       "(mujoco only) Torsional friction of the tyre contact patches: turning costs torque.",
       {{"torsion_m",
         "m",
         "torsional friction coefficient (torque / normal force)",
         "",
         {},
         false,
         0,
         0.2}}},
      {"rolling_resistance",
       "(mujoco only) Rolling resistance of all tyres, proportional to the load on each.",
       {{"coefficient_m",
         "m",
         "rolling friction coefficient (torque / normal force)",
         "",
         {},
         false,
         0,
         0.05}}},
      {"soft_tyre",
       "(mujoco only) The drive tyres' rolling radius grows with speed: "
       "r = r0 + growth_m (u / 1 m/s)^2.",
       {{"growth_m", "m", "radius change at a rim speed of 1 m/s", "", {}, false, -0.02, 0.02}}},
      {"tyre_grip",
       "(mujoco only) Tyre-floor Coulomb friction coefficient (low: the chair slips).",
       {{"mu", "-", "friction coefficient", "", {}, false, 0.02, 3}}},
  };
  return cat;
}

const std::vector<std::string>& engineNames() {
  static const std::vector<std::string> n = {"model", "mujoco"};
  return n;
}

void validateEngineEffect(const effects::EffectSpec& e, const std::string& engine) {
  if (engine != "model" && engine != "mujoco")
    throw std::invalid_argument("unknown engine '" + engine + "' (known: model, mujoco)");
  const effects::EffectInfo* info = findMujocoEffect(e.id);
  if (const effects::EffectInfo* u = findUnknownEffect(e.id))
    return effects::validateAgainst(*u, e);
  if (!info) return effects::validateEffect(e);
  if (engine != "mujoco")
    throw std::invalid_argument("effect '" + e.id + "' exists only with --engine mujoco");
  effects::validateAgainst(*info, e);
}

effects::EffectSpec parseEngineEffect(const std::string& text, const std::string& engine) {
  effects::EffectSpec e = effects::parseEffect(text);
  validateEngineEffect(e, engine);
  return e;
}

// ------------------------------------------------------------------------------------------
std::string mujocoXml(const config::WheelchairConfig& cfg, const MujocoOptions& o,
                      const std::vector<effects::EffectSpec>& effects,
                      const std::vector<Obstacle>& obstacles) {
  const ChairSpec c = makeSpec(cfg, o, effects);
  std::ostringstream x;
  x << "<mujoco model=\"wheelchair\">\n"
    << "<compiler angle=\"radian\" inertiafromgeom=\"false\"/>\n"
    << "<option timestep=\"" << num(o.timestep_s) << "\" integrator=\"Euler\"/>\n"
    << "<worldbody>\n"
    << "<geom name=\"floor\" type=\"plane\" size=\"0 0 1\" contype=\"0\" conaffinity=\"1\" "
       "condim=\"3\" friction=\"0.01 0 0\" group=\"0\"/>\n";
  for (std::size_t i = 0; i < obstacles.size(); ++i)
    x << "<geom name=\"obstacle" << i << "\" type=\"cylinder\" pos=\"" << num(obstacles[i].x_m)
      << " " << num(obstacles[i].y_m) << " 0.5\" size=\"" << num(obstacles[i].radius_m)
      << " 0.5\" contype=\"0\" conaffinity=\"0\" group=\"3\" rgba=\"0.8 0.3 0.3 1\"/>\n";
  x << "<body name=\"chassis\" pos=\"0 0 " << num(c.r) << "\">\n"
    << "<joint name=\"root\" type=\"free\"/>\n";
  // The chassis' own inertial; seat, occupant and payload are welded child bodies.
  const auto& ch = c.parts[0];
  x << inertial(ch.x, 0, ch.z, ch.mass, ch.izz, ch.izz, ch.izz)
    << "<geom type=\"box\" size=\"0.35 0.25 0.03\" pos=\"0.15 0 0.05\" contype=\"0\" "
       "conaffinity=\"0\" group=\"2\"/>\n";
  for (std::size_t i = 1; i < c.parts.size(); ++i) {
    const auto& p = c.parts[i];
    x << "<body name=\"" << p.name << "\" pos=\"0 0 0\">\n"
      << inertial(p.x, 0, p.z, p.mass, p.izz, p.izz, p.izz) << "</body>\n";
  }
  const char* side_name[2] = {"right", "left"};
  for (int s = 0; s < 2; ++s) {
    const double y = (s == 0 ? -1 : 1) * c.lw / 2;
    x << "<body name=\"wheel_" << side_name[s] << "\" pos=\"0 " << num(y) << " 0\">\n"
      << "<joint name=\"wheel_" << side_name[s] << "\" type=\"hinge\" axis=\"0 1 0\" damping=\""
      << num(c.damping[s]) << "\" frictionloss=\"" << num(c.frictionloss[s]) << "\" armature=\""
      << num(c.armature) << "\"/>\n"
      << inertial(0, 0, 0, c.mw, c.Iw / 2, c.Iw, c.Iw / 2)
      << tyreGeom("tyre_" + std::string(side_name[s]), c.r, c) << "</body>\n";
  }
  for (int s = 0; s < 2; ++s) {
    const double y = (s == 0 ? -1 : 1) * c.yc;
    x << "<body name=\"fork_" << side_name[s] << "\" pos=\"" << num(c.xc) << " " << num(y)
      << " 0\">\n"
      << "<joint name=\"swivel_" << side_name[s] << "\" type=\"hinge\" axis=\"0 0 1\" damping=\""
      << num(c.swivel_damping) << "\" frictionloss=\"" << num(c.swivel_friction)
      << "\" armature=\"0.001\"/>\n"
      << inertial(-c.trail / 2, 0, (c.rc - c.r) / 2, c.fork_m, c.fork_izz, c.fork_izz, c.fork_izz)
      << "<body name=\"castor_" << side_name[s] << "\" pos=\"" << num(-c.trail) << " 0 "
      << num(c.rc - c.r) << "\">\n"
      << "<joint name=\"castor_" << side_name[s]
      << "\" type=\"hinge\" axis=\"0 1 0\" damping=\"0.0005\" armature=\"0.0005\"/>\n"
      << inertial(0, 0, 0, c.castor_m, c.castor_iyy / 2, c.castor_iyy, c.castor_iyy / 2)
      << tyreGeom("castor_tyre_" + std::string(side_name[s]), c.rc, c) << "</body>\n</body>\n";
  }
  x << "</body>\n</worldbody>\n<actuator>\n";
  for (int s = 0; s < 2; ++s)
    x << "<motor name=\"motor_" << side_name[s] << "\" joint=\"wheel_" << side_name[s]
      << "\" gear=\"" << num(c.gear[s]) << "\"/>\n";
  x << "</actuator>\n</mujoco>\n";
  return x.str();
}

// ------------------------------------------------------------------------------------------
struct MujocoChair::Impl {
  mjModel* m = nullptr;
  mjData* d = nullptr;
  ChairSpec spec;
  MujocoOptions opt;
  int q_wheel[2] = {0, 0}, v_wheel[2] = {0, 0}, q_swivel[2] = {0, 0};
  int tyre_geom[2] = {0, 0};
  int chassis = 0;
  ExternalLoad load;  ///< out-of-catalogue force and moment on the chassis (UnknownEffects.h)
  double phi = 0;  // unwrapped heading
  double step_h = 0;
  int substeps = 1;

  ~Impl() {
    if (d) mj_deleteData(d);
    if (m) mj_deleteModel(m);
  }
  double yaw() const {
    const double* q = d->qpos + 3;  // w x y z
    return std::atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] * q[2] + q[3] * q[3]));
  }
  void unwrap() {
    const double y = yaw();
    double dphi = y - std::remainder(phi, 2 * M_PI);
    dphi = std::remainder(dphi, 2 * M_PI);
    phi += dphi;
  }
  /// The out-of-catalogue forward force and yaw moment on the chassis (world frame).
  void externalForce() {
    const double c = std::cos(phi), sn = std::sin(phi);
    const double* v = d->qvel;
    const Eigen::Vector2d fm = load.forceMoment(c * v[0] + sn * v[1], v[5], phi);
    double* x = d->xfrc_applied + 6 * chassis;
    x[0] = fm(0) * c, x[1] = fm(0) * sn, x[5] = fm(1);
  }
  void softTyre() {
    if (spec.tyre_growth == 0) return;
    for (int s = 0; s < 2; ++s) {
      const double u = spec.r * d->qvel[v_wheel[s]];
      const double r = spec.r + spec.tyre_growth * u * u;
      m->geom_size[3 * tyre_geom[s]] = r;
      m->geom_rbound[tyre_geom[s]] = r;
    }
  }
};

MujocoChair::MujocoChair(const config::WheelchairConfig& cfg, const MujocoOptions& opt,
                         const std::vector<effects::EffectSpec>& effects,
                         const std::vector<Obstacle>& obstacles)
    : impl_(std::make_unique<Impl>()) {
  xml_ = mujocoXml(cfg, opt, effects, obstacles);
  Impl& I = *impl_;
  I.spec = makeSpec(cfg, opt, effects);
  I.opt = opt;
  I.load = externalLoad(effects);
  auto vfs = std::make_unique<mjVFS>();
  mj_defaultVFS(vfs.get());
  const char* name = "wheelchair.xml";
  if (mj_makeEmptyFileVFS(vfs.get(), name, static_cast<int>(xml_.size())) != 0)
    throw std::runtime_error("MuJoCo: cannot create the model file in the VFS");
  const int idx = mj_findFileVFS(vfs.get(), name);
  std::memcpy(vfs->filedata[idx], xml_.data(), xml_.size());
  char err[1000] = "";
  static const bool quiet = (mju_user_warning = quietWarning, true);  // once, thread-safe
  (void)quiet;
  I.m = mj_loadXML(name, vfs.get(), err, sizeof err);
  mj_deleteVFS(vfs.get());
  if (!I.m)
    throw std::runtime_error(std::string("MuJoCo: the chair model does not compile: ") + err);
  I.d = mj_makeData(I.m);
  const char* side_name[2] = {"right", "left"};
  I.chassis = mj_name2id(I.m, mjOBJ_BODY, "chassis");
  for (int s = 0; s < 2; ++s) {
    const int jw = mj_name2id(I.m, mjOBJ_JOINT, ("wheel_" + std::string(side_name[s])).c_str());
    const int js = mj_name2id(I.m, mjOBJ_JOINT, ("swivel_" + std::string(side_name[s])).c_str());
    I.q_wheel[s] = I.m->jnt_qposadr[jw];
    I.v_wheel[s] = I.m->jnt_dofadr[jw];
    I.q_swivel[s] = I.m->jnt_qposadr[js];
    I.tyre_geom[s] = mj_name2id(I.m, mjOBJ_GEOM, ("tyre_" + std::string(side_name[s])).c_str());
  }
  // Settle on a level floor with the motors off, then restart the clock at the origin.
  I.m->opt.gravity[0] = I.m->opt.gravity[1] = 0;
  I.m->opt.gravity[2] = -kGravity_m_s2;
  const long n_settle = std::lround(std::max(0.0, opt.settle_s) / I.m->opt.timestep);
  for (long k = 0; k < n_settle; ++k) mj_step(I.m, I.d);
  checkWarnings(I.d);
  double* q = I.d->qpos;
  const double yaw = I.yaw(), c = std::cos(-yaw / 2), sn = std::sin(-yaw / 2);
  const double w = q[3], a = q[4], b = q[5], z = q[6];  // qz(-yaw) * q
  q[3] = c * w - sn * z, q[4] = c * a - sn * b, q[5] = c * b + sn * a, q[6] = c * z + sn * w;
  q[0] = q[1] = 0;
  for (int s = 0; s < 2; ++s) q[I.q_wheel[s]] = 0;
  for (int i = 0; i < I.m->nv; ++i) I.d->qvel[i] = 0;
  I.d->time = 0;
  // The slope: gravity tilted in the floor frame, downhill along downhill_heading.
  const auto& sp = I.spec;
  I.m->opt.gravity[0] = kGravity_m_s2 * std::sin(sp.slope) * std::cos(sp.downhill);
  I.m->opt.gravity[1] = kGravity_m_s2 * std::sin(sp.slope) * std::sin(sp.downhill);
  I.m->opt.gravity[2] = -kGravity_m_s2 * std::cos(sp.slope);
  mj_forward(I.m, I.d);
  I.phi = 0;
}

MujocoChair::~MujocoChair() = default;

void MujocoChair::step(const Eigen::Vector2d& current_A, double h_s) {
  Impl& I = *impl_;
  if (h_s != I.step_h) {
    I.step_h = h_s;
    I.substeps = std::max(1, static_cast<int>(std::ceil(h_s / I.opt.timestep_s - 1e-9)));
    I.m->opt.timestep = h_s / I.substeps;
  }
  I.d->ctrl[0] = current_A(0);
  I.d->ctrl[1] = current_A(1);
  for (int k = 0; k < I.substeps; ++k) {
    if (I.load.any()) I.externalForce();
    I.softTyre();
    mj_step(I.m, I.d);
    I.unwrap();
  }
  checkWarnings(I.d);
}

ChairState MujocoChair::state() const {
  const Impl& I = *impl_;
  ChairState s;
  const double* q = I.d->qpos;
  const double* v = I.d->qvel;
  s.x_m = q[0], s.y_m = q[1], s.phi_rad = I.phi;
  const double c = std::cos(I.phi), sn = std::sin(I.phi);
  s.v_m_s = c * v[0] + sn * v[1];
  s.lateral_m_s = -sn * v[0] + c * v[1];
  s.omega_rad_s = v[5];  // free joint: angular velocity in the chassis frame
  s.psi_right_rad = q[I.q_wheel[0]], s.psi_left_rad = q[I.q_wheel[1]];
  s.psidot_right_rad_s = v[I.v_wheel[0]], s.psidot_left_rad_s = v[I.v_wheel[1]];
  s.castor_swivel_right_rad = q[I.q_swivel[0]], s.castor_swivel_left_rad = q[I.q_swivel[1]];
  return s;
}

double MujocoChair::sonarRange(double x_m, double y_m, double yaw_rad,
                               double half_angle_rad) const {
  const Impl& I = *impl_;
  const mjtByte groups[mjNGROUP] = {0, 0, 0, 1, 0, 0};  // obstacles only
  double best = std::numeric_limits<double>::infinity();
  const int n = I.opt.sonar_rays;
  for (int k = 0; k < n; ++k) {
    const double a = yaw_rad - half_angle_rad + 2 * half_angle_rad * k / (n - 1);
    const mjtNum pnt[3] = {x_m, y_m, I.opt.sonar_height_m};
    const mjtNum vec[3] = {std::cos(a), std::sin(a), 0};
    int geom = -1;
    const double dist = mj_ray(I.m, I.d, pnt, vec, groups, 1, -1, &geom);
    if (dist >= 0) best = std::min(best, dist);
  }
  return best;
}

std::vector<MujocoPart> MujocoChair::parts() const {
  const mjModel* m = impl_->m;
  const mjData* d = impl_->d;
  std::vector<MujocoPart> out;
  for (int b = 1; b < m->nbody; ++b) {
    if (m->body_mass[b] <= 0) continue;
    const char* n = mj_id2name(m, mjOBJ_BODY, b);
    out.push_back({n ? n : "", d->xipos[3 * b], d->xipos[3 * b + 1], d->xipos[3 * b + 2],
                   m->body_mass[b], 0});
  }
  for (int g = 0; g < m->ngeom; ++g) {
    if (m->geom_type[g] != mjGEOM_SPHERE) continue;
    const char* n = mj_id2name(m, mjOBJ_GEOM, g);
    out.push_back({n ? n : "", d->geom_xpos[3 * g], d->geom_xpos[3 * g + 1],
                   d->geom_xpos[3 * g + 2], 0, m->geom_size[3 * g]});
  }
  return out;
}

double MujocoChair::totalMass() const {
  return impl_->m->body_subtreemass[1];
}

double MujocoChair::time() const {
  return impl_->d->time;
}

}  // namespace wheelchair::simulation
