// memory_footprint: peak resident memory of the `wheelchair` commands against the length of
// the drive (issue 13, "Memory grows with the drive"; docs/benchmarks.md, "Memory").
//
// For each duration D (s) it simulates an `excite` drive (seed 1) into a rawlog and runs
//   simulate  --scenario excite --duration D -o drive.rawlog
//   filter    drive.rawlog --estimates e.csv --trajectory t.tum --variants
//   evaluate  drive.rawlog -j 1 --csv m.csv
//   diagnose  drive.rawlog --json d.json
//   identify  drive.rawlog --json i.json
//   report    drive.rawlog -o DIR --no-3d
// each as a child process, its peak RSS (ru_maxrss from wait4, kB -> MB) printed as a table.
// With two or more durations it also prints the growth per recorded hour,
//   (RSS(D_max) - RSS(D_min)) / (D_max - D_min) * 3600   [MB/h],
// the slope that decides whether a ten-hour drive fits: RSS(10 h) ~ RSS(D) + slope * (10 h - D).
// --check-growth LIMITS exits 1 if a command's slope exceeds its limit: one number for every
// command or CMD=MB_PER_H,... (a check on growth, not on an absolute figure: the ~120 MB of
// mapped libraries cancel out).
//
// Usage:
//   memory_footprint --cli build/bin/wheelchair --durations 3600,36000 [--keep DIR]
//   memory_footprint --cli build/bin/wheelchair --durations 300,600
//       --check-growth simulate=40,filter=40,evaluate=60,diagnose=200
//   memory_footprint --cli build/bin/wheelchair --durations 3600 --commands diagnose
// --commands LIST measures only those commands (simulate always runs: it makes the drive, and
// is measured only when listed).
// Exit: 0 ok, 1 a command failed or the growth check failed, 2 usage.
#include <fmt/core.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace {

struct Run {
  bool ok = false;
  double rss_mb = 0;
};

// Runs argv with stdout/stderr to `log`; peak RSS of that child alone (wait4).
Run runMeasured(const std::vector<std::string>& argv, const std::string& log) {
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  std::fflush(stdout);  // the child must not inherit (and repeat) buffered output
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid < 0) return {};
  if (pid == 0) {
    if (!freopen(log.c_str(), "w", stdout) || !freopen(log.c_str(), "a", stderr)) _exit(127);
    execv(args[0], args.data());
    _exit(127);
  }
  int status = 0;
  rusage ru{};
  if (wait4(pid, &status, 0, &ru) != pid) return {};
  Run r;
  r.ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
  r.rss_mb = static_cast<double>(ru.ru_maxrss) / 1024.0;  // Linux: kB
  return r;
}

std::vector<double> parseList(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) v.push_back(std::stod(item));
  return v;
}

