// wheelchair export FILE.rawlog -o DIR : rawlog -> plain-text recording directory.
#include "Command.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/TextFormat.h"

#include <fmt/core.h>

#include <iostream>

namespace wheelchair::cli {
namespace {

struct ExportOptions {
  std::string input, output;
  bool salvage = false;
};

int runExport(const ExportOptions& o) {
  io::RawlogReader in(o.input);
  io::TextRecordingWriter out(o.output);
  mrpt::serialization::CSerializable::Ptr obj;
  std::size_t n = 0, ignored = 0;
  std::map<std::string, std::string> meta;
  while (in.next(obj)) {
    auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj);
    if (auto text = io::headerText(*obj)) {
      meta = io::headerMeta(*text);
      continue;
    }
    const auto s = obs ? io::fromObservation(*obs) : std::nullopt;
    if (!s) {
      ++ignored;
      continue;
    }
    out.write(*s);
    ++n;
  }
  if (in.error())
    std::cerr << "wheelchair export: warning: "
              << io::salvageOrThrow(o.input, *in.error(), n, o.salvage) << "\n";
  out.setMeta(meta);
  out.commit();
  fmt::print("exported {} observations from {} into {}", n, o.input, o.output);
  if (ignored) fmt::print(" ({} records of other sensors not exported)", ignored);
  fmt::print("\n");
  return kExitOk;
}

const RegisterCommand reg{
    Command{"export", "Write a rawlog back as a plain-text recording directory",
            [](CLI::App& sub) -> std::function<int()> {
              auto o = std::make_shared<ExportOptions>();
              sub.add_option("input", o->input, "Input rawlog")->required();
              sub.add_option("-o,--output", o->output, "Output recording directory")->required();
              sub.add_flag("--salvage", o->salvage, kSalvageHelp);
              return [o] { return runExport(*o); };
            }}};

}  // namespace
}  // namespace wheelchair::cli
