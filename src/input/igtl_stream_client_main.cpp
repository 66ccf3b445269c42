// igtl_stream_client: streams a recorded session (CSV or HDF5) to arthrosim's OpenIGTLink
// server over loopback, as a haptic-device bridge would, and prints the forces it gets back.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <fstream>

#include "arthrosim/core/error.h"
#include "arthrosim/input/igtl_client.h"

int main(int argc, char** argv) {
  using namespace arthrosim::input;
  CLI::App app{"Stream a recorded arthrosim session to an OpenIGTLink server"};
  std::string file, forces_out;
  StreamClientOptions o;
  app.add_option("session", file, "session file (.csv, .h5)")->required();
  app.add_option("--host", o.host, "server address")->capture_default_str();
  app.add_option("--port", o.port, "server port")->capture_default_str();
  app.add_option("--speed", o.speed, "playback speed (1 = real time, 0 = as fast as possible)")
      ->capture_default_str();
  app.add_option("--linger", o.linger_s, "seconds to keep reading forces after the last sample")
      ->capture_default_str();
  app.add_option("--forces", forces_out, "write received forces as CSV (t,slot,fx,fy,fz in N)");
  bool no_end = false;
  app.add_flag("--no-end", no_end, "do not send 'session end' when done");
  CLI11_PARSE(app, argc, argv);
  o.send_end = !no_end;
  try {
    const SessionTable table = ReadSession(file);
    for (const std::string& w : table.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
    const StreamResult r = StreamSession(table, o);
    std::printf("sent %llu messages, received %zu force messages\n",
                static_cast<unsigned long long>(r.messages_sent), r.forces.size());
    if (!forces_out.empty()) {
      std::ofstream out(forces_out);
      out << "t,slot,fx,fy,fz\n";
      for (const ForceSample& f : r.forces) {
        out << fmt::format("{:.17g},{},{:.17g},{:.17g},{:.17g}\n", f.t_s, f.slot, f.force_n.x(),
                           f.force_n.y(), f.force_n.z());
      }
    }
  } catch (const arthrosim::InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
