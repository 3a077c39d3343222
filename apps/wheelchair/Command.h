// Subcommand registry of the `wheelchair` program.
//
// Each subcommand lives in its own cmd_<name>.cpp and registers itself with a static
// `RegisterCommand` object; main.cpp only dispatches. Exit codes are shared by all:
// 0 success, 1 bad input (file content, I/O), 2 usage error (command line).
#pragma once

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RawlogStream.h"

#include <iostream>

#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <vector>

namespace wheelchair::cli {

constexpr int kExitOk = 0;
constexpr int kExitBadInput = 1;
constexpr int kExitUsage = 2;

/// Help text of the `--salvage` flag of every command that reads rawlogs (docs/rawlog-mapping.md).
constexpr const char* kSalvageHelp =
    "Damaged rawlog: use every complete record before the break (a warning says where and why "
    "it broke) instead of refusing the file";

/// Reads a rawlog for command `command` (io::readRawlogSalvaging): a damaged file is refused
/// with one line, or with `salvage` read up to the break with a warning on stderr
/// ("wheelchair COMMAND: warning: ...").
inline io::Recording readRawlogFor(const char* command, const std::string& path, bool salvage,
                                   io::RawlogReadReport* report = nullptr) {
  std::string warning;
  io::Recording rec = io::readRawlogSalvaging(path, salvage, &warning, report);
  if (!warning.empty()) std::cerr << "wheelchair " << command << ": warning: " << warning << "\n";
  return rec;
}

/// readRawlogFor's rule for a rawlog read as a stream: its summary (io::scanRawlogSalvaging),
/// a damaged file refused with one line, or with `salvage` a warning on stderr.
inline io::RecordingSummary scanRawlogFor(const char* command, const std::string& path,
                                          bool salvage) {
  std::string warning;
  io::RecordingSummary sum = io::scanRawlogSalvaging(path, salvage, &warning);
  if (!warning.empty()) std::cerr << "wheelchair " << command << ": warning: " << warning << "\n";
  return sum;
}

struct Command {
  std::string name;
  std::string description;
  // Adds the subcommand's options to `sub`; returns the action run after parsing.
  std::function<std::function<int()>(CLI::App& sub)> setup;
  // Non-empty: the command runs in this other program of the same directory, started with the
  // same arguments before any parsing (FullProgram.h); `setup` then only lists it in --help.
  std::string runs_in = {};
};

std::vector<Command>& commandRegistry();

struct RegisterCommand {
  explicit RegisterCommand(Command c) { commandRegistry().push_back(std::move(c)); }
};

}  // namespace wheelchair::cli
