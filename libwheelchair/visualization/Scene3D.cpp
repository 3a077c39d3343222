#include "libwheelchair/visualization/Scene3D.h"

#include "libwheelchair/util/Text.h"
#include "libwheelchair/visualization/Plot.h"

#include <mrpt/img/CImage.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/opengl/CBox.h>
#include <mrpt/opengl/CCylinder.h>
#include <mrpt/opengl/CEllipsoid2D.h>
#include <mrpt/opengl/CFBORender.h>
#include <mrpt/opengl/CGridPlaneXY.h>
#include <mrpt/opengl/CPointCloud.h>
#include <mrpt/opengl/CSetOfLines.h>
#include <mrpt/opengl/CSetOfTriangles.h>
#include <mrpt/opengl/CSphere.h>
#include <mrpt/poses/CPose3D.h>

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

namespace wheelchair::visualization {

void fillRibbon(mrpt::opengl::CSetOfTriangles& t, const std::vector<std::pair<double, double>>& pts,
                double width, double z, bool closed);

namespace {

using namespace mrpt::opengl;

// Chair footprint (body frame, m): the simulator's default (simulation::Footprint).
constexpr double kFront = 0.60, kRear = 0.30, kHalfWidth = 0.33;

mrpt::img::TColorf tcolor(Color c, float a = 1.0f) {
  return mrpt::img::TColorf(c.r / 255.f, c.g / 255.f, c.b / 255.f, a);
}

CSetOfLines::Ptr polyline(const std::vector<std::pair<double, double>>& pts, Color c, float width,
                          double z) {
  auto l = CSetOfLines::Create();
  for (std::size_t i = 1; i < pts.size(); ++i)
    l->appendLine(pts[i - 1].first, pts[i - 1].second, z, pts[i].first, pts[i].second, z);
  l->setColor_u8(c.r, c.g, c.b);
  l->setLineWidth(width);
  return l;
}

// A flat ribbon of `width` metres along a polyline (OpenGL core profiles draw lines 1 px wide
// whatever the requested width, so thick curves are made of triangles). Unlit: exact colour.
CSetOfTriangles::Ptr ribbon(const std::vector<std::pair<double, double>>& pts, Color c,
                            double width, double z, bool closed = false) {
  auto t = CSetOfTriangles::Create();
  fillRibbon(*t, pts, width, z, closed);
  t->setColor_u8(mrpt::img::TColor(c.r, c.g, c.b));
  t->enableLight(false);
  return t;
}

}  // namespace

void fillRibbon(CSetOfTriangles& t, const std::vector<std::pair<double, double>>& pts, double width,
                double z, bool closed) {
  t.clearTriangles();
  const double h = width / 2;
  const float zf = static_cast<float>(z);
  for (std::size_t i = 1; i < pts.size(); ++i) {
    const double x0 = pts[i - 1].first, y0 = pts[i - 1].second, x1 = pts[i].first,
                 y1 = pts[i].second;
    const double L = std::hypot(x1 - x0, y1 - y0);
    if (L < 1e-9) continue;
    const double nx = -(y1 - y0) / L * h, ny = (x1 - x0) / L * h;
    // Extend each piece by half the width so consecutive pieces overlap at the joints.
    const double ex = (x1 - x0) / L * h, ey = (y1 - y0) / L * h;
    const mrpt::math::TPoint3Df a(x0 - ex + nx, y0 - ey + ny, zf),
        b(x0 - ex - nx, y0 - ey - ny, zf), cc(x1 + ex - nx, y1 + ey - ny, zf),
        d(x1 + ex + nx, y1 + ey + ny, zf);
    t.insertTriangle(TTriangle(b, cc, d));  // counter-clockwise seen from above
    t.insertTriangle(TTriangle(b, d, a));
  }
  (void)closed;
}

Color variantColor(const std::string& v) {
  if (v == "encoders") return Color{0, 60, 255};
  if (v == "encoders_gyro") return Color{0, 170, 0};
  if (v == "ekf") return colors::black;
  if (v == "baseline") return Color{150, 60, 200};
  if (v == "truth") return Color{140, 0, 0};
  return Color{230, 0, 0};  // ground truth
}

std::string variantLabel(const std::string& v) {
  if (v == "encoders") return "encoders only";
  if (v == "encoders_gyro") return "encoder v + gyro omega";
  if (v == "ekf") return "EKF";
  if (v == "baseline") return "baseline EKF (kinematic)";
  if (v == "truth") return "true path (simulation)";
  return v;
}

namespace {

using Legend = std::vector<std::pair<std::string, Color>>;

// The drives on the ground: the simulated truth, each estimate as a ribbon (widest first), the
// ground-truth points and the true obstacles; their legend entries.
void insertDrives(COpenGLScene& scene, const DriveData& d, Legend& legend) {
  double z = 0.01;
  if (d.truth && !d.truth->t_s.empty()) {
    std::vector<std::pair<double, double>> p;
    for (std::size_t i = 0; i < d.truth->t_s.size(); i += 5)
      p.emplace_back(d.truth->x_m[i], d.truth->y_m[i]);
    if (p.size() > Plot::kDecimateAbove) {  // a long drive: the points drawn (pathPointsToDraw)
      const auto keep = pathPointsToDraw(
          p.size(), [&](std::size_t i) { return p[i].first; },
          [&](std::size_t i) { return p[i].second; });
      std::vector<std::pair<double, double>> drawn;
      drawn.reserve(keep.size());
      for (std::size_t i : keep) drawn.push_back(p[i]);
      p = std::move(drawn);
    }
    scene.insert(ribbon(p, variantColor("truth"), 0.03, z));
    legend.emplace_back(variantLabel("truth"), variantColor("truth"));
  }
  for (const std::string v : {"encoders", "encoders_gyro", "baseline", "ekf"}) {
    auto it = d.trajectories.find(v);
    if (it == d.trajectories.end()) continue;
    std::vector<std::pair<double, double>> p;
    const std::size_t step = std::max<std::size_t>(1, it->second.size() / 1500);
    for (std::size_t i = 0; i < it->second.size(); i += step)
      p.emplace_back(it->second[i].x_m, it->second[i].y_m);
    p.emplace_back(it->second.back().x_m, it->second.back().y_m);
    z += 0.005;
    // Nested widths (widest first): where the trajectories coincide each still shows as a
    // coloured edge around the next one instead of being hidden under it.
    const double width_m = v == "encoders"        ? 0.16
                           : v == "encoders_gyro" ? 0.12
                           : v == "baseline"      ? 0.08
                                                  : 0.04;
    scene.insert(ribbon(p, variantColor(v), width_m, z));
    legend.emplace_back(variantLabel(v), variantColor(v));
  }
  if (!d.gt_start.empty()) {
    auto pc = CPointCloud::Create();
    for (const auto& s : d.gt_start) pc->insertPoint(s.x_m, s.y_m, 0.03f);
    const Color c = variantColor("gt");
    pc->setColor_u8(c.r, c.g, c.b);
    pc->setPointSize(4.0f);
    scene.insert(pc);
    legend.emplace_back(d.gt.source == evaluation::GroundTruthSource::Pozyx ? "Pozyx (ground truth)"
                                                                            : "ground truth",
                        c);
  }
  if (d.truth)
    for (const auto& o : d.truth->obstacles) {
      const float rr = static_cast<float>(std::max(0.08, o.radius_m));
      auto cyl = CCylinder::Create(rr, rr, 0.5f, 16);
      cyl->setColor_u8(220, 30, 30);
      cyl->setLocation(o.x_m, o.y_m, 0);
      scene.insert(cyl);
    }
}

// The chair in its body frame: footprint box and outline, wheels, heading arrow.
void insertChairBody(CSetOfObjects& chair, const DriveData& d) {
  auto body = CBox::Create(mrpt::math::TPoint3D(-kRear, -kHalfWidth, 0.02),
                           mrpt::math::TPoint3D(kFront, kHalfWidth, 0.10));
  body->setColor_u8(255, 190, 60, 150);
  chair.insert(body);
  chair.insert(polyline({{-kRear, -kHalfWidth},
                         {kFront, -kHalfWidth},
                         {kFront, kHalfWidth},
                         {-kRear, kHalfWidth},
                         {-kRear, -kHalfWidth}},
                        Color{90, 60, 0}, 2.0f, 0.11));
  const double r = d.cfg.vehicle.geom.wheel_radius_m, hw = d.cfg.vehicle.geom.track_width_m / 2;
  for (double side : {-1.0, 1.0}) {
    auto w = CBox::Create(mrpt::math::TPoint3D(-r, side * hw - 0.03, 0.0),
                          mrpt::math::TPoint3D(r, side * hw + 0.03, 2 * r));
    w->setColor_u8(40, 40, 40);
    chair.insert(w);
  }
  chair.insert(polyline({{0, 0}, {kFront + 0.25, 0}}, Color{90, 60, 0}, 2.0f, 0.12));
}

// The sonar cone of unit radius at the sonar's mounting pose (scaled to a reading later):
// filled orange (a reading) or a grey outline (no echo).
CSetOfObjects::Ptr sonarFan(const config::SonarParams& so, bool filled) {
  const double half_cone = so.cone_half_angle_deg * M_PI / 180.0;
  auto set = CSetOfObjects::Create();
  std::vector<std::pair<double, double>> arc{{0, 0}};
  const int n = 16;
  auto tris = CSetOfTriangles::Create();
  for (int i = 0; i <= n; ++i) {
    const double a = -half_cone + 2 * half_cone * i / n;
    arc.emplace_back(std::cos(a), std::sin(a));
    if (i > 0 && filled)
      tris->insertTriangle(
          TTriangle(mrpt::math::TPoint3Df(0, 0, 0.05f),
                    mrpt::math::TPoint3Df(arc[i].first, arc[i].second, 0.05f),
                    mrpt::math::TPoint3Df(arc[i + 1].first, arc[i + 1].second, 0.05f)));
  }
  arc.emplace_back(0, 0);
  if (filled) {
    tris->setColor_u8(mrpt::img::TColor(255, 140, 0, 110));
    set->insert(tris);
  }
  set->insert(polyline(arc, filled ? Color{230, 110, 0} : Color{150, 150, 150}, 2.0f, 0.06));
  set->setPose(mrpt::poses::CPose3D(so.x_m, so.y_m, 0.0, so.yaw_deg * M_PI / 180.0, 0, 0));
  return set;
}

}  // namespace

DriveScene::DriveScene(const DriveData& d) : d_(d) {
  scene_ = COpenGLScene::Create();
  auto vp = scene_->getViewport("main");
  vp->setCustomBackgroundColor(mrpt::img::TColorf(0.97f, 0.97f, 0.97f));

  // Ground grid over the drive (1 m).
  double cx, cy, zoom;
  view(cx, cy, zoom);
  const double half = std::max(4.0, zoom * 0.45);
  auto grid = CGridPlaneXY::Create(std::floor(cx - half), std::ceil(cx + half),
                                   std::floor(cy - half), std::ceil(cy + half), 0, 1, 1.0f);
  grid->setColor_u8(175, 175, 175);
  scene_->insert(grid);
  insertDrives(*scene_, d, legend_);

  // The chair (body frame children) with the sonar cone.
  chair_ = CSetOfObjects::Create();
  insertChairBody(*chair_, d);
  cone_ = sonarFan(d.cfg.sonar, true);
  cone_empty_ = sonarFan(d.cfg.sonar, false);
  cone_empty_->setScale(static_cast<float>(d.cfg.sonar.max_range_m));
  chair_->insert(cone_);
  chair_->insert(cone_empty_);

  // Obstacle estimate and its covariance ellipse (body frame).
  obstacle_ = CSetOfObjects::Create();
  auto dot = CSphere::Create(0.06f, 12);
  dot->setColor_u8(0, 190, 0);
  obstacle_->insert(dot);
  chair_->insert(obstacle_);
  auto ell = CEllipsoid2D::Create();
  ell->setQuantiles(1.0f);
  ell->setColor_u8(0, 200, 220);
  ell->setLineWidth(3.0f);
  ellipse_ = ell;
  chair_->insert(ellipse_);
  ellipse_ribbon_ = CSetOfTriangles::Create();
  ellipse_ribbon_->setColor_u8(mrpt::img::TColor(0, 200, 220));
  ellipse_ribbon_->enableLight(false);
  chair_->insert(ellipse_ribbon_);
  scene_->insert(chair_);

  legend_.emplace_back("obstacle estimate, 1-sigma ellipse", Color{0, 170, 190});
  if (d.truth && !d.truth->obstacles.empty())
    legend_.emplace_back("true obstacles", Color{220, 30, 30});
  legend_.emplace_back("sonar cone (current reading)", Color{230, 110, 0});
  setTime(d.t0_s);
}

void DriveScene::view(double& cx, double& cy, double& zoom) const {
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const auto& [v, t] : d_.trajectories)
    for (const auto& s : t)
      x0 = std::min(x0, s.x_m), x1 = std::max(x1, s.x_m), y0 = std::min(y0, s.y_m),
      y1 = std::max(y1, s.y_m);
  if (d_.truth)
    for (const auto& o : d_.truth->obstacles)
      x0 = std::min(x0, o.x_m), x1 = std::max(x1, o.x_m), y0 = std::min(y0, o.y_m),
      y1 = std::max(y1, o.y_m);
  if (x0 > x1) x0 = y0 = -1, x1 = y1 = 1;
  cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
  zoom = std::max(4.0, 1.3 * std::max(x1 - x0, y1 - y0) + 2.0);
}

