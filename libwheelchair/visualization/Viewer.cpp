#include "libwheelchair/visualization/Viewer.h"

#include "libwheelchair/visualization/Plot.h"

#include "libwheelchair/visualization/Scene3D.h"

#include <mrpt/gui/CDisplayWindow3D.h>
#include <mrpt/gui/keycodes.h>
#include <mrpt/img/CImage.h>

#include <fmt/core.h>

#include <chrono>
#include <cstdlib>
#include <thread>

namespace wheelchair::visualization {
namespace {

// A grabbed frame that is one flat colour is a failed read-back.
bool blank(const mrpt::img::CImage& im) {
  if (im.getWidth() == 0 || im.getHeight() == 0) return true;
  const uint8_t* first = im.ptrLine<uint8_t>(0);
  const std::size_t ch = im.isColor() ? 3 : 1;
  for (unsigned y = 0; y < im.getHeight(); y += 3) {
    const uint8_t* row = im.ptrLine<uint8_t>(y);
    for (unsigned x = 0; x < im.getWidth() * ch; ++x)
      if (row[x] != first[x % ch]) return false;
  }
  return true;
}

void setCamera(mrpt::gui::CDisplayWindow3D& win, const DriveScene& s) {
  double cx, cy, zoom;
  s.view(cx, cy, zoom);
  win.setCameraPointingToPoint(static_cast<float>(cx), static_cast<float>(cy), 0.f);
  win.setCameraZoom(static_cast<float>(zoom));
  win.setCameraElevationDeg(60.f);
  win.setCameraAzimuthDeg(-90.f);
}

// Shows the scene in the window (the window keeps its own copy of the pointer).
void showScene(mrpt::gui::CDisplayWindow3D& win, mrpt::opengl::COpenGLScene::Ptr scene) {
  auto& sc = win.get3DSceneAndLock();
  sc = std::move(scene);
  win.unlockAccess3DScene();
}

// Opens a window on the scene and grabs its framebuffer until it is not blank or the timeout
// passes; null (or a blank image) when that failed.
mrpt::img::CImage::Ptr grabWindow(const DriveData& d, const DriveScene& scene,
                                  const ViewerOptions& o) {
  using namespace std::chrono;
  mrpt::img::CImage::Ptr grabbed;
  mrpt::gui::CDisplayWindow3D win("wheelchair view: " + d.path, o.width, o.height);
  showScene(win, scene.scene());
  setCamera(win, scene);
  win.captureImagesStart();
  const auto deadline = steady_clock::now() + duration<double>(o.window_grab_timeout_s);
  while (steady_clock::now() < deadline) {
    win.forceRepaint();
    std::this_thread::sleep_for(milliseconds(100));
    grabbed = win.getLastWindowImagePtr();
    if (grabbed && !blank(*grabbed)) break;
  }
  win.captureImagesStop();
  // Give the window its own scene back before it closes (the GUI thread may render it).
  showScene(win, mrpt::opengl::COpenGLScene::Create());
  return grabbed;
}

// --screenshot: the window's framebuffer when there is a display and it reads back, else an
// offscreen rendering.
ViewerResult screenshot(const DriveData& d, const DriveScene& scene, const ViewerOptions& o) {
  ViewerResult res;
  if (displayAvailable()) {
    const mrpt::img::CImage::Ptr grabbed = grabWindow(d, scene, o);
    if (grabbed && !blank(*grabbed)) {
      saveImage(*grabbed, o.screenshot);  // checked; throws naming the file on failure
      res.ok = true;
      res.method = "window";
      res.message = "saved the window's framebuffer";
      return res;
    }
    res.message = "the window's framebuffer read back blank; rendered offscreen instead";
  }
  std::string why;
  if (renderSnapshot(scene, o.screenshot, o.width, o.height, &why)) {
    res.ok = true;
    res.method = "offscreen";
    if (res.message.empty()) res.message = "no display: rendered offscreen (CFBORender)";
  } else {
    res.message = why;
  }
  return res;
}

// Playback state of the interactive viewer.
struct Playback {
  bool playing = false;
  double speed = 1, t_s = 0;
};

// Applies one key to the playback; false for a quit key.
bool applyKey(int k, Playback& pb, const DriveData& d) {
  const double step = pb.playing ? 2.0 : 0.5;
  switch (k) {
    case ' ':
      pb.playing = !pb.playing;
      break;
    case mrpt::gui::MRPTK_RIGHT:
      pb.t_s += step;
      break;
    case mrpt::gui::MRPTK_LEFT:
      pb.t_s -= step;
      break;
    case mrpt::gui::MRPTK_UP:
      pb.t_s += 10;
      break;
    case mrpt::gui::MRPTK_DOWN:
      pb.t_s -= 10;
      break;
    case '+':
    case mrpt::gui::MRPTK_ADD:
    case mrpt::gui::MRPTK_NUMPAD_ADD:
      pb.speed = std::min(64.0, pb.speed * 2);
      break;
    case '-':
    case mrpt::gui::MRPTK_SUBTRACT:
    case mrpt::gui::MRPTK_NUMPAD_SUBTRACT:
      pb.speed = std::max(1.0 / 16, pb.speed / 2);
      break;
    case mrpt::gui::MRPTK_HOME:
      pb.t_s = d.t0_s;
      break;
    case mrpt::gui::MRPTK_END:
      pb.t_s = d.t1_s;
      break;
    case 'q':
    case 'Q':
    case mrpt::gui::MRPTK_ESCAPE:
      return false;
    default:
      break;
  }
  return true;
}

// The interactive window: keys move the time, playback advances it in real time x speed.
ViewerResult interactive(const DriveData& d, DriveScene& scene, const ViewerOptions& o,
                         double t_start) {
  using namespace std::chrono;
  ViewerResult res;
  if (!displayAvailable()) {
    res.message = "no display (DISPLAY is not set); use --screenshot for a headless image";
    return res;
  }
  mrpt::gui::CDisplayWindow3D win("wheelchair view: " + d.path, o.width, o.height);
  showScene(win, scene.scene());
  setCamera(win, scene);
  Playback pb;
  pb.speed = o.speed, pb.t_s = t_start;
  auto last = steady_clock::now();
  auto status = [&] {
    return fmt::format(
        "[{}] speed x{:g}   space: play/pause  <- ->: step  up/down: +-10 s  +/-: speed  "
        "Home/End  q: quit",
        pb.playing ? "playing" : "paused", pb.speed);
  };
  {
    win.get3DSceneAndLock();
    scene.setStatus(status());
    win.unlockAccess3DScene();
  }
  win.repaint();
  while (win.isOpen()) {
    bool changed = false;
    if (win.keyHit()) {
      mrpt::gui::mrptKeyModifier mod;
      if (!applyKey(win.getPushedKey(&mod), pb, d)) {
        win.setWindowTitle("closing");
        res.ok = true;
        return res;
      }
      changed = true;
    }
    const auto now = steady_clock::now();
    const double dt = duration<double>(now - last).count();
    last = now;
    if (pb.playing) {
      pb.t_s += dt * pb.speed;
      if (pb.t_s >= d.t1_s) pb.t_s = d.t1_s, pb.playing = false;
      changed = true;
    }
    pb.t_s = std::clamp(pb.t_s, d.t0_s, d.t1_s);
    if (changed) {
      win.get3DSceneAndLock();
      scene.setTime(pb.t_s);
      scene.setStatus(status());
      win.unlockAccess3DScene();
      win.repaint();
    }
    std::this_thread::sleep_for(milliseconds(30));
  }
  res.ok = true;
  return res;
}

}  // namespace

bool displayAvailable() {
  const char* d = std::getenv("DISPLAY");
  return d && *d;
}

ViewerResult runViewer(const DriveData& d, const ViewerOptions& o) {
  DriveScene scene(d);
  const bool shot = !o.screenshot.empty();
  const double t_start =
      std::isfinite(o.at_s) ? d.t0_s + o.at_s : (shot ? defaultObstacleTime(d) : d.t0_s);
  scene.setTime(t_start);
  return shot ? screenshot(d, scene, o) : interactive(d, scene, o, t_start);
}

}  // namespace wheelchair::visualization
