// igtl_soak: drives `arthrosim serve` over loopback at 1 kHz for a while with a seeded mix of
// valid and bad OpenIGTLink traffic, and checks that the server survives it (issue #18):
//   bridge A  slot0 + scope TRANSFORMs and commands every ms, with bad messages mixed in (bad
//             CRC, truncated body, unsupported type, unknown device, out of order, bad command,
//             oversized, ignored names), sent split so the server always holds part of a message
//   bridge B  a second client from 10 % to 90 % of the run: slot1 through a mapped name
//             (StylusToTracker), and now and then a pose for A's slot0 (refused: owner)
//   churn     bursts of back-to-back connect/disconnect cycles (a valid command, a garbage
//             header, a message cut short by the disconnect), the last of each burst waiting for
//             its first force; once, one client too many
// It reads every force both bridges get (a step is answered when both slots' SENSOR arrive),
// counts each refusal kind in the server log against what it sent, times every connect, and
// samples the server's RSS (VmRSS) and CPU time each second. --check turns the bounds into the
// exit status (1 = a check failed, 2 = could not run). Linux only (/proc).
#include <fcntl.h>
#include <igtl_util.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "igtl_wire.h"

namespace {

using namespace arthrosim;
using namespace arthrosim::input;
using Clock = std::chrono::steady_clock;
using Bytes = std::vector<std::uint8_t>;

struct Args {
  std::string arthrosim, scene, dir;
  double duration_s = 20, dt_s = 0.001;
  int cycles = 50, burst = 10, max_clients = 4;
  std::uint64_t seed = 1;
  double bad_per_ms = 0.02;   // chance of a bad message per tick of bridge A
  double latency_ms = 50;     // bound on every connect and first force
  double rss_growth_pct = 5;  // bound on RSS growth from the reference sample to the end
  bool check = false;
};

double Since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// ---- messages -------------------------------------------------------------------------------

void PutBigEndian(std::uint8_t* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (56 - 8 * i));
}

// Sets the header's body size and CRC to match the body actually there.
void Reframe(Bytes* m) {
  const std::size_t body = m->size() - igtl_wire::kHeaderBytes;
  PutBigEndian(m->data() + 42, body);
  PutBigEndian(m->data() + 50, crc64(m->data() + igtl_wire::kHeaderBytes, body, 0));
}

Pose PoseAt(const Vec3& p) {
  Pose pose;
  pose.position_mm = p;
  return pose;
}

/// The bad messages bridge A mixes in, by the refusal kind the server should log ("ignored" is
/// not a refusal: a name mapped to ignore, dropped without a log line).
const std::vector<std::string> kBadKinds = {"crc",   "malformed", "type",    "device",
                                            "order", "command",   "ignored", "oversized"};

Bytes BadMessage(const std::string& kind, double ts) {
  Bytes m = igtl_wire::EncodeTransform("Slot0ToReference", PoseAt(Vec3(40, 10, 20)), ts);
  if (kind == "crc") {
    m.back() ^= 0x55;
  } else if (kind == "malformed") {  // truncated body, framed and CRC'd as sent
    m.resize(igtl_wire::kHeaderBytes + 24);
    Reframe(&m);
  } else if (kind == "type") {
    std::memcpy(m.data() + 2, "POSITION\0\0\0\0", 12);
  } else if (kind == "device") {
    m = igtl_wire::EncodeTransform("Slot7ToReference", Pose{}, ts);
  } else if (kind == "order") {
    m = igtl_wire::EncodeTransform("Slot0ToReference", Pose{}, ts - 0.5);
  } else if (kind == "command") {
    m = igtl_wire::EncodeString("Command", "slot0 speed=3", ts);
  } else if (kind == "ignored") {
    m = igtl_wire::EncodeTransform("ReferenceToTracker", Pose{}, ts);
  } else if (kind == "oversized") {
    m.resize(igtl_wire::kHeaderBytes + 70000, 0xab);  // the server's limit is 64 KiB
    Reframe(&m);
  }
  return m;
}

