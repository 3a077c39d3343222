// Interactive 3-D viewer of a drive (`wheelchair view`): an MRPT CDisplayWindow3D showing
// the DriveScene (Scene3D.h) with playback.
//
// Keys: space play/pause; right/left arrow step +-0.5 s (paused) or seek +-2 s (playing);
// up/down seek +-10 s; + / - playback speed x2 / /2; Home / End jump to the start / end;
// q or Esc quit. The mouse rotates (left drag), pans (right drag) and zooms (wheel) as in any
// MRPT 3-D window.
//
// Screenshot mode (ViewerOptions::screenshot): the scene is set to `at_s` and saved as PNG, then
// the function returns. When a display is available the window is opened and its framebuffer
// grabbed; if that grab fails or comes back blank (e.g. Xvfb with Mesa, where the wx GL
// canvas reads back black), the same scene is rendered offscreen with CFBORender (EGL) at the
// window size instead. ViewerResult says which was used.
#pragma once

#include "libwheelchair/visualization/DriveData.h"

#include <cmath>
#include <string>

namespace wheelchair::visualization {

struct ViewerOptions {
  std::string screenshot;  ///< "" = interactive
  double at_s = NAN;       ///< time since the start of the drive; NaN = start (interactive) or
                           ///< defaultObstacleTime (screenshot)
  int width = 1200, height = 800;
  double speed = 1.0;  ///< initial playback speed
  double window_grab_timeout_s = 3.0;
};

struct ViewerResult {
  bool ok = false;
  std::string method;  ///< "window" or "offscreen"
  std::string message;
};

/// True when an X display is configured (DISPLAY set).
bool displayAvailable();

ViewerResult runViewer(const DriveData& d, const ViewerOptions& o);

}  // namespace wheelchair::visualization
