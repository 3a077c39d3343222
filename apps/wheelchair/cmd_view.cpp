// wheelchair view FILE.rawlog [--config F] [--truth T.json] [--screenshot OUT.png --at T]
// Interactive 3-D viewer of a drive (libwheelchair/visualization/Viewer.h): trajectories of
// Fig. 5, the chair moving along the EKF path, obstacle estimate with its covariance ellipse,
// sonar cone. Space play/pause, arrows step/seek, +/- speed, q quit. --screenshot saves one
// frame (at --at seconds since the start) and exits; works without a display (offscreen).
#include "Command.h"
#include "FullProgram.h"

#include "libwheelchair/io/RawlogIO.h"

#include "libwheelchair/config/WheelchairConfig.h"
#include "libwheelchair/visualization/Viewer.h"

#include <fmt/core.h>

#include <iostream>
#include <memory>

namespace wheelchair::cli {
namespace {

struct ViewCliOptions {
  std::string file, config_path, truth, screenshot;
  double at_s = NAN, speed = 1.0;
  int width = 1200, height = 800;
  bool salvage = false;
};

int runView(const ViewCliOptions& o) {
  const auto cfg = o.config_path.empty() ? config::WheelchairConfig()
                                         : config::WheelchairConfig::load(o.config_path);
  const auto d = visualization::loadDrive(readRawlogFor("view", o.file, o.salvage), o.file, cfg,
                                          evaluation::MetricOptions{}, o.truth);
  visualization::ViewerOptions vo;
  vo.screenshot = o.screenshot;
  vo.at_s = o.at_s;
  vo.width = o.width;
  vo.height = o.height;
  vo.speed = o.speed;
  const auto r = visualization::runViewer(d, vo);
  if (!r.ok) {
    std::cerr << "wheelchair view: " << r.message << "\n";
    return kExitBadInput;
  }
  if (!o.screenshot.empty()) fmt::print("wrote {} ({}: {})\n", o.screenshot, r.method, r.message);
  return kExitOk;
}

const RegisterCommand reg{Command{
    "view", fullOnlyDescription("view"), [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<ViewCliOptions>();
      sub.add_option("file", o->file, "Rawlog recording")->required();
      sub.add_option("--config", o->config_path, "Configuration INI (default: nominal vehicle)");
      sub.add_option("--truth", o->truth,
                     "Simulator truth JSON (default FILE.truth.json if present)");
      sub.add_option("--screenshot", o->screenshot, "Save one frame as PNG and exit");
      sub.add_option("--at", o->at_s, "Time of the frame, s since the start of the drive");
      sub.add_option("--width", o->width, "Window width (px)")->default_val(1200);
      sub.add_option("--height", o->height, "Window height (px)")->default_val(800);
      sub.add_option("--speed", o->speed, "Initial playback speed")->default_val(1.0);
      sub.add_flag("--salvage", o->salvage, kSalvageHelp);
      return [o] { return runView(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
