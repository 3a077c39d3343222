#include "libwheelchair/estimation/EstimateWriters.h"

#include "libwheelchair/util/NumberFormat.h"

#include <fmt/compile.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iterator>

namespace wheelchair::estimation {

namespace {
// Rows between checks of the stream: a full disk stops a long run within ~1 MB of output.
constexpr std::size_t kCheckEvery = 4096;

void put(std::ostream& os, const char* data, std::size_t size) {
  os.write(data, static_cast<std::streamsize>(size));
}
void put(std::ostream& os, const fmt::memory_buffer& buf) {
  put(os, buf.data(), buf.size());
}
}  // namespace

EstimatesCsvWriter::EstimatesCsvWriter(const std::string& path) : file_(path), buf_(kBufferBytes) {
  file_.stream()
      << "t_s,v_m_s,omega_rad_s,x_m,y_m,phi_rad,obstacle_x_m,obstacle_y_m,obstacle_distance_m,"
         "sd_v_m_s,sd_omega_rad_s,sd_x_m,sd_y_m,sd_phi_rad,sd_obstacle_x_m,sd_obstacle_y_m,"
         "sd_obstacle_distance_m\n";
  file_.check();
}

char* writeEstimateRow(char* p, const EstimateSample& e) {
  // t: fmt's "{:.6f}" characters (util::writeFixed6); the rest 10 significant digits
  // (util::write10Significant: a third fewer characters and cheaper digits than the shortest
  // round-trip form; docs/benchmarks.md, "Tenth round").
  p = util::writeFixed6(p, e.t_s);
  const auto num = [&p](double v) {
    *p++ = ',';
    p = util::write10Significant(p, v);
  };
  for (int i = 0; i < 7; ++i) num(e.x(i));
  num(e.obstacle_distance_m);
  for (int i = 0; i < 7; ++i) num(e.sd(i));
  num(e.obstacle_distance_sd_m);
  *p++ = '\n';
  return p;
}

void EstimatesCsvWriter::add(const EstimateSample& e) {
  // Rows go to the file's stream in blocks of ~256 kB (written without a copy: AtomicFile).
  if (kBufferBytes - used_ < kMaxEstimateRowChars) flushBuffer();
  char* const start = buf_.data() + used_;
  used_ += static_cast<std::size_t>(writeEstimateRow(start, e) - start);
  ++rows_;
}

void EstimatesCsvWriter::flushBuffer() {
  put(file_.stream(), buf_.data(), used_);
  used_ = 0;
  file_.check();  // a full disk stops a long run within one block of output
}

void EstimatesCsvWriter::commit() {
  flushBuffer();
  file_.commit();
}

void writeCommandDrivenCsv(const std::string& path, const std::vector<CommandDrivenEstimate>& est) {
  util::AtomicFile file(path);
  std::ostream& os = file.stream();
  os << "t_s,x_m,y_m,phi_rad,v_m_s,omega_rad_s,sd_x_m,sd_y_m,sd_phi_rad,sd_v_m_s,sd_omega_rad_s,"
        "cov_xy_m2\n";
  auto sd = [](double var) { return std::sqrt(std::max(var, 0.0)); };
  std::size_t rows = 0;
  for (const auto& e : est) {
    fmt::memory_buffer buf;
    fmt::format_to(std::back_inserter(buf), "{:.6f},{},{},{},{},{},{},{},{},{},{},{}\n", e.t_s,
                   e.x_m, e.y_m, e.phi_rad, e.v_m_s, e.omega_rad_s, sd(e.var_x), sd(e.var_y),
                   sd(e.var_phi), sd(e.var_v), sd(e.var_omega), e.cov_xy);
    put(os, buf);
    if (++rows % kCheckEvery == 0) file.check();
  }
  file.commit();
}

}  // namespace wheelchair::estimation