void DriveScene::setupCamera(CCamera& cam) const {
  double cx, cy, zoom;
  view(cx, cy, zoom);
  cam.setPointingAt(static_cast<float>(cx), static_cast<float>(cy), 0.f);
  cam.setZoomDistance(static_cast<float>(zoom));
  cam.setElevationDegrees(60.f);
  cam.setAzimuthDegrees(-90.f);
}

void DriveScene::setStatus(const std::string& s) {
  status_ = s;
  updateText();
}

void DriveScene::setTime(double t) {
  t_ = std::clamp(t, d_.t0_s, std::max(d_.t0_s, d_.t1_s));
  const auto* e = d_.ekfAt(t_);
  if (e) chair_->setPose(mrpt::poses::CPose3D(e->x(2), e->x(3), 0.0, e->x(4), 0, 0));
  // Sonar reading at or before t (held for one period).
  double reading = 0;
  bool have = false;
  for (const auto& s : d_.rec.sonar)
    if (s.t_s <= t_ && s.t_s >= t_ - 1.5 / std::max(1.0, d_.cfg.sonar.rate_hz))
      reading = s.range_m, have = true;
  const bool valid = have && reading > 0;
  cone_->setVisibility(valid);
  cone_empty_->setVisibility(!valid);
  if (valid) cone_->setScale(static_cast<float>(reading));
  const bool obs = e && e->obstacle_initialised;
  obstacle_->setVisibility(obs);
  ellipse_->setVisibility(obs);
  if (obs) {
    obstacle_->setLocation(e->x(5), e->x(6), 0.06);
    mrpt::math::CMatrixDouble22 C;
    C(0, 0) = e->P(5, 5), C(0, 1) = e->P(5, 6), C(1, 0) = e->P(6, 5), C(1, 1) = e->P(6, 6);
    auto ell = std::dynamic_pointer_cast<CEllipsoid2D>(ellipse_);
    ell->setCovMatrix(C);
    ell->setLocation(e->x(5), e->x(6), 0.07);
    fillRibbon(*ellipse_ribbon_,
               covarianceEllipse(e->x(5), e->x(6), C(0, 0), C(0, 1), C(1, 1), 1.0, 72), 0.03, 0.08,
               true);
  }
  ellipse_ribbon_->setVisibility(obs);
  updateText();
}

