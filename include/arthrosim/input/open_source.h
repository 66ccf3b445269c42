#pragma once
// One entry point for the CLI: picks the input source from a spec string.
#include <memory>
#include <optional>
#include <string>

#include "arthrosim/input/input_source.h"
#include "arthrosim/input/script_source.h"
#include "arthrosim/input/session.h"

namespace arthrosim::input {

struct SourceOptions {
  double dt_s = 0.02;                 ///< simulation step, s (Model::options.dt_s)
  std::optional<std::uint64_t> seed;  ///< script noise seed
  double noise_scale = 0;             ///< script trainee noise (0 = expert)
  SessionOptions session;             ///< recorded-session checks
  std::string record_path;            ///< if set, record applied frames as session CSV
  bool realtime = true;               ///< live server: pace Frame to wall time
  IgtlDeviceNames igtl_devices;       ///< live server: TRANSFORM names mapped to devices
};

/// Adds one live-input device mapping "NAME=TARGET" (TARGET slot0, slot1, scope or ignore; NAME
/// the TRANSFORM device name, 1 to 20 printable characters, no '=') to *names. Throws InputError
/// ("--igtl-device: ...") for a bad target or name, or a name already mapped elsewhere.
void AddIgtlDeviceName(const std::string& spec, IgtlDeviceNames* names);

/// "none" -> IdleSource; *.csv, *.h5, *.hdf5 -> RecordedSource; *.yaml, *.yml -> ScriptSource;
/// "igtl" or "igtl:PORT" or "igtl:ADDRESS:PORT" -> IgtlServer (if built with OpenIGTLink).
/// Throws InputError for a bad spec or bad file. Warnings of recorded sessions go to *warnings.
std::unique_ptr<InputSource> OpenInputSource(const std::string& spec, const Model& model,
                                             const SourceOptions& options,
                                             std::vector<std::string>* warnings = nullptr);

}  // namespace arthrosim::input