// ---- a client connection --------------------------------------------------------------------

struct Received {
  std::map<std::int64_t, int> steps;  // step -> slots answered (bit 0: Slot0Force, bit 1: ...)
  std::uint64_t forces = 0;
};

class Conn {
 public:
  Conn(int port, double dt_s) : dt_(dt_s), parser_(1 << 20) {
    fd_ = igtl_wire::Connect("127.0.0.1", port, 5.0);
  }
  ~Conn() { Close(); }
  bool ok() const { return fd_ >= 0; }
  void Close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  /// Sends all of b (reading meanwhile if the server is busy); false if the connection broke.
  bool Send(const Bytes& b) {
    std::size_t off = 0;
    while (off < b.size()) {
      const ssize_t n = ::send(fd_, b.data() + off, b.size() - off, MSG_NOSIGNAL);
      if (n > 0) {
        off += static_cast<std::size_t>(n);
      } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        if (!Read(5)) return false;
      } else {
        return false;
      }
    }
    return true;
  }
  /// Reads what arrives within timeout_ms; false once the server has closed the connection.
  bool Read(int timeout_ms) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return true;
    std::uint8_t buf[65536];
    for (;;) {
      const ssize_t n = ::recv(fd_, buf, sizeof(buf), 0);
      if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
        Parse();
        return false;
      }
      if (n < 0) break;
      parser_.Append(buf, static_cast<std::size_t>(n));
      any_ = true;
    }
    Parse();
    return true;
  }
  bool any() const { return any_; }
  const Received& received() const { return rx_; }

 private:
  void Parse() {
    igtl_wire::Message m;
    std::string why;
    while (parser_.Next(&m, &why) == igtl_wire::StreamParser::Result::kMessage) {
      if (m.type != "SENSOR") continue;
      const int slot = m.device == "Slot0Force" ? 0 : m.device == "Slot1Force" ? 1 : -1;
      if (slot < 0 || !igtl_wire::DecodeSensor(m, &why)) continue;
      rx_.steps[std::llround(m.timestamp_s / dt_)] |= 1 << slot;
      ++rx_.forces;
    }
  }
  int fd_ = -1;
  double dt_;
  igtl_wire::StreamParser parser_;
  Received rx_;
  bool any_ = false;
};

// ---- what the run did -----------------------------------------------------------------------

struct Tally {
  std::mutex mu;
  std::map<std::string, std::uint64_t> sent;  // by kind; "valid" for applied messages
  std::vector<double> connect_ms, served_ms;  // every connect; first force of each burst's last
  std::uint64_t connections = 0, refused_clients = 0, cycles = 0;
  Received a, b;
  std::string failure;  // a client thread's fatal problem
  void Add(const std::string& kind, std::uint64_t n = 1) {
    std::lock_guard<std::mutex> l(mu);
    sent[kind] += n;
  }
  void Fail(const std::string& why) {
    std::lock_guard<std::mutex> l(mu);
    if (failure.empty()) failure = why;
  }
};

struct Shared {
  Args args;
  int port = 0;
  Clock::time_point start;
  std::atomic<bool> stop_b{false};
  Tally tally;
};

// Connects, timing it; counts the connection.
std::unique_ptr<Conn> Dial(Shared* s) {
  const auto t0 = Clock::now();
  auto c = std::make_unique<Conn>(s->port, s->args.dt_s);
  std::lock_guard<std::mutex> l(s->tally.mu);
  s->tally.connect_ms.push_back(Since(t0) * 1000);
  if (c->ok()) ++s->tally.connections;
  return c;
}

// Ticks at 1 kHz from `from_s` to `to_s` (run time), calling tick(k) and reading in between.
template <class F>
void AtOneKilohertz(Shared* s, double from_s, double to_s, Conn* c, F tick) {
  for (std::int64_t k = 0;; ++k) {
    const double at = from_s + static_cast<double>(k) * 1e-3;
    if (at >= to_s) return;
    const auto due =
        s->start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(at));
    while (Clock::now() < due) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(due - Clock::now());
      if (!c->Read(static_cast<int>(std::max<std::int64_t>(0, left.count())))) return;
    }
    if (!c->Read(0) || !tick(k)) return;  // read every tick, also when behind
  }
}