// "300" (every command) or "filter=150,evaluate=200,..." (MB per recorded hour).
std::map<std::string, double> parseLimits(const std::string& text) {
  std::map<std::string, double> m;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    const auto eq = item.find('=');
    const std::string name = eq == std::string::npos ? "" : item.substr(0, eq);
    const double v = std::stod(eq == std::string::npos ? item : item.substr(eq + 1));
    if (!(v > 0)) throw std::invalid_argument("growth limits must be positive: " + item);
    m[name] = v;
  }
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  std::string cli, keep;
  std::vector<double> durations{300, 600};
  const std::vector<std::string> all_commands{"simulate", "filter",   "evaluate",
                                              "diagnose", "identify", "report"};
  std::vector<std::string> commands = all_commands;
  std::map<std::string, double> limits;  // MB per recorded hour, per command ("" = all)
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto value = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "--cli")
        cli = value();
      else if (a == "--durations")
        durations = parseList(value());
      else if (a == "--check-growth")
        limits = parseLimits(value());
      else if (a == "--keep")
        keep = value();
      else if (a == "--commands") {
        commands.clear();
        std::stringstream ss(value());
        for (std::string c; std::getline(ss, c, ',');) {
          if (std::find(all_commands.begin(), all_commands.end(), c) == all_commands.end())
            throw std::invalid_argument("--commands: unknown command " + c);
          commands.push_back(c);
        }
        if (commands.empty()) throw std::invalid_argument("--commands needs at least one");
      } else
        throw std::invalid_argument("unknown option " + a);
    }
    if (cli.empty()) throw std::invalid_argument("--cli PATH (the wheelchair program) is required");
    if (durations.empty()) throw std::invalid_argument("--durations needs at least one value");
    for (double d : durations)
      if (!(d > 0)) throw std::invalid_argument("durations must be positive");
  } catch (const std::exception& e) {
    fmt::print(stderr, "memory_footprint: {}\n", e.what());
    return 2;
  }
  namespace fs = std::filesystem;
  const fs::path dir =
      keep.empty() ? fs::temp_directory_path() / ("wc_memory_footprint_" + std::to_string(getpid()))
                   : fs::path(keep);
  fs::create_directories(dir);
  std::map<std::string, std::vector<double>> rss;  // per command, per duration
  bool failed = false;
  fmt::print("{:>10}", "duration_s");
  for (const auto& c : commands) fmt::print(" {:>10}", c);
  fmt::print("   (peak RSS, MB)\n");
  for (double d : durations) {
    const std::string tag = fmt::format("d{:.0f}", d);
    const std::string rawlog = (dir / (tag + ".rawlog")).string();
    auto p = [&](const std::string& name) { return (dir / (tag + name)).string(); };
    const std::map<std::string, std::vector<std::string>> argvs{
        {"simulate",
         {cli, "simulate", "--scenario", "excite", "--seed", "1", "--duration",
          fmt::format("{}", d), "-o", rawlog}},
        {"filter",
         {cli, "filter", rawlog, "--no-progress", "--estimates", p(".csv"), "--trajectory",
          p(".tum"), "--variants"}},
        {"evaluate", {cli, "evaluate", rawlog, "-j", "1", "-q", "--csv", p("_metrics.csv")}},
        {"diagnose", {cli, "diagnose", rawlog, "--json", p("_diagnosis.json")}},
        {"identify", {cli, "identify", rawlog, "--json", p("_identify.json")}},
        {"report", {cli, "report", rawlog, "-o", p("_report"), "--no-3d"}}};
    fmt::print("{:>10.0f}", d);
    const bool measure_simulate =
        std::find(commands.begin(), commands.end(), "simulate") != commands.end();
    if (!measure_simulate && !runMeasured(argvs.at("simulate"), p("_simulate.log")).ok) {
      failed = true;
      fmt::print(stderr, "\nmemory_footprint: simulate failed on the {} s drive (log: {})\n", d,
                 p("_simulate.log"));
    }
    for (const auto& c : commands) {
      const Run r = runMeasured(argvs.at(c), p("_" + c + ".log"));
      if (!r.ok) {
        failed = true;
        fmt::print(stderr, "\nmemory_footprint: {} failed on the {} s drive (log: {})\n", c, d,
                   p("_" + c + ".log"));
      }
      rss[c].push_back(r.rss_mb);
      fmt::print(" {:>10.1f}", r.rss_mb);
      std::fflush(stdout);
    }
    fmt::print("\n");
  }
  bool growth_failed = false;
  if (durations.size() >= 2) {
    const double d0 = durations.front(), d1 = durations.back();
    fmt::print("{:>10}", "MB/h");
    std::string verdicts;
    for (const auto& c : commands) {
      const double slope = (rss[c].back() - rss[c].front()) / (d1 - d0) * 3600.0;
      fmt::print(" {:>10.1f}", slope);
      const auto it = limits.count(c) ? limits.find(c) : limits.find("");
      if (it == limits.end()) continue;
      const bool over = slope > it->second;
      growth_failed |= over;
      verdicts += fmt::format(" {} {:.0f} {} {:.0f};", c, slope, over ? ">" : "<=", it->second);
    }
    fmt::print("   (growth per recorded hour, {:.0f} s -> {:.0f} s)\n", d0, d1);
    if (!limits.empty())
      fmt::print("growth check (MB/h):{} {}\n", verdicts, growth_failed ? "FAILED" : "ok");
  }
  if (keep.empty()) {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  return failed || growth_failed ? 1 : 0;
}
