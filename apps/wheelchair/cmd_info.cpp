// wheelchair info FILE.rawlog [--json] : per-stream counts, rates, gaps, timestamp health.
#include "Command.h"

#include "libwheelchair/io/RawlogIO.h"
#include "libwheelchair/io/RecordingStats.h"

#include <fmt/core.h>
#include <mrpt/core/Clock.h>

#include <iostream>

namespace wheelchair::cli {
namespace {

struct InfoOptions {
  std::string input;
  bool json = false;
};

int runInfo(const InfoOptions& o) {
  io::RawlogReader in(o.input);
  io::RecordingStats stats;
  mrpt::serialization::CSerializable::Ptr obj;
  std::size_t non_observations = 0;
  while (in.next(obj)) {
    auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj);
    if (!obs) {
      ++non_observations;
      continue;
    }
    // MRPT does not serialize a comment's label: name our header record explicitly.
    const std::string label = io::headerText(*obs) ? "META" : obs->sensorLabel;
    stats.add(label, obs->GetRuntimeClass()->className,
              mrpt::Clock::toDouble(obs->timestamp));
  }
  if (o.json) {
    auto j = stats.toJson();
    j["file"] = o.input;
    j["non_observation_records"] = non_observations;
    if (in.error()) j["broken"] = io::describeBreak(o.input, *in.error());
    std::cout << j.dump(2) << "\n";
  } else {
    fmt::print("{}\n{}", o.input, stats.toText());
    if (non_observations) fmt::print("{} records are not observations\n", non_observations);
  }
  if (in.error()) {
    std::cerr << "wheelchair info: error: " << io::describeBreak(o.input, *in.error())
              << " (statistics above cover the " << in.recordsRead() << " complete records)\n";
    return kExitBadInput;
  }
  return kExitOk;
}

const RegisterCommand reg{Command{
    "info", "Per-stream summary of a rawlog: counts, rates, gaps, timestamp order",
    [](CLI::App& sub) -> std::function<int()> {
      auto o = std::make_shared<InfoOptions>();
      sub.add_option("input", o->input, "Input rawlog")->required();
      sub.add_flag("--json", o->json, "Machine-readable output");
      return [o] { return runInfo(*o); };
    }}};

}  // namespace
}  // namespace wheelchair::cli