// Bridge A: slot0 and the scope every ms, commands every 50 ms, bad messages mixed in; holds
// back the last 20 bytes of each tick's stream until the next (the server always has a message
// in part: its parser must not keep what it has consumed).
void BridgeA(Shared* s, std::unique_ptr<Conn> c) {
  std::mt19937_64 rng(s->args.seed);
  std::uniform_real_distribution<double> u(0, 1);
  Bytes held;
  std::uint64_t valid = 0;
  auto tick = [&](std::int64_t k) {
    const double ts = 1.0 + static_cast<double>(k) * 1e-3;
    const double x = 40 + 5 * std::sin(static_cast<double>(k) * 1e-3);
    Bytes out = held;
    auto put = [&](const Bytes& m) { out.insert(out.end(), m.begin(), m.end()); };
    if (k > 0 && u(rng) < s->args.bad_per_ms) {  // k > 0: 'order' needs an earlier pose
      const auto pick = static_cast<std::size_t>(u(rng) * (kBadKinds.size() - 1));
      put(BadMessage(kBadKinds[pick], ts));
      s->tally.Add(kBadKinds[pick]);
    }
    if (k % 2000 == 1000) {  // 70 kB: one every 2 s
      put(BadMessage("oversized", ts));
      s->tally.Add("oversized");
    }
    if (k % 50 == 0) {
      put(igtl_wire::EncodeString("Command",
                                  fmt::format("slot0 instrument=grasper jaw={:.3f} buttons={}",
                                              0.5 + 0.5 * std::sin(ts), (k / 50) % 2),
                                  ts));
      ++valid;
    }
    put(igtl_wire::EncodeTransform("Slot0ToReference", PoseAt(Vec3(x, 10, 14)), ts));
    put(igtl_wire::EncodeTransform("ScopeToReference", PoseAt(Vec3(50, 10, 20)), ts));
    valid += 2;
    held.assign(out.end() - 20, out.end());
    out.resize(out.size() - 20);
    return c->Send(out);
  };
  AtOneKilohertz(s, 0.0, s->args.duration_s, c.get(), tick);
  const Bytes end = igtl_wire::EncodeString("Command", "session end", 0);
  held.insert(held.end(), end.begin(), end.end());
  if (!c->Send(held)) s->tally.Fail("bridge A: connection lost before 'session end'");
  s->tally.Add("valid", valid + 1);
  const auto t0 = Clock::now();
  while (c->Read(50) && Since(t0) < 15) {  // the last forces, until the server closes
  }
  std::lock_guard<std::mutex> l(s->tally.mu);
  s->tally.a = c->received();
}

// Bridge B: slot1 through the mapped name StylusToTracker every ms; every 100 ms a pose for
// slot0, which A is driving (refused: owner).
void BridgeB(Shared* s) {
  const double from = 0.1 * s->args.duration_s, to = 0.9 * s->args.duration_s;
  std::this_thread::sleep_until(
      s->start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(from)));
  auto c = Dial(s);
  if (!c->ok()) return s->tally.Fail("bridge B could not connect");
  c->Send(igtl_wire::EncodeString("Command", "slot1 instrument=scissors", 1.0));
  std::uint64_t valid = 1;
  auto tick = [&](std::int64_t k) {
    const double ts = 1.0 + static_cast<double>(k) * 1e-3;
    Bytes out = igtl_wire::EncodeTransform("StylusToTracker", PoseAt(Vec3(45, 20, 14)), ts);
    ++valid;
    if (k % 100 == 50) {
      const Bytes o = igtl_wire::EncodeTransform("Slot0ToReference", PoseAt(Vec3(0, 0, 0)), ts);
      out.insert(out.end(), o.begin(), o.end());
      s->tally.Add("owner");
    }
    return c->Send(out);
  };
  AtOneKilohertz(s, from, to, c.get(), tick);
  c->Read(20);
  s->tally.Add("valid", valid);
  std::lock_guard<std::mutex> l(s->tally.mu);
  s->tally.b = c->received();
}

