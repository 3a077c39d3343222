#include "libwheelchair/capture/SerialReplayer.h"

#include "libwheelchair/util/AtomicFile.h"

#include "libwheelchair/capture/HostClock.h"
#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/TextFormat.h"

#include <fmt/format.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>
#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace fs = std::filesystem;

namespace wheelchair::capture {

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// Driver name -> stream (the drivers of LineSensor.h / QuadratureCounterSensor.h).
std::optional<io::StreamKind> kindOfDriver(const std::string& d) {
  if (d == "ArduinoMotorsSensor") return io::StreamKind::Motors;
  if (d == "RazorImuSensor") return io::StreamKind::Imu;
  if (d == "PozyxSensor") return io::StreamKind::Pozyx;
  if (d == "SonarSensor") return io::StreamKind::Sonar;
  if (d == "JoystickSensor") return io::StreamKind::Joystick;
  if (d == "QuadratureCounterSensor") return io::StreamKind::Encoders;
  return std::nullopt;
}

}  // namespace

Outage parseOutage(const std::string& spec) {
  const auto at = spec.find('@');
  const auto plus = spec.find('+', at == std::string::npos ? 0 : at);
  if (at == std::string::npos || plus == std::string::npos || at == 0)
    throw std::invalid_argument("outage '" + spec + "': expected SOURCE@START+DURATION (seconds)");
  Outage o;
  o.source = spec.substr(0, at);
  const auto s = parseFiniteNumber(spec.substr(at + 1, plus - at - 1));
  const auto d = parseFiniteNumber(spec.substr(plus + 1));
  if (!s || !d || *s < 0 || *d <= 0)
    throw std::invalid_argument("outage '" + spec + "': START >= 0 and DURATION > 0 seconds");
  o.start_s = *s;
  o.duration_s = *d;
  return o;
}

struct SerialReplayer::Source {
  std::string section;
  io::StreamKind kind;
  std::optional<LineFormat> format;
  std::string link;
  int master = -1;
  std::vector<std::pair<double, double>> outages;  ///< absolute [begin, end) recording times
  bool unplugged = false;
  std::size_t since_garbage = 0, garbage_kind = 0;
  std::string last_line;
  ReplaySourceReport rep;
};

SerialReplayer::SerialReplayer(ReplayOptions opt) : opt_(std::move(opt)) {
  if (opt_.speed < 0) throw std::invalid_argument("--speed must be >= 0");
  if (opt_.link_dir.empty()) throw std::invalid_argument("a directory for the pty links is needed");
  std::ifstream in(opt_.capture_config, std::ios::binary);
  if (!in) throw std::invalid_argument(opt_.capture_config + ": cannot open");
  std::stringstream ss;
  ss << in.rdbuf();
  mrpt::config::CConfigFileMemory ini(ss.str());
  std::vector<std::string> sections;
  ini.getAllSections(sections);
  fs::create_directories(opt_.link_dir);
  for (const auto& sec : sections) {
    const std::string driver = ini.read_string(sec, "driver", "", false);
    if (driver.empty() || !ini.read_bool(sec, "enabled", true, false)) continue;
    const auto kind = kindOfDriver(driver);
    if (!kind) throw std::invalid_argument(fmt::format("[{}] driver = {}: unknown", sec, driver));
    auto s = std::make_unique<Source>();
    s->section = sec;
    s->kind = *kind;
    // The encoders' replay is always the serial fallback's format.
    s->format = LineFormat::fromConfig(ini, sec, *kind);
    if (!s->format->canFormat())
      throw std::invalid_argument(
          fmt::format("[{}] uses line_regex: set line_format to replay it", sec));
    if (!s->format->hasDeviceTime())
      throw std::invalid_argument(fmt::format(
          "[{}] line format '{}' has no {{t}} field: the replay needs it to carry the recording's "
          "timestamps",
          sec, s->format->describe()));
    s->link = (fs::absolute(opt_.link_dir) / sec).string();
    s->rep.section = sec;
    s->rep.label = io::streamLabel(*kind);
    s->rep.link = s->link;
    // Derived configuration for the capture side.
    ini.write(sec, "serial_port", s->link);
    ini.write(sec, "time_source", std::string("device"));
    if (*kind == io::StreamKind::Encoders) ini.write(sec, "interface", std::string("serial"));
    sources_.push_back(std::move(s));
  }
  if (sources_.empty()) throw std::invalid_argument(opt_.capture_config + ": no source sections");
  for (const auto& o : opt_.outages) {
    bool found = false;
    for (auto& s : sources_)
      if (lower(o.source) == lower(s->section) || lower(o.source) == lower(s->rep.label)) {
        s->outages.emplace_back(o.start_s, o.start_s + o.duration_s);  // relative until run()
        found = true;
      }
    if (!found) throw std::invalid_argument("outage of unknown source '" + o.source + "'");
  }
  const std::string vc = ini.read_string("capture", "vehicle_config", "", false);
  if (!vc.empty() && fs::path(vc).is_relative())
    ini.write("capture", "vehicle_config",
              fs::absolute(fs::path(opt_.capture_config).parent_path() / vc).string());
  derived_text_ = "# Written by `wheelchair replay-serial` from " + opt_.capture_config +
                  ": the sources read the replay's pseudo-terminals.\n" + ini.getContent();
}

