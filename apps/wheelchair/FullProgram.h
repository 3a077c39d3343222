// The two programs of the command line (apps/CMakeLists.txt, docs/benchmarks.md "Seventh round").
//
// `wheelchair-full` has every command. `wheelchair` (the program users run) has the same
// commands but links only what the data commands need (filter, evaluate, simulate, import, ...):
// the commands below need MRPT's GUI/3-D/hardware-driver modules or OpenCV's image codecs,
// whose ~160 further shared libraries cost ~0.1 s of dynamic loading at every start, so
// `wheelchair` runs `wheelchair-full` (from its own directory, same arguments, same process:
// exec) for them. Their names and one-line descriptions are kept here once, for both programs'
// --help.
//
// Example: `wheelchair view d.rawlog` execs `<dir of wheelchair>/wheelchair-full view d.rawlog`.
#pragma once

#include <cstring>

namespace wheelchair::cli {

/// File name of the complete program, built next to `wheelchair`.
constexpr const char* kFullProgram = "wheelchair-full";

struct FullOnlyCommand {
  const char* name;
  const char* description;
};

/// The commands `wheelchair` runs in kFullProgram (and nothing else does).
constexpr FullOnlyCommand kFullOnlyCommands[] = {
    {"capture",
     "Record the wheelchair's sensors (serial devices, SPI counters) into a rawlog, live"},
    {"diagnose",
     "Find the physics the model leaves out: locate, name, fit and validate model extensions"},
    {"replay-serial",
     "Play a recording into pseudo-terminals in the capture sources' line formats (no hardware)"},
    {"report", "Figures like the paper's Fig. 5-8 (PNG, headless) and index.md for a recording"},
    {"view", "3-D viewer of a drive: trajectories, chair, obstacle estimate, sonar (MRPT window)"},
};

/// Description of the full-only command `name` (nullptr if it is not one).
inline const char* fullOnlyDescription(const char* name) {
  for (const auto& c : kFullOnlyCommands)
    if (std::strcmp(c.name, name) == 0) return c.description;
  return nullptr;
}

}  // namespace wheelchair::cli