// One connect/disconnect cycle: connects (timed), sends its message, closes; `serve`: waits for
// the first force before closing (timed from the connect).
void Cycle(Shared* s, const std::string& kind, bool serve) {
  const auto t0 = Clock::now();
  auto c = Dial(s);
  if (!c->ok()) return s->tally.Fail("a cycle could not connect");
  Bytes m = igtl_wire::EncodeString("Command", "scope lens_roll=0.1", 1.0);
  if (kind == "header") m.assign(igtl_wire::kHeaderBytes, 0xff);
  if (kind == "partial") m = Bytes(m.begin(), m.begin() + 30);
  c->Send(m);
  s->tally.Add(kind == "command" ? "valid" : kind);
  if (serve) {
    while (c->received().forces == 0 && Since(t0) < 5 && c->Read(5)) {
    }
    std::lock_guard<std::mutex> l(s->tally.mu);
    s->tally.served_ms.push_back(c->received().forces > 0 ? Since(t0) * 1000 : 1e9);
  }
  std::lock_guard<std::mutex> l(s->tally.mu);
  ++s->tally.cycles;
}

// One client too many (with A and B connected): opens max_clients - 1 more at once; the ones
// closed by the server without a byte were refused.
void TooMany(Shared* s) {
  std::vector<std::unique_ptr<Conn>> extra;
  for (int i = 0; i < s->args.max_clients - 1; ++i) extra.push_back(Dial(s));
  const auto t0 = Clock::now();
  std::vector<bool> open(extra.size(), true);
  while (Since(t0) < 0.5) {
    for (std::size_t i = 0; i < extra.size(); ++i) {
      if (open[i] && extra[i]->ok() && !extra[i]->Read(1)) open[i] = false;
    }
  }
  std::lock_guard<std::mutex> l(s->tally.mu);
  for (std::size_t i = 0; i < extra.size(); ++i) {
    if (!open[i] && !extra[i]->any()) {
      ++s->tally.refused_clients;
      --s->tally.connections;  // refused: not a served connection
    }
  }
}

void Churn(Shared* s) {
  std::mt19937_64 rng(s->args.seed + 1);
  const char* kinds[] = {"command", "header", "partial"};
  const int bursts = (s->args.cycles + s->args.burst - 1) / s->args.burst;
  bool too_many_done = false;
  for (int b = 0, done = 0; b < bursts; ++b) {
    const double at = s->args.duration_s * (0.05 + 0.8 * b / std::max(1, bursts));
    std::this_thread::sleep_until(
        s->start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(at)));
    if (!too_many_done && at >= 0.5 * s->args.duration_s) {
      TooMany(s);
      too_many_done = true;
    }
    for (int i = 0; i < s->args.burst && done < s->args.cycles; ++i, ++done) {
      const bool last = i == s->args.burst - 1 || done == s->args.cycles - 1;
      Cycle(s, last ? "command" : kinds[rng() % 3], last);
    }
  }
  if (!too_many_done) TooMany(s);
}

// ---- the server process ---------------------------------------------------------------------

int FreePort() {
  int port = 0;
  const int fd = igtl_wire::Listen("127.0.0.1", 0, &port);
  ::close(fd);
  return port;
}

pid_t StartServer(const Args& a, int port) {
  const std::string log = a.dir + "/server.log", out = a.dir + "/soak.h5";
  const std::string p = std::to_string(port);
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    execl(a.arthrosim.c_str(), a.arthrosim.c_str(), "serve", a.scene.c_str(), "--port", p.c_str(),
          "--out", out.c_str(), "--igtl-device", "StylusToTracker=slot1", "--igtl-device",
          "ReferenceToTracker=ignore", static_cast<char*>(nullptr));
    _exit(127);
  }
  return pid;
}