SerialReplayer::~SerialReplayer() {
  close();
}

std::string SerialReplayer::linkPath(const std::string& section) const {
  for (const auto& s : sources_)
    if (s->section == section) return s->link;
  return {};
}

void SerialReplayer::openPty(Source& s) {
  const int m = posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (m < 0) throw std::runtime_error(std::string("posix_openpt: ") + std::strerror(errno));
  char name[128];
  if (grantpt(m) != 0 || unlockpt(m) != 0 || ptsname_r(m, name, sizeof name) != 0) {
    const int e = errno;
    ::close(m);
    throw std::runtime_error(std::string("pty setup: ") + std::strerror(e));
  }
  // Raw mode on the slave side (set through the master): no echo, no line editing, no
  // newline translation, whatever the reader does.
  termios t{};
  if (tcgetattr(m, &t) == 0) {
    cfmakeraw(&t);
    tcsetattr(m, TCSANOW, &t);
  }
  fcntl(m, F_SETFL, fcntl(m, F_GETFL) | O_NONBLOCK);
  // Stable name: an atomic rename of a fresh symlink over the link.
  const std::string tmp = s.link + ".new";
  ::unlink(tmp.c_str());
  if (::symlink(name, tmp.c_str()) != 0 || ::rename(tmp.c_str(), s.link.c_str()) != 0) {
    const int e = errno;
    ::close(m);
    throw std::runtime_error(fmt::format("link {} -> {}: {}", s.link, name, std::strerror(e)));
  }
  s.master = m;
  ++s.rep.ptys;
}

void SerialReplayer::closePty(Source& s, bool settle) {
  if (s.master < 0) return;
  // The device stops sending, then the cable is pulled: give the reader a moment to take
  // what is already in the pty (a hang-up discards unread input).
  if (settle) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ::unlink(s.link.c_str());
  ::close(s.master);
  s.master = -1;
}

void SerialReplayer::close() {
  for (auto& s : sources_) closePty(*s, false);
}

void SerialReplayer::setup() {
  for (auto& s : sources_) {
    const bool absent = std::any_of(s->outages.begin(), s->outages.end(),
                                    [](const auto& o) { return o.first <= 0; });
    if (!absent)
      openPty(*s);
    else
      ::unlink(s->link.c_str());
  }
  if (!opt_.derived_config.empty()) {
    util::writeFileAtomically(opt_.derived_config,
                              [&](std::ostream& out) { out << derived_text_; });
  }
}

bool SerialReplayer::writeLine(Source& s, const std::string& line) {
  std::size_t off = 0;
  const double start = HostClock::monotonic();
  while (off < line.size()) {
    const ssize_t k = ::write(s.master, line.data() + off, line.size() - off);
    if (k > 0) {
      off += static_cast<std::size_t>(k);
      continue;
    }
    if (k < 0 && errno != EAGAIN && errno != EINTR) return false;
    // Nobody reading: drop a line not yet begun after 0.2 s; finish one begun (a half line
    // would corrupt the next) unless the reader is gone for good (2 s).
    const double waited = HostClock::monotonic() - start;
    if ((off == 0 && waited > 0.2) || waited > 2.0) return false;
    pollfd p{s.master, POLLOUT, 0};
    ::poll(&p, 1, 10);
  }
  return true;
}

