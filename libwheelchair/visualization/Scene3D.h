// The 3-D scene of a drive (MRPT opengl), shared by `wheelchair view` (interactive
// CDisplayWindow3D) and the offscreen snapshots (CFBORender, EGL: no display needed):
//
//   ground grid (1 m), trajectories of Fig. 5 in distinct colours (encoders blue,
//   encoders + gyro green, EKF black, baseline purple, ground truth red points, simulated
//   truth dark red), the chair's footprint at the current time (EKF pose) with its wheels, the
//   sonar cone (a fan of the current reading's length; grey outline at the maximum range when
//   the reading is 0), the obstacle estimate (green) with its 1-sigma covariance ellipse (cyan,
//   CEllipsoid2D), the true obstacles when simulated (red cylinders), and a legend / status
//   text in the viewport (rendered in the window and offscreen alike).
//
// Example:
//   DriveScene s(drive);  s.setTime(12.0);
//   std::string why;  renderSnapshot(s, "x.png", 1000, 700, &why);
#pragma once

#include "libwheelchair/visualization/DriveData.h"
#include "libwheelchair/visualization/Plot.h"

#include <mrpt/opengl/COpenGLScene.h>
#include <mrpt/opengl/CSetOfObjects.h>
#include <mrpt/opengl/CSetOfTriangles.h>

#include <string>

namespace mrpt::opengl {
class CCamera;
}

namespace wheelchair::visualization {

/// Colours of the variants (also used by the report figures).
Color variantColor(const std::string& variant);
/// Display label of a variant ("EKF", "encoders only", ...).
std::string variantLabel(const std::string& variant);

class DriveScene {
 public:
  explicit DriveScene(const DriveData& d);

  mrpt::opengl::COpenGLScene::Ptr scene() const { return scene_; }
  /// Moves the chair, sonar and obstacle to time t (clamped to the drive); updates the text.
  void setTime(double t_s);
  double time() const { return t_; }
  double startTime() const { return d_.t0_s; }
  double endTime() const { return d_.t1_s; }
  /// A status line shown below the legend (e.g. "playing x2").
  void setStatus(const std::string& s);
  /// Points the camera at the whole drive, looking down at an angle.
  void setupCamera(mrpt::opengl::CCamera& cam) const;
  /// Centre of the drive and a zoom distance that shows it all.
  void view(double& cx, double& cy, double& zoom) const;

 private:
  void updateText();
  const DriveData& d_;
  mrpt::opengl::COpenGLScene::Ptr scene_;
  mrpt::opengl::CSetOfObjects::Ptr chair_, cone_, cone_empty_, obstacle_;
  mrpt::opengl::CRenderizable::Ptr ellipse_, reading_;
  mrpt::opengl::CSetOfTriangles::Ptr ellipse_ribbon_;
  double t_ = 0;
  std::string status_;
  std::vector<std::pair<std::string, Color>> legend_;
};

/// Renders the scene offscreen (CFBORender) into a PNG of w x h. Returns false (and the reason
/// in `why`) when no OpenGL context can be created; throws if the PNG cannot be written.
bool renderSnapshot(const DriveScene& s, const std::string& png, int w, int h, std::string* why);

}  // namespace wheelchair::visualization