struct Sample {
  double t_s;
  long rss_kb;
  double cpu_s;
};

bool ReadProc(pid_t pid, Sample* s) {
  std::ifstream st("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  s->rss_kb = -1;
  while (std::getline(st, line)) {
    if (line.rfind("VmRSS:", 0) == 0) s->rss_kb = std::stol(line.substr(6));
  }
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
  const std::size_t paren = text.rfind(')');
  if (s->rss_kb < 0 || paren == std::string::npos) return false;
  std::istringstream in(text.substr(paren + 2));
  std::string field;
  unsigned long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && in >> field; ++i) {  // fields 14, 15: utime, stime (ticks)
    if (i == 14) utime = std::stoull(field);
    if (i == 15) stime = std::stoull(field);
  }
  s->cpu_s = static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
  return true;
}

// ---- the server log -------------------------------------------------------------------------

struct LogCounts {
  std::map<std::string, std::uint64_t> lines, summed;  // refusals by kind
  std::uint64_t connected = 0, steps = 0;
  std::string crash;  // a line that says the server failed
};

LogCounts ReadLog(const std::string& path) {
  LogCounts c;
  std::ifstream in(path);
  std::string l;
  while (std::getline(in, l)) {
    char kind[32];
    unsigned long long n = 0;
    if (std::sscanf(l.c_str(), "igtl: refused %31[a-z]: %llu more", kind, &n) == 2) {
      c.summed[kind] += n;
    } else if (std::sscanf(l.c_str(), "igtl: refused %31[a-z] from", kind) == 1) {
      ++c.lines[kind];
    } else if (std::sscanf(l.c_str(), "igtl: connections: %llu more", &n) == 1) {
      c.connected += n;
    } else if (l.rfind("igtl: client ", 0) == 0 && l.size() > 10 &&
               l.compare(l.size() - 10, 10, " connected") == 0) {
      ++c.connected;
    } else if (l.find(" steps (") != std::string::npos) {
      c.steps = std::stoull(l.substr(l.find(": ") + 2));
    } else if (l.rfind("error", 0) == 0 || l.find("terminate") != std::string::npos) {
      c.crash = l;
    }
  }
  return c;
}

// ---- checks and report ----------------------------------------------------------------------

struct Report {
  int failures = 0;
  void Check(bool ok, const std::string& what) {
    std::printf("%s %s\n", ok ? "  ok  " : "  FAIL", what.c_str());
    if (!ok) ++failures;
  }
};

// Steps between the first and last answered, and how many of them lack a force.
std::pair<std::int64_t, std::int64_t> Answered(const Received& r, std::int64_t* last) {
  if (r.steps.empty()) return {0, 0};
  const std::int64_t first = r.steps.begin()->first;
  *last = r.steps.rbegin()->first;
  std::int64_t missing = 0;
  for (std::int64_t k = first; k <= *last; ++k) {
    const auto it = r.steps.find(k);
    if (it == r.steps.end() || it->second != 3) ++missing;
  }
  return {*last - first + 1, missing};
}

void CheckSteps(const Shared& s, const LogCounts& log, Report* rep) {
  std::int64_t last_a = -1, last_b = -1;
  const auto [na, miss_a] = Answered(s.tally.a, &last_a);
  const auto [nb, miss_b] = Answered(s.tally.b, &last_b);
  std::printf(
      "steps: server %llu; bridge A got forces of %lld (last %lld), %lld missing; "
      "bridge B %lld, %lld missing\n",
      static_cast<unsigned long long>(log.steps), static_cast<long long>(na),
      static_cast<long long>(last_a), static_cast<long long>(miss_a), static_cast<long long>(nb),
      static_cast<long long>(miss_b));
  rep->Check(na > 0 && miss_a == 0 && last_a == static_cast<std::int64_t>(log.steps),
             "every step answered to bridge A, to the last");
  rep->Check(nb > 0 && miss_b == 0, "every step answered to bridge B while connected");
}