void DriveScene::updateText() {
  auto vp = scene_->getViewport("main");
  vp->clearTextMessages();
  TFontParams fp;
  fp.vfont_name = "sans";
  fp.vfont_scale = 14;
  size_t id = 0;
  double y = 0.95;
  for (const auto& [label, c] : legend_) {
    fp.color = tcolor(c);
    vp->addTextMessage(0.01, y, "--- " + label, id++, fp);
    y -= 0.04;
  }
  fp.color = mrpt::img::TColorf(0.1f, 0.1f, 0.1f);
  const auto* e = d_.ekfAt(t_);
  std::string line = fmt::format("t = {:.2f} s", t_);
  if (e) {
    line += fmt::format("   v = {:.2f} m/s   omega = {:.2f} rad/s", e->x(0), e->x(1));
    if (e->obstacle_initialised)
      line += fmt::format("   d_o = {:.2f} +- {:.2f} m", e->obstacle_distance_m,
                          e->obstacle_distance_sd_m);
  }
  vp->addTextMessage(0.01, 0.02, line, id++, fp);
  if (!status_.empty()) vp->addTextMessage(0.01, 0.06, status_, id++, fp);
}

bool renderSnapshot(const DriveScene& s, const std::string& png, int w, int h, std::string* why) {
  mrpt::img::CImage im;
  try {
    CFBORender render(static_cast<unsigned>(w), static_cast<unsigned>(h));
    s.setupCamera(render.getCamera(*s.scene()));
    render.render_RGB(*s.scene(), im);
  } catch (const std::exception& e) {
    if (why) *why = "offscreen OpenGL rendering failed: " + util::oneLineMessage(e.what());
    return false;
  }
  saveImage(im, png);  // a write failure is an error, not a skipped figure
  return true;
}

}  // namespace wheelchair::visualization