ReplayReport SerialReplayer::run(const std::atomic<bool>* stop) {
  // Stream the recording in time order.
  std::unique_ptr<io::TextRecordingReader> text;
  std::vector<io::AnySample> all;
  std::size_t next_all = 0;
  if (fs::is_directory(opt_.recording)) {
    text = std::make_unique<io::TextRecordingReader>(opt_.recording);
  } else {
    const auto rec = io::readRawlog(opt_.recording);
    io::forEachInTimeOrder(rec, [&](const io::AnySample& s) { all.push_back(s); });
  }
  auto next = [&](io::AnySample& s) {
    if (text) return text->next(s);
    if (next_all >= all.size()) return false;
    s = all[next_all++];
    return true;
  };
  std::vector<Source*> by_kind(io::kNumStreams, nullptr);
  for (auto& s : sources_) by_kind[static_cast<int>(s->kind)] = s.get();

  ReplayReport rep;
  if (opt_.start_delay_s > 0)
    std::this_thread::sleep_for(std::chrono::duration<double>(opt_.start_delay_s));
  const double mono0 = HostClock::monotonic();
  bool first = true;
  double t0 = 0;
  io::AnySample smp;
  while ((!stop || !*stop) && next(smp)) {
    const double t = io::timeOf(smp);
    if (first) {
      t0 = t;
      first = false;
      for (auto& s : sources_)
        for (auto& o : s->outages) o = {t0 + o.first, t0 + o.second};
    }
    if (opt_.speed > 0) {
      const double due = mono0 + (t - t0) / opt_.speed;
      const double wait = due - HostClock::monotonic();
      if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait));
    }
    // Outages that begin or end by now (any source).
    for (auto& s : sources_) {
      bool in = false;
      for (const auto& o : s->outages) in = in || (t >= o.first && t < o.second);
      if (in && s->master >= 0) {
        closePty(*s, true);
      } else if (!in && s->master < 0) {
        openPty(*s);
      }
    }
    Source* s = by_kind[static_cast<int>(io::kindOf(smp))];
    if (!s) {
      ++rep.no_source;
      continue;
    }
    if (s->master < 0) {
      ++s->rep.dropped_unplugged;
      s->rep.dropped_times.push_back(t);
      continue;
    }
    std::string line = s->format->format(smp, &s->rep.inexact) + "\n";
    if (writeLine(*s, line)) {
      ++s->rep.lines;
      s->last_line = line;
    } else {
      ++s->rep.dropped_overflow;
    }
    if (opt_.garbage_every > 0 && ++s->since_garbage >= opt_.garbage_every) {
      s->since_garbage = 0;
      std::string g;
      switch (s->garbage_kind++ % 4) {
        case 0:  // binary noise, as after a baud-rate mismatch or a brown-out
          for (int i = 0; i < 12; ++i) g.push_back(static_cast<char>(0x80 + (i * 37) % 0x7f));
          g += '\n';
          break;
        case 1: {  // a line cut short (reset mid-line): ends on a dangling separator
          const std::string body = s->last_line.substr(0, s->last_line.size() - 1);
          const auto cut = body.find_last_of(",; \t");
          g = (cut == std::string::npos ? std::string("1,") : body.substr(0, cut + 1)) + "\n";
          break;
        }
        case 2: {  // a field that is not a number: the second one replaced by "err"
          const std::string body = s->last_line.substr(0, s->last_line.size() - 1);
          const auto c1 = body.find(',');
          const auto c2 = c1 == std::string::npos ? c1 : body.find(',', c1 + 1);
          if (c1 == std::string::npos)
            g = body + ",err\n";
          else
            g = body.substr(0, c1 + 1) + "err" + (c2 == std::string::npos ? "" : body.substr(c2)) +
                "\n";
          break;
        }
        default:  // an overlong line (no end of line for a long time)
          g = std::string(3000, '7') + "\n";
          break;
      }
      if (writeLine(*s, g)) ++s->rep.garbage;
    }
  }
  rep.wall_s = HostClock::monotonic() - mono0;
  for (auto& s : sources_) rep.sources.push_back(s->rep);
  return rep;
}

}  // namespace wheelchair::capture