void CheckRefusals(const Shared& s, const LogCounts& log, Report* rep) {
  std::printf("%-10s %8s %8s %8s\n", "kind", "sent", "lines", "summed");
  for (const auto& [kind, n] : s.tally.sent) {
    const std::uint64_t lines = log.lines.count(kind) ? log.lines.at(kind) : 0;
    const std::uint64_t summed = log.summed.count(kind) ? log.summed.at(kind) : 0;
    std::printf("%-10s %8llu %8llu %8llu\n", kind.c_str(), static_cast<unsigned long long>(n),
                static_cast<unsigned long long>(lines), static_cast<unsigned long long>(summed));
    if (kind == "valid" || kind == "ignored") {
      rep->Check(lines + summed == 0, kind + ": no refusal logged");
    } else {
      rep->Check(
          lines >= 1 && lines + summed == n,
          fmt::format("{}: {} sent, {} logged one by one + {} summed", kind, n, lines, summed));
    }
  }
  const std::uint64_t clients = log.lines.count("clients") ? log.lines.at("clients") : 0;
  rep->Check(
      s.tally.refused_clients == 1 && clients == 1,
      fmt::format("one client too many: {} refused, {} logged", s.tally.refused_clients, clients));
}

void CheckConnects(const Shared& s, const LogCounts& log, Report* rep) {
  const auto& c = s.tally.connect_ms;
  const auto& v = s.tally.served_ms;
  double sum = 0;
  for (double x : c) sum += x;
  const double worst = c.empty() ? 0 : *std::max_element(c.begin(), c.end());
  const double worst_served = v.empty() ? 0 : *std::max_element(v.begin(), v.end());
  std::printf(
      "connects: %zu, connect max %.2f ms mean %.2f ms; first force after connect (%zu "
      "bursts) max %.2f ms\n",
      c.size(), worst, c.empty() ? 0 : sum / static_cast<double>(c.size()), v.size(), worst_served);
  rep->Check(s.tally.cycles == static_cast<std::uint64_t>(s.args.cycles),
             fmt::format("{} connect/disconnect cycles made", s.tally.cycles));
  rep->Check(worst <= s.args.latency_ms && worst_served <= s.args.latency_ms,
             fmt::format("every connect and first force within {} ms", s.args.latency_ms));
  rep->Check(log.connected == s.tally.connections,
             fmt::format("server logged {} connections, the soak made {}", log.connected,
                         s.tally.connections));
}

void CheckMemory(const Shared& s, const std::vector<Sample>& samples, Report* rep) {
  if (samples.size() < 4) return rep->Check(false, "too few RSS samples");
  // The reference: minute 1 of a long run, a quarter of the way through a short one.
  const double ref_t = s.args.duration_s >= 120 ? 60 : s.args.duration_s / 4;
  const Sample* ref = &samples.front();
  for (const Sample& x : samples) {
    if (x.t_s <= ref_t) ref = &x;
  }
  const Sample* last = &samples.front();  // the last sample of the traffic, not the shutdown
  for (const Sample& x : samples) {
    if (x.t_s <= s.args.duration_s) last = &x;
  }
  const Sample& end = *last;
  const double growth =
      100.0 * static_cast<double>(end.rss_kb - ref->rss_kb) / static_cast<double>(ref->rss_kb);
  std::printf(
      "server RSS: %ld kB at %.0f s, %ld kB at %.0f s (%+.1f %%); CPU %.1f s over "
      "%.0f s (%.0f %% of one core)\n",
      ref->rss_kb, ref->t_s, end.rss_kb, end.t_s, growth, end.cpu_s, end.t_s,
      100 * end.cpu_s / std::max(1.0, end.t_s));
  rep->Check(growth <= s.args.rss_growth_pct,
             fmt::format("RSS growth {:.1f} % <= {} %", growth, s.args.rss_growth_pct));
}

