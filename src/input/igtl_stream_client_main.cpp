// igtl_stream_client: streams a recorded session (CSV or HDF5) to arthrosim's OpenIGTLink
// server over loopback, as a haptic-device bridge would, and prints the forces and the live
// feedback notices (STRING messages) it gets back.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <fstream>

#include "arthrosim/core/error.h"
#include "arthrosim/input/igtl_client.h"

int main(int argc, char** argv) {
  using namespace arthrosim::input;
  CLI::App app{"Stream a recorded arthrosim session to an OpenIGTLink server"};
  std::string file, forces_out, notices_out;
  StreamClientOptions o;
  app.add_option("session", file, "session file (.csv, .h5)")->required();
  app.add_option("--host", o.host, "server address")->capture_default_str();
  app.add_option("--port", o.port, "server port")->capture_default_str();
  app.add_option("--speed", o.speed, "playback speed (1 = real time, 0 = as fast as possible)")
      ->capture_default_str();
  app.add_option(
         "--linger", o.linger_s,
         "seconds to keep reading forces and notices after the last sample (less if the server "
         "closes first)")
      ->capture_default_str();
  app.add_option("--forces", forces_out, "write received forces as CSV (t,slot,fx,fy,fz in N)");
  app.add_option("--notices", notices_out,
                 "write received notices (live feedback) as text: t<TAB>device<TAB>text per line");
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
    for (const NoticeSample& n : r.notices) std::printf("%s\n", n.text.c_str());
    if (!notices_out.empty()) {
      std::ofstream out(notices_out);
      for (const NoticeSample& n : r.notices)
        out << fmt::format("{:.17g}\t{}\t{}\n", n.t_s, n.device, n.text);
    }
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
