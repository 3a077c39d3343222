#include "libwheelchair/capture/CaptureSession.h"

#include "libwheelchair/capture/HostClock.h"
#include "libwheelchair/config/Options.h"

#include <fmt/format.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/obs/CObservationComment.h>
#include <mrpt/system/datetime.h>

#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <thread>

namespace fs = std::filesystem;

namespace wheelchair::capture {

namespace {

std::string isoTime(double t) {
  return mrpt::system::dateTimeToString(mrpt::Clock::fromDouble(t)) + " UTC";
}

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument(fmt::format("{}: cannot open configuration file", path));
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

CaptureSession::CaptureSession(CaptureOptions opt) : opt_(std::move(opt)) {
  ini_text_ = readText(opt_.config_path);
  const config::IniFile ini(ini_text_, opt_.config_path);
  const std::string g = "capture";
  // [capture]: the session's keys, one table (config/Options.h): strict numbers and ranges,
  // unknown keys are errors naming file, line and key.
  std::string vc_key, log_opt;
  config::Options session(g, "capture session (docs/capture.md)");
  session
      .text("vehicle_config", vc_key,
            "vehicle configuration, relative to this file; empty: nominal")
      .real("reorder_window_s", window_s_, "reorder window (s)", config::Range::between(0, 10))
      .real("flush_period_s", out_opt_.flush_period_s,
            "complete gzip member at least this often (s)", config::Range{0, 1, true, false})
      .integer("compression_level", out_opt_.compression_level, "gzip level",
               config::Range::between(0, 9))
      .flag("fsync", out_opt_.fsync, "fsync after every flush")
      .real("status_period_s", status_period_s_, "live status period (s)", config::Range::above(0))
      .text("log_file", log_opt, "event log; empty = OUTPUT.log, none = off");
  session.checkUnknownKeys(ini);
  try {
    session.load(ini);
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(e.what());
  }
  // Sections: [capture], [recording] (free-form) and the sources (a `driver` key).
  for (const auto& e : ini.entries())
    if (e.key.empty() && e.section != g && e.section != "recording" &&
        ini.read_string(e.section, "driver", "", false).empty())
      throw std::invalid_argument(fmt::format(
          "{}:{}: [{}]: unknown section (not [capture], [recording] or a source with `driver`)",
          ini.origin(), e.line, e.section));
  // Vehicle configuration: sensor geometry for the observations, recorded in the header.
  std::string vc = opt_.vehicle_config;
  if (vc.empty()) {
    vc = vc_key;
    if (!vc.empty() && fs::path(vc).is_relative())
      vc = (fs::path(opt_.config_path).parent_path() / vc).string();
  }
  try {
    vehicle_ = vc.empty() ? config::WheelchairConfig() : config::WheelchairConfig::load(vc);
  } catch (const std::exception& e) {
    throw std::invalid_argument(e.what());
  }

  std::vector<std::string> keys;
  ini.getAllKeys("recording", keys);
  for (const auto& k : keys) recording_meta_[k] = ini.read_string("recording", k, "");

  // Sources: every section with a `driver` key (rawlog-grabber conventions).
  std::vector<std::string> sections;
  ini.getAllSections(sections);
  std::vector<int> rank;
  std::map<io::StreamKind, std::string> seen;
  for (const auto& sec : sections) {
    const std::string driver = ini.read_string(sec, "driver", "", false);
    if (driver.empty() || !ini.read_bool(sec, "enabled", true, false)) continue;
    auto src = createCaptureSource(driver);
    if (!src)
      throw std::invalid_argument(fmt::format(
          "[{}] driver = {}: unknown (ArduinoMotorsSensor, RazorImuSensor, PozyxSensor, "
          "SonarSensor, JoystickSensor, QuadratureCounterSensor)",
          sec, driver));
    src->setSection(sec);
    src->setVehicleConfig(vehicle_);
    try {
      src->loadConfig(ini, sec);
    } catch (const std::exception& e) {
      // MRPT wraps the driver's exception in its own report: use the driver's message.
      const std::string what = src->configError().empty() ? e.what() : src->configError();
      throw std::invalid_argument(fmt::format("{}: {}", opt_.config_path, what));
    }
    if (seen.count(src->kind()))
      throw std::invalid_argument(fmt::format("[{}] and [{}] both capture {}", seen[src->kind()],
                                              sec, io::streamLabel(src->kind())));
    seen[src->kind()] = sec;
    rank.push_back(static_cast<int>(src->kind()));
    sources_.push_back(std::move(src));
  }
  if (sources_.empty())
    throw std::invalid_argument(opt_.config_path + ": no source section (a section with `driver`)");
  merge_ = std::make_unique<MergeBuffer>(sources_.size(), rank, window_s_);
  last_records_.assign(sources_.size(), 0);
  rates_.assign(sources_.size(), 0.0);

  out_ = std::make_unique<RawlogAppender>(opt_.output, out_opt_, opt_.overwrite);
  log_path_ = log_opt == "none" ? "" : (log_opt.empty() ? opt_.output + ".log" : log_opt);
  if (!log_path_.empty()) log_.open(log_path_, std::ios::app);
  tty_ = opt_.status_out && isatty(fileno(opt_.status_out));
  live_ = opt_.status_out && (tty_ || opt_.verbose);
}

CaptureSession::~CaptureSession() {
  stop_threads_ = true;
  for (auto& s : sources_) s->shutdown();
}

std::vector<SourceStatus> CaptureSession::status() const {
  std::vector<SourceStatus> v;
  for (const auto& s : sources_) v.push_back(s->status());
  return v;
}

std::vector<CaptureEvent> CaptureSession::events() const {
  std::lock_guard lk(events_mtx_);
  return events_;
}

bool CaptureSession::captures(io::StreamKind k) const {
  return std::any_of(sources_.begin(), sources_.end(),
                     [k](const auto& s) { return s->kind() == k; });
}

std::size_t CaptureSession::lateRecords() const {
  std::size_t n = 0;
  for (std::size_t i = 0; i < sources_.size(); ++i) n += merge_->late(i);
  return n;
}

void CaptureSession::logLine(const std::string& text, bool to_terminal) {
  if (log_.is_open()) {
    log_ << isoTime(HostClock::now()) << "  " << text << "\n";
    log_.flush();
  }
  if (to_terminal && opt_.status_out) {
    clearStatus();
    std::fprintf(opt_.status_out, "%s\n", text.c_str());
    std::fflush(opt_.status_out);
  }
}

void CaptureSession::handleEvents() {
  for (auto& s : sources_) {
    for (auto& e : s->takeEvents()) {
      logLine(fmt::format("[{}] {}{}", e.source, e.error ? "error: " : "", e.text), live_);
      std::lock_guard lk(events_mtx_);
      events_.push_back(std::move(e));
    }
  }
}

void CaptureSession::clearStatus() {
  if (tty_ && status_lines_ > 0) {
    std::fprintf(opt_.status_out, "\x1b[%dF\x1b[J", status_lines_);
    status_lines_ = 0;
  }
}

void CaptureSession::printStatus(double mono, bool final_summary) {
  const double dt = mono - last_status_mono_;
  for (std::size_t i = 0; i < sources_.size(); ++i) {
    const auto st = sources_[i]->status();
    if (dt > 0) rates_[i] = (st.records - last_records_[i]) / dt;
    last_records_[i] = st.records;
  }
  last_status_mono_ = mono;
  if (!opt_.status_out || (!live_ && !final_summary)) return;
  std::string text = fmt::format(
      "capture {:.1f} s  written {} records ({:.1f} KiB, {} flushes)  buffered {}{}\n",
      mono - start_mono_, out_->recordsOnDisk(), out_->bytesOnDisk() / 1024.0, out_->members(),
      merge_->size() + out_->recordsPending(),
      final_summary ? "" : fmt::format("  last flush {:.1f} s ago", mono - out_->lastFlushMono()));
  for (std::size_t i = 0; i < sources_.size(); ++i) {
    const auto st = sources_[i]->status();
    text += fmt::format(
        "  {:<9}{:<6}{:>7.1f}/s  records {:<8} garbage {:<5} reconnects {:<3} gaps {:<3}{}\n",
        st.label, st.connected ? "ok" : "DOWN", final_summary ? 0.0 : rates_[i], st.records,
        st.garbage, st.connects > 0 ? st.connects - 1 : 0, st.gaps,
        st.connected ? st.device : "  " + st.last_error);
  }
  clearStatus();
  std::fputs(text.c_str(), opt_.status_out);
  std::fflush(opt_.status_out);
  if (tty_ && !final_summary)
    status_lines_ = static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

void CaptureSession::collect(double mono) {
  for (std::size_t i = 0; i < sources_.size(); ++i) {
    mrpt::hwdrivers::CGenericSensor::TListObservations lst;
    sources_[i]->getObservations(lst);
    for (auto& [ts, obj] : lst) {
      auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj);
      if (obs) merge_->push(i, std::move(obs), mono);
    }
  }
}

void CaptureSession::writeHeader(mrpt::Clock::time_point t) {
  auto c = mrpt::obs::CObservationComment::Create();
  c->timestamp = t;
  c->sensorLabel = "META";
  std::ostringstream ss;
  ss << "# libwheelchair recording\n[recording]\n";
  auto meta = recording_meta_;
  meta["source"] = "wheelchair capture";
  meta["capture_started"] = isoTime(HostClock::now() - (HostClock::monotonic() - start_mono_));
  meta["capture_config"] = fs::absolute(opt_.config_path).string();
  for (const auto& [k, v] : meta) ss << k << " = " << v << "\n";
  ss << "# configuration used when writing this file\n" << vehicle_.text();
  ss << "\n# capture configuration (" << opt_.config_path << ")\n";
  std::istringstream in(ini_text_);
  for (std::string line; std::getline(in, line);) ss << "#| " << line << "\n";
  c->text = ss.str();
  out_->write(*c);
  header_written_ = true;
}

void CaptureSession::writeObservation(const mrpt::obs::CObservation& obs) {
  if (!header_written_) writeHeader(obs.timestamp);
  out_->write(obs);
  ++records_written_;
  if (opt_.on_record) opt_.on_record(obs, [this](const std::string& s) { logLine(s, true); });
}

int CaptureSession::run(const std::atomic<bool>* stop) {
  start_mono_ = last_status_mono_ = HostClock::monotonic();
  logLine(fmt::format(
              "capture started: {} -> {} ({} sources, reorder window {} s, flush every {} s)",
              opt_.config_path, opt_.output, sources_.size(), window_s_, out_opt_.flush_period_s),
          false);
  for (auto& s : sources_) s->initialize();
  handleEvents();
  // The source threads; joined on every way out of run() (also an unexpected exception).
  struct Threads {
    std::atomic<bool>& stop;
    std::vector<std::thread> v;
    void joinAll() {
      stop = true;
      for (auto& t : v)
        if (t.joinable()) t.join();
      v.clear();
    }
    ~Threads() { joinAll(); }
  } threads{stop_threads_, {}};
  for (auto& s : sources_) {
    CaptureSource* src = s.get();
    threads.v.emplace_back([this, src] {
      while (!stop_threads_) {
        try {
          src->doProcess();
        } catch (const std::exception& e) {
          // A driver must not take the capture down: log, pause, go on.
          std::string what = e.what();
          if (const auto nl = what.find('\n'); nl != std::string::npos) what = what.substr(0, nl);
          src->logEvent("driver error: " + what, true);
          src->shutdown();
          std::this_thread::sleep_for(std::chrono::milliseconds(200));
        }
      }
    });
  }
  auto write = [this](std::size_t, const mrpt::obs::CObservation& o) { writeObservation(o); };
  int rc = 0;
  try {
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      const double mono = HostClock::monotonic();
      collect(mono);
      merge_->release(mono, false, write);
      out_->flushIfDue(mono);
      handleEvents();
      if (mono - last_status_mono_ >= status_period_s_) printStatus(mono, false);
      if (stop_requested_ || (stop && *stop) ||
          (opt_.duration_s > 0 && mono - start_mono_ >= opt_.duration_s))
        break;
    }
    threads.joinAll();
    for (auto& s : sources_) s->shutdown();
    const double mono = HostClock::monotonic();
    collect(mono);
    merge_->release(mono, true, write);
    if (!header_written_) writeHeader(HostClock::nowStamp());
    out_->close();
    handleEvents();
    logLine(fmt::format("capture stopped: {} records in {}", out_->recordsOnDisk(), opt_.output),
            false);
  } catch (const WriteError& e) {
    threads.joinAll();
    for (auto& s : sources_) s->shutdown();
    handleEvents();
    error_ = fmt::format(
        "{}; capture stopped. The file is intact up to the last flush: {} records "
        "({} bytes)",
        e.what(), out_->recordsOnDisk(), out_->bytesOnDisk());
    logLine("error: " + error_, false);
    rc = 1;
  }
  if (opt_.on_finish) opt_.on_finish([this](const std::string& s) { logLine(s, true); });
  printStatus(HostClock::monotonic(), true);
  return rc;
}

}  // namespace wheelchair::capture