std::vector<Sample> Sampler(pid_t pid, Shared* s, const std::atomic<bool>* done) {
  std::vector<Sample> samples;
  for (int k = 1; !done->load(); ++k) {
    std::this_thread::sleep_until(s->start + std::chrono::seconds(k));
    Sample x;
    x.t_s = Since(s->start);
    if (!done->load() && ReadProc(pid, &x)) samples.push_back(x);
  }
  return samples;
}

int Run(Shared* s) {
  const Args& a = s->args;
  std::filesystem::create_directories(a.dir);
  s->port = FreePort();
  const pid_t pid = StartServer(a, s->port);
  std::unique_ptr<Conn> first;
  for (int i = 0; i < 100 && !(first && first->ok()); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    first = std::make_unique<Conn>(s->port, a.dt_s);
  }
  if (!first->ok()) {
    ::kill(pid, SIGKILL);
    std::fprintf(stderr, "igtl_soak: the server did not listen (see %s/server.log)\n",
                 a.dir.c_str());
    return 2;
  }
  s->tally.connections = 1;
  s->start = Clock::now();
  std::atomic<bool> done{false};
  std::vector<Sample> samples;
  std::thread sampler([&] { samples = Sampler(pid, s, &done); });
  std::thread b([&] { BridgeB(s); });
  std::thread churn([&] { Churn(s); });
  BridgeA(s, std::move(first));  // ends with 'session end' and reads until the server closes
  b.join();
  churn.join();
  int status = 0;
  for (int i = 0; i < 200 && waitpid(pid, &status, WNOHANG) == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  if (waitpid(pid, &status, WNOHANG) == 0) {
    ::kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
  }
  done = true;
  sampler.join();

  Report rep;
  const LogCounts log = ReadLog(a.dir + "/server.log");
  rep.Check(WIFEXITED(status) && WEXITSTATUS(status) == 0 && log.crash.empty(),
            fmt::format("server exited with 0 (status {}) {}", status, log.crash));
  rep.Check(s->tally.failure.empty(), "clients: " + s->tally.failure);
  CheckSteps(*s, log, &rep);
  CheckRefusals(*s, log, &rep);
  CheckConnects(*s, log, &rep);
  CheckMemory(*s, samples, &rep);
  std::printf("%s: %d check(s) failed\n", rep.failures ? "FAILED" : "passed", rep.failures);
  return a.check && rep.failures > 0 ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Soak arthrosim's live OpenIGTLink server over loopback (issue #18)"};
  Shared s;
  Args& a = s.args;
  app.add_option("--arthrosim", a.arthrosim, "the arthrosim binary")->required();
  app.add_option("--scene", a.scene, "scenario to serve (dt should be --dt)")->required();
  app.add_option("--dir", a.dir, "folder for server.log and soak.h5")->required();
  app.add_option("--duration", a.duration_s, "seconds of traffic")->capture_default_str();
  app.add_option("--dt", a.dt_s, "the scene's step, s")->capture_default_str();
  app.add_option("--cycles", a.cycles, "connect/disconnect cycles")->capture_default_str();
  app.add_option("--burst", a.burst, "cycles back to back per burst")->capture_default_str();
  app.add_option("--max-clients", a.max_clients, "the server's limit")->capture_default_str();
  app.add_option("--seed", a.seed, "seed of the mix")->capture_default_str();
  app.add_option("--bad-rate", a.bad_per_ms, "bad messages per ms of bridge A")
      ->capture_default_str();
  app.add_option("--latency-ms", a.latency_ms, "bound on each connect and first force")
      ->capture_default_str();
  app.add_option("--rss-growth", a.rss_growth_pct, "bound on RSS growth, %")->capture_default_str();
  app.add_flag("--check", a.check, "exit 1 if a check fails");
  CLI11_PARSE(app, argc, argv);
  ::signal(SIGPIPE, SIG_IGN);
  return Run(&s);
}
