// The --alignment option of the commands that print trajectory metrics (evaluate, report).
#pragma once

#include "Command.h"

#include "libwheelchair/evaluation/Batch.h"

#include <iostream>
#include <string>

namespace wheelchair::cli {

/// evaluation::parseAlignment for command `command`: false, with the reason on one line on
/// stderr ("wheelchair COMMAND: ..."), when `text` is not none | origin | se2 | se2-first:S
/// (the command then exits kExitUsage).
inline bool parseAlignmentFor(const char* command, const std::string& text,
                              evaluation::MetricOptions& metrics) {
  try {
    evaluation::parseAlignment(text, metrics);
    return true;
  } catch (const std::invalid_argument& e) {
    std::cerr << "wheelchair " << command << ": " << e.what() << "\n";
    return false;
  }
}

}  // namespace wheelchair::cli
