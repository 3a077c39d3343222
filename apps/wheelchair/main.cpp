// `wheelchair`: command-line front end of libwheelchair. Dispatches to the registered
// subcommands (cmd_*.cpp); turns exceptions into the documented exit codes.
#include "Command.h"
#include "libwheelchair/config/Options.h"

#include <fmt/core.h>

#include <algorithm>
#include <exception>
#include <iostream>
#include <map>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>

#include <sys/resource.h>
#include <unistd.h>

namespace wheelchair::cli {
std::vector<Command>& commandRegistry() {
  static std::vector<Command> registry;
  return registry;
}
}  // namespace wheelchair::cli

namespace {
// The example that ends every subcommand's --help: run from the repository root, on the bundled
// recordings (datasets/, docs/recording-format.md). Each line works as given (tests/cli runs
// those that need no hardware or display).
const std::map<std::string, std::string>& examples() {
  static const std::string imp = "wheelchair import datasets/three_task_faulty -o faulty.rawlog";
  static const std::map<std::string, std::string> ex{
      {"capture",
       "wheelchair capture -c config/capture.ini -o drive.rawlog --duration 60   (needs the "
       "serial sensors of config/capture.ini; see replay-serial to test without them)"},
      {"diagnose", imp + " && wheelchair diagnose faulty.rawlog --json diagnosis.json"},
      {"evaluate", imp + " && wheelchair evaluate faulty.rawlog --markdown metrics.md"},
      {"export", imp + " && wheelchair export faulty.rawlog -o faulty_csv"},
      {"filter", imp + " && wheelchair filter faulty.rawlog --trajectory ekf.tum --variants"},
      {"identify",
       "wheelchair import datasets/excite -o excite.rawlog && wheelchair identify excite.rawlog "
       "--json identification.json"},
      {"import", imp},
      {"info", imp + " && wheelchair info faulty.rawlog"},
      {"replay-serial",
       "wheelchair replay-serial datasets/three_task_faulty -c config/capture.ini --link-dir "
       "/tmp/wc-ptys --write-config replay.ini   (then capture with -c replay.ini)"},
      {"report", imp + " && wheelchair report faulty.rawlog -o report --no-3d --truth "
                       "datasets/three_task_faulty.truth.json"},
      {"simulate",
       "wheelchair simulate --scenario three_task --effect encoder_scale:side=left,scale=0.95 "
       "-o sim.rawlog"},
      {"view", imp + " && wheelchair view faulty.rawlog --screenshot frame.png --at 10   (needs a "
                     "display)"},
  };
  return ex;
}

// The command named on the command line when it runs in another program (Command::runs_in,
// FullProgram.h): the first argument that is not an option (the program's own options,
// --lenient, --help and --version, take no value), or nullptr.
const wheelchair::cli::Command* runsElsewhere(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (argv[i][0] == '-') continue;
    for (const auto& c : wheelchair::cli::commandRegistry())
      if (c.name == argv[i]) return c.runs_in.empty() ? nullptr : &c;
    return nullptr;
  }
  return nullptr;
}

// Replaces this process by `c.runs_in` from this program's directory, with the same
// arguments; returns (exit code 1, one line) only if it cannot be started.
int runInOtherProgram(const wheelchair::cli::Command& c, char** argv) {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  const std::string path =
      ((ec ? std::filesystem::path(argv[0]) : self).parent_path() / c.runs_in).string();
  execv(path.c_str(), argv);
  const int err = errno;
  std::cerr << "wheelchair " << c.name << ": error: cannot run " << path << ": "
            << std::strerror(err) << " (" << c.name << " is in " << c.runs_in
            << ", built with wheelchair)\n";
  return wheelchair::cli::kExitBadInput;
}

// A corrupt rawlog can hold a nonsense container length that MRPT's deserializer would try to
// allocate (and zero) in full. Capping the address space turns that into std::bad_alloc,
// which the readers report as a corrupt record, instead of the OOM killer ending the process.
void capAddressSpace() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page <= 0) return;
  const rlim_t cap = std::min<rlim_t>(static_cast<rlim_t>(pages) * page / 2, rlim_t{16} << 30);
  rlimit rl{};
  if (getrlimit(RLIMIT_AS, &rl) == 0 && (rl.rlim_cur == RLIM_INFINITY || rl.rlim_cur > cap)) {
    rl.rlim_cur = cap;
    setrlimit(RLIMIT_AS, &rl);
  }
}
}  // namespace

int main(int argc, char** argv) {
  using namespace wheelchair::cli;
  if (const Command* other = runsElsewhere(argc, argv)) return runInOtherProgram(*other, argv);
  capAddressSpace();
  // A file-size limit (ulimit -f) must be an I/O error like a full disk (write(2) fails with
  // EFBIG and every writer reports it), not a silent kill by SIGXFSZ.
  std::signal(SIGXFSZ, SIG_IGN);
  CLI::App app{
      "wheelchair: localization and model checking for a semi-autonomous power wheelchair"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "libwheelchair 0.1.0");
  app.option_defaults()->always_capture_default();  // --help shows every option's default
  bool lenient = false;
  app.add_flag("--lenient", lenient,
               "Configuration files: unknown sections/keys and an empty file only warn "
               "(for files written by older versions); by default they are errors");
  app.fallthrough();  // --lenient is accepted after the subcommand name too
  // Every module with an options table is linked into both programs (FullProgram.h; tests/cli
  // compares their `config --dump`), so every table has registered itself (config/Options.h):
  // a section no table knows is a typo, not a module left out.
  wheelchair::config::setAllSectionsRegistered(true);

  auto& registry = commandRegistry();
  std::sort(registry.begin(), registry.end(),
            [](const Command& a, const Command& b) { return a.name < b.name; });
  std::map<CLI::App*, std::function<int()>> actions;
  for (const auto& cmd : registry) {
    CLI::App* sub = app.add_subcommand(cmd.name, cmd.description);
    actions[sub] = cmd.setup(*sub);
    const auto ex = examples().find(cmd.name);
    sub->footer("Example (from the repository root):\n  " +
                (ex != examples().end() ? ex->second : "wheelchair " + cmd.name + " --help"));
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? kExitOk : kExitUsage;
  }

  wheelchair::config::setLenient(lenient);
  for (auto& [sub, action] : actions) {
    if (sub->parsed()) {
      try {
        return action();
      } catch (const std::exception& e) {
        std::cerr << "wheelchair " << sub->get_name() << ": error: " << e.what() << "\n";
        return kExitBadInput;
      }
    }
  }
  return kExitUsage;
}
