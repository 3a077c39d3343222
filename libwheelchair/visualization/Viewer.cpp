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

}  // namespace

bool displayAvailable() {
  const char* d = std::getenv("DISPLAY");
  return d && *d;
}

ViewerResult runViewer(const DriveData& d, const ViewerOptions& o) {
  using namespace std::chrono;
  ViewerResult res;
  DriveScene scene(d);
  const bool shot = !o.screenshot.empty();
  const double t_start =
      std::isfinite(o.at_s) ? d.t0_s + o.at_s : (shot ? defaultObstacleTime(d) : d.t0_s);
  scene.setTime(t_start);

  if (shot) {
    if (displayAvailable()) {
      // Try the real window's framebuffer first.
      mrpt::img::CImage::Ptr grabbed;
      {
        mrpt::gui::CDisplayWindow3D win("wheelchair view: " + d.path, o.width, o.height);
        {
          auto& sc = win.get3DSceneAndLock();
          sc = scene.scene();
          win.unlockAccess3DScene();
        }
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
        {
          auto& sc = win.get3DSceneAndLock();
          sc = mrpt::opengl::COpenGLScene::Create();
          win.unlockAccess3DScene();
        }
      }
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

  if (!displayAvailable()) {
    res.message = "no display (DISPLAY is not set); use --screenshot for a headless image";
    return res;
  }
  mrpt::gui::CDisplayWindow3D win("wheelchair view: " + d.path, o.width, o.height);
  {
    auto& sc = win.get3DSceneAndLock();
    sc = scene.scene();
    win.unlockAccess3DScene();
  }
  setCamera(win, scene);
  bool playing = false;
  double speed = o.speed, t = t_start;
  auto last = steady_clock::now();
  auto status = [&] {
    return fmt::format(
        "[{}] speed x{:g}   space: play/pause  <- ->: step  up/down: +-10 s  +/-: speed  "
        "Home/End  q: quit",
        playing ? "playing" : "paused", speed);
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
      const int k = win.getPushedKey(&mod);
      const double step = playing ? 2.0 : 0.5;
      switch (k) {
        case ' ':
          playing = !playing;
          break;
        case mrpt::gui::MRPTK_RIGHT:
          t += step;
          break;
        case mrpt::gui::MRPTK_LEFT:
          t -= step;
          break;
        case mrpt::gui::MRPTK_UP:
          t += 10;
          break;
        case mrpt::gui::MRPTK_DOWN:
          t -= 10;
          break;
        case '+':
        case mrpt::gui::MRPTK_ADD:
        case mrpt::gui::MRPTK_NUMPAD_ADD:
          speed = std::min(64.0, speed * 2);
          break;
        case '-':
        case mrpt::gui::MRPTK_SUBTRACT:
        case mrpt::gui::MRPTK_NUMPAD_SUBTRACT:
          speed = std::max(1.0 / 16, speed / 2);
          break;
        case mrpt::gui::MRPTK_HOME:
          t = d.t0_s;
          break;
        case mrpt::gui::MRPTK_END:
          t = d.t1_s;
          break;
        case 'q':
        case 'Q':
        case mrpt::gui::MRPTK_ESCAPE:
          win.setWindowTitle("closing");
          res.ok = true;
          return res;
        default:
          break;
      }
      changed = true;
    }
    const auto now = steady_clock::now();
    const double dt = duration<double>(now - last).count();
    last = now;
    if (playing) {
      t += dt * speed;
      if (t >= d.t1_s) t = d.t1_s, playing = false;
      changed = true;
    }
    t = std::clamp(t, d.t0_s, d.t1_s);
    if (changed) {
      win.get3DSceneAndLock();
      scene.setTime(t);
      scene.setStatus(status());
      win.unlockAccess3DScene();
      win.repaint();
    }
    std::this_thread::sleep_for(milliseconds(30));
  }
  res.ok = true;
  return res;
}

}  // namespace wheelchair::visualization
