#include "libwheelchair/estimation/EstimateWriters.h"

#include <fmt/compile.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iterator>

namespace wheelchair::estimation {

namespace {
// Rows between checks of the stream: a full disk stops a long run within ~1 MB of output.
constexpr std::size_t kCheckEvery = 4096;

void put(std::ostream& os, const fmt::memory_buffer& buf) {
  os.write(buf.data(), static_cast<std::streamsize>(buf.size()));
}
}  // namespace

EstimatesCsvWriter::EstimatesCsvWriter(const std::string& path) : file_(path) {
  file_.stream()
      << "t_s,v_m_s,omega_rad_s,x_m,y_m,phi_rad,obstacle_x_m,obstacle_y_m,obstacle_distance_m,"
         "sd_v_m_s,sd_omega_rad_s,sd_x_m,sd_y_m,sd_phi_rad,sd_obstacle_x_m,sd_obstacle_y_m,"
         "sd_obstacle_distance_m\n";
  file_.check();
}

void EstimatesCsvWriter::add(const EstimateSample& e) {
  const auto& x = e.x;
  const auto& sd = e.sd;
  // A compiled format (no parsing per row) into a stack buffer: the row costs the 17 number
  // conversions and one write into the file's buffer.
  fmt::memory_buffer buf;
  fmt::format_to(std::back_inserter(buf),
                 FMT_COMPILE("{:.6f},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n"), e.t_s,
                 x(0), x(1), x(2), x(3), x(4), x(5), x(6), e.obstacle_distance_m, sd(0), sd(1),
                 sd(2), sd(3), sd(4), sd(5), sd(6), e.obstacle_distance_sd_m);
  put(file_.stream(), buf);
  if (++rows_ % kCheckEvery == 0) file_.check();
}

void EstimatesCsvWriter::commit() {
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
