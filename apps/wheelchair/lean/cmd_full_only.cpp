// `wheelchair` (the lean program, apps/CMakeLists.txt): the commands that need MRPT's GUI/3-D,
// hardware drivers or OpenCV's image codecs are listed here and run in `wheelchair-full`
// (FullProgram.h): main.cpp execs it with the same arguments before parsing, so their options,
// help, messages and exit codes are exactly the full program's.
#include "../Command.h"
#include "../FullProgram.h"

namespace wheelchair::cli {
namespace {

const bool kRegistered = [] {
  for (const auto& c : kFullOnlyCommands)
    RegisterCommand{Command{c.name, c.description,
                            [](CLI::App& sub) -> std::function<int()> {
                              sub.allow_extras();
                              return [] { return kExitUsage; };  // never parsed (main.cpp)
                            },
                            kFullProgram}};
  return true;
}();

}  // namespace
}  // namespace wheelchair::cli
