#include "arthrosim/input/open_source.h"

#include <stdexcept>

#include "arthrosim/core/error.h"
#include "arthrosim/input/recorded_source.h"
#include "arthrosim/input/recorder.h"
#ifdef ARTHROSIM_HAVE_OPENIGTLINK
#include "arthrosim/input/igtl_server.h"
#endif

namespace arthrosim::input {
namespace {

bool EndsWith(const std::string& s, const std::string& e) {
  return s.size() >= e.size() && s.compare(s.size() - e.size(), e.size(), e) == 0;
}

std::unique_ptr<InputSource> OpenRaw(const std::string& spec, const Model& model,
                                     const SourceOptions& o, std::vector<std::string>* warnings) {
  if (spec == "none") return std::make_unique<IdleSource>(model);
  if (EndsWith(spec, ".csv") || EndsWith(spec, ".h5") || EndsWith(spec, ".hdf5")) {
    auto src = RecordedSource::Open(spec, model, o.dt_s, o.session);
    if (warnings != nullptr)
      warnings->insert(warnings->end(), src->warnings().begin(), src->warnings().end());
    return src;
  }
  if (EndsWith(spec, ".yaml") || EndsWith(spec, ".yml")) {
    ScriptOptions so;
    so.dt_s = o.dt_s;
    so.seed = o.seed;
    so.noise_scale = o.noise_scale;
    return ScriptSource::Open(spec, model, so);
  }
  if (spec == "igtl" || spec.rfind("igtl:", 0) == 0) {
#ifdef ARTHROSIM_HAVE_OPENIGTLINK
    IgtlServerOptions io;
    io.realtime = o.realtime;
    io.device_names = o.igtl_devices;
    const std::string rest = spec.size() > 5 ? spec.substr(5) : "";
    const std::size_t colon = rest.rfind(':');
    try {
      if (colon != std::string::npos) {
        io.bind_address = rest.substr(0, colon);
        io.port = std::stoi(rest.substr(colon + 1));
      } else if (!rest.empty()) {
        io.port = std::stoi(rest);
      }
    } catch (const std::exception&) {
      throw InputError("", 0, "input",
                       "bad live input spec '" + spec + "'; expected igtl[:ADDRESS][:PORT]");
    }
    return std::make_unique<IgtlServer>(model, io);
#else
    throw InputError("", 0, "input", "this build has no OpenIGTLink: live input unavailable");
#endif
  }
  throw InputError(
      spec, 0, "input",
      "unknown input; expected none, a session (.csv/.h5), a script (.yaml) or igtl[:PORT]");
}

}  // namespace

void AddIgtlDeviceName(const std::string& spec, IgtlDeviceNames* names) {
  auto fail = [&](const std::string& why) {
    throw InputError("--igtl-device", 0, "", "'" + spec + "': " + why);
  };
  const std::size_t eq = spec.find('=');
  if (eq == std::string::npos) fail("expected NAME=slot0|slot1|scope|ignore");
  const std::string name = spec.substr(0, eq), target = spec.substr(eq + 1);
  if (name.empty() || name.size() > 20) fail("the device name must have 1 to 20 characters");
  for (const char c : name) {
    if (c < 0x21 || c > 0x7e) fail("the device name must be printable ASCII without spaces");
  }
  std::optional<Device> dev;
  if (target != "ignore") {
    dev = ParseDevice(target);
    if (!dev || target == "camera")
      fail("unknown target '" + target + "' (slot0, slot1, scope, ignore)");
  }
  const auto [it, added] = names->try_emplace(name, dev);
  if (!added && it->second != dev) fail("'" + name + "' is already mapped to another target");
}

std::unique_ptr<InputSource> OpenInputSource(const std::string& spec, const Model& model,
                                             const SourceOptions& options,
                                             std::vector<std::string>* warnings) {
  std::unique_ptr<InputSource> src = OpenRaw(spec, model, options, warnings);
  if (!options.record_path.empty()) {
    src = std::make_unique<RecordingSource>(std::move(src), options.record_path, model);
  }
  return src;
}

}  // namespace arthrosim::input
