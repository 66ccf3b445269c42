// The live OpenIGTLink server: one network thread (poll loop), device state behind a mutex.
// Wall-clock reads happen only here (pacing Frame to real time, log windows, which client drives
// a device) and never in file/script sources.
#include "arthrosim/input/igtl_server.h"

#include <arpa/inet.h>
#include <fmt/format.h>
#include <igtl_util.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>
#include <vector>

#include "igtl_log.h"
#include "igtl_wire.h"

namespace arthrosim::input {
namespace {

using Clock = std::chrono::steady_clock;

constexpr std::size_t kMaxQueuedBytes = 1 << 20;
/// A device's pose comes from one client: the one that sent it last, while it keeps sending
/// (another client's TRANSFORMs for it are refused until this long after its last one).
constexpr std::chrono::milliseconds kOwnerHold{1000};

constexpr EnumName<Refusal> kRefusalNames[] = {
    {Refusal::kHeader, "header"},  {Refusal::kOversized, "oversized"},
    {Refusal::kCrc, "crc"},        {Refusal::kMalformed, "malformed"},
    {Refusal::kType, "type"},      {Refusal::kDevice, "device"},
    {Refusal::kOrder, "order"},    {Refusal::kCommand, "command"},
    {Refusal::kOwner, "owner"},    {Refusal::kPartial, "partial"},
    {Refusal::kClients, "clients"}};
static_assert(std::size(kRefusalNames) == kRefusalKinds, "a name for every Refusal");

void StderrLog(const std::string& s) { std::fprintf(stderr, "igtl: %s\n", s.c_str()); }

std::uint64_t BigEndian(const std::uint8_t* p, int n) {
  std::uint64_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | p[i];
  return v;
}

/// A NUL-padded header field as text.
std::string HeaderField(const std::uint8_t* p, std::size_t n) {
  std::size_t len = 0;
  while (len < n && p[len] != 0) ++len;
  return std::string(reinterpret_cast<const char*>(p), len);
}

/// Whether the body's CRC-64 is the one in the header (bytes 50-57).
bool BodyCrcMatches(const igtl_wire::Message& m) {
  const std::size_t header = igtl_wire::kHeaderBytes;
  std::vector<std::uint8_t> body(m.bytes.begin() + static_cast<std::ptrdiff_t>(header),
                                 m.bytes.end());
  return crc64(body.data(), body.size(), 0) == BigEndian(m.bytes.data() + header - 8, 8);
}

/// What of a message arrived: "30 of 106 bytes of TRANSFORM 'Slot0ToReference'" (a header is
/// complete: Next checked it) or "12 of the 58 header bytes".
std::string DescribePartial(const std::vector<std::uint8_t>& p) {
  const std::size_t header = igtl_wire::kHeaderBytes;
  if (p.size() < header) return fmt::format("{} of the {} header bytes", p.size(), header);
  return fmt::format("{} of {} bytes of {} '{}'", p.size(), header + BigEndian(&p[42], 8),
                     HeaderField(&p[2], 12), HeaderField(&p[14], 20));
}

/// `text` fit for one log line: control and non-ASCII bytes as '?', at most about 300
/// characters, its start and end (a client's STRING must not forge log lines or write 64 kB).
std::string OneLine(const std::string& text) {
  std::string out =
      text.size() <= 300 ? text : text.substr(0, 196) + " ... " + text.substr(text.size() - 99);
  for (char& c : out) {
    if (c < 0x20 || c > 0x7e) c = '?';
  }
  return out;
}

std::string PeerAddress(const sockaddr_in& a) {
  char ip[INET_ADDRSTRLEN] = "?";
  ::inet_ntop(AF_INET, &a.sin_addr, ip, sizeof(ip));
  return fmt::format("{}:{}", ip, ntohs(a.sin_port));
}

/// The TRANSFORM names the server takes: the defaults, with the mapped names over them.
IgtlDeviceNames TransformNames(const IgtlDeviceNames& mapped) {
  IgtlDeviceNames names;
  for (const auto& row : igtl_wire::kTransformNames) names[row.name] = row.value;
  for (const auto& [name, dev] : mapped) names[name] = dev;
  return names;
}

bool ParseNumber(const std::string& s, double* v) {
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), *v);
  return ec == std::errc() && p == s.data() + s.size() && std::isfinite(*v);
}

}  // namespace

const char* RefusalName(Refusal kind) { return NameIn(kRefusalNames, kind, "?"); }

bool ApplyCommandString(const Model& model, const std::string& text, InputFrame* frame,
                        std::array<std::uint8_t, kToolSlots>* latched, std::string* why) {
  std::istringstream in(text);
  std::string dev_name;
  in >> dev_name;
  const std::optional<Device> dev = ParseDevice(dev_name);
  if (!dev) {
    *why = fmt::format("STRING '{}': unknown device '{}' (slot0, slot1, scope)", text, dev_name);
    return false;
  }
  InputFrame next = *frame;
  std::uint8_t press = 0;
  std::string kv;
  while (in >> kv) {
    const std::size_t eq = kv.find('=');
    const std::string key = kv.substr(0, eq);
    const std::string val = eq == std::string::npos ? "" : kv.substr(eq + 1);
    double x = 0;
    auto bad = [&](const char* expected) {
      *why = fmt::format("STRING '{}': bad {} '{}' ({})", text, key, val, expected);
      return false;
    };
    if (*dev == Device::kScope) {
      if (key == "lens_roll" || key == "head_roll") {
        if (!ParseNumber(val, &x)) return bad("radians");
        (key == "lens_roll" ? next.camera.lens_roll_rad : next.camera.head_roll_rad) = x;
        continue;
      }
    } else {
      ToolCommand& tc = next.tools[static_cast<int>(*dev)];
      if (key == "jaw") {
        if (!ParseNumber(val, &x) || x < 0 || x > 1) return bad("number in [0, 1]");
        tc.jaw = x;
        continue;
      }
      if (key == "buttons") {
        if (!ParseNumber(val, &x) || x != std::floor(x) || x < 0 || x > 3)
          return bad("integer 0..3");
        tc.buttons = static_cast<std::uint8_t>(x);
        press = tc.buttons;
        continue;
      }
      if (key == "instrument") {
        if (val == "none") {
          tc.instrument = -1;
          continue;
        }
        const int idx = model.FindInstrument(val);
        if (idx < 0) return bad("instrument name of the scenario, or none");
        tc.instrument = idx;
        continue;
      }
    }
    *why = fmt::format("STRING '{}': unknown key '{}' for {}", text, key, dev_name);
    return false;
  }
  *frame = next;
  if (*dev != Device::kScope) (*latched)[static_cast<int>(*dev)] |= press;
  return true;
}

struct IgtlServer::Impl {
  struct Client {
    int fd = -1;
    std::uint64_t id = 0;
    std::string name;  // "client 3 (127.0.0.1:40122)", in every log line about it
    igtl_wire::StreamParser parser;
    std::vector<std::uint8_t> out;  // queued bytes (guarded by mu)
    std::size_t out_pos = 0;
    std::map<std::string, double> last_ts;  // per device name, this connection only
    bool overflow_logged = false;
    explicit Client(std::size_t max_body) : parser(max_body) {}
  };
  struct Owner {  // the client driving a device's pose
    std::uint64_t client = 0;
    Clock::time_point seen;  // its last TRANSFORM for the device
  };

  const Model& model;
  IgtlServerOptions opt;
  IgtlDeviceNames names;  // TRANSFORM device name -> device
  RateLimitedLog log;
  int listen_fd = -1;
  int bound_port = 0;
  int wake[2] = {-1, -1};
  std::thread thread;
  std::atomic<bool> stop{false};
  std::vector<std::uint8_t> rx = std::vector<std::uint8_t>(64 * 1024);  // network thread only

  mutable std::mutex mu;
  mutable std::condition_variable cv;
  InputFrame state;
  std::array<std::uint8_t, kToolSlots> latched{};
  bool session_end = false;
  IgtlServerStats stats;
  std::vector<std::unique_ptr<Client>> clients;
  std::array<Owner, kDeviceCount> owners{};
  double last_t = 0;
  double lag_s = 0;                                  // of the last Frame (realtime pacing)
  std::array<bool, kToolSlots> posed{false, false};  // a TRANSFORM arrived for the slot
  bool have_origin = false;
  Clock::time_point origin;

  Impl(const Model& m, IgtlServerOptions o)
      : model(m),
        opt(std::move(o)),
        names(TransformNames(opt.device_names)),
        log(opt.log ? opt.log : StderrLog, opt.log_lines_per_second),
        state(IdleFrame(m)) {
    listen_fd = igtl_wire::Listen(opt.bind_address, opt.port, &bound_port);
    if (::pipe(wake) != 0) throw std::runtime_error("pipe() failed");
    igtl_wire::SetNonBlocking(wake[0]);
    igtl_wire::SetNonBlocking(wake[1]);
    if (!opt.device_names.empty()) log.Always("TRANSFORM device names: " + MappingText());
    thread = std::thread([this] { Loop(); });
  }

  std::string MappingText() const {
    std::string text;
    for (const auto& [name, dev] : opt.device_names) {
      text += fmt::format("{}{} -> {}", text.empty() ? "" : ", ", name,
                          dev ? DeviceName(*dev) : "ignored");
    }
    return text;
  }

  void Wake() {
    const char c = 1;
    [[maybe_unused]] const ssize_t n = ::write(wake[1], &c, 1);
  }

  void Refuse(Refusal kind, const std::string& who, const std::string& why) {  // mu held
    ++stats.refused[static_cast<std::size_t>(kind)];
    ++stats.dropped;
    const std::string word = RefusalName(kind);
    log.Write("refused " + word, fmt::format("refused {} from {}: {}", word, who, OneLine(why)),
              Clock::now());
  }

  bool HeldByOther(int dev, const Client& c, std::uint64_t* owner) const {  // mu held
    const Owner& o = owners[static_cast<std::size_t>(dev)];
    *owner = o.client;
    return o.client != 0 && o.client != c.id && Clock::now() - o.seen < kOwnerHold;
  }

  bool ApplyTransform(Client* c, const igtl_wire::Message& m) {  // mu held
    const auto it = names.find(m.device);
    if (it == names.end()) {
      Refuse(Refusal::kDevice, c->name,
             fmt::format("TRANSFORM '{}': unknown device name (Slot0ToReference, "
                         "Slot1ToReference, ScopeToReference, or map it: --igtl-device "
                         "NAME=slot0|slot1|scope|ignore)",
                         m.device));
      return false;
    }
    if (!it->second) {
      ++stats.ignored;
      return false;
    }
    const int dev = static_cast<int>(*it->second);
    std::uint64_t owner = 0;
    if (HeldByOther(dev, *c, &owner)) {
      Refuse(Refusal::kOwner, c->name,
             fmt::format("TRANSFORM '{}': {} is driven by client {}; one client per device",
                         m.device, DeviceName(*it->second), owner));
      return false;
    }
    std::string why;
    const std::optional<Pose> pose = igtl_wire::DecodeTransform(m, &why);
    if (!pose) {
      Refuse(Refusal::kMalformed, c->name, why);
      return false;
    }
    (*it->second == Device::kScope ? state.camera.pose : state.tools[dev].pose) = *pose;
    if (dev < kToolSlots) posed[static_cast<std::size_t>(dev)] = true;
    owners[static_cast<std::size_t>(dev)] = Owner{c->id, Clock::now()};
    return true;
  }

  bool ApplyString(Client* c, const igtl_wire::Message& m) {  // mu held
    std::string why;
    const std::optional<std::string> text = igtl_wire::DecodeString(m, &why);
    if (!text) {
      Refuse(Refusal::kMalformed, c->name, why);
      return false;
    }
    if (*text == "session end") {
      session_end = true;
    } else if (!ApplyCommandString(model, *text, &state, &latched, &why)) {
      Refuse(Refusal::kCommand, c->name, why);
      return false;
    }
    return true;
  }

  void Handle(Client* c, const igtl_wire::Message& m) {  // mu held
    if (m.type != "TRANSFORM" && m.type != "STRING") {
      return Refuse(Refusal::kType, c->name,
                    fmt::format("{} '{}': unsupported message type (TRANSFORM, STRING are taken)",
                                m.type, m.device));
    }
    if (!BodyCrcMatches(m)) {
      return Refuse(Refusal::kCrc, c->name,
                    fmt::format("{} '{}': body CRC mismatch", m.type, m.device));
    }
    // Out of order: a timestamped message older than the last one of that device is stale.
    const std::string key = m.device + "/" + m.type;
    const auto last = c->last_ts.find(key);
    if (m.timestamp_s > 0 && last != c->last_ts.end() && m.timestamp_s < last->second) {
      return Refuse(Refusal::kOrder, c->name,
                    fmt::format("{} '{}': timestamp {:.6f} older than {:.6f} (out of order)",
                                m.type, m.device, m.timestamp_s, last->second));
    }
    if (!(m.type == "TRANSFORM" ? ApplyTransform(c, m) : ApplyString(c, m))) return;
    if (m.timestamp_s > 0) c->last_ts[key] = m.timestamp_s;
    ++stats.applied;
    cv.notify_all();
  }

  // Closes client i; `partial`: a message it had begun is refused as cut short.
  void Close(std::size_t i, const std::string& why, bool partial) {  // mu held
    Client* c = clients[i].get();
    const std::vector<std::uint8_t> pending = c->parser.Pending();
    if (partial && !pending.empty() && !c->parser.Skipping())
      Refuse(Refusal::kPartial, c->name, "disconnected mid-message: " + DescribePartial(pending));
    for (Owner& o : owners) {
      if (o.client == c->id) o = Owner{};
    }
    log.Write("disconnections",
              fmt::format("{} disconnected: {} (device state kept)", c->name, why), Clock::now());
    ::close(c->fd);
    clients.erase(clients.begin() + static_cast<std::ptrdiff_t>(i));
    stats.clients = static_cast<int>(clients.size());
    cv.notify_all();
  }

  void Admit(int fd, const std::string& peer) {  // mu held
    if (static_cast<int>(clients.size()) >= opt.max_clients) Reap();
    if (static_cast<int>(clients.size()) >= opt.max_clients) {
      Refuse(Refusal::kClients, "a client at " + peer,
             fmt::format("{} clients connected, the limit; connection closed", opt.max_clients));
      ::close(fd);
      return;
    }
    const int one = 1;  // forces go out as soon as a step is done
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
    auto c = std::make_unique<Client>(opt.max_body_bytes);
    c->fd = fd;
    c->id = ++stats.connections;
    c->name = fmt::format("client {} ({})", c->id, peer);
    log.Write("connections", c->name + " connected", Clock::now());
    clients.push_back(std::move(c));
    stats.clients = static_cast<int>(clients.size());
    cv.notify_all();
  }

  // Accepts every connection waiting: a burst of connects must not wait for later poll rounds
  // (nor overflow the backlog, which makes the kernel drop SYNs the client repeats after 1 s).
  void AcceptAll() {  // mu held
    for (;;) {
      sockaddr_in a{};
      socklen_t len = sizeof(a);
      const int fd =
          ::accept4(listen_fd, reinterpret_cast<sockaddr*>(&a), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (fd >= 0) {
        Admit(fd, PeerAddress(a));
        continue;
      }
      if (errno == EINTR || errno == ECONNABORTED) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK)
        log.Write("accept", fmt::format("accept failed: {}", std::strerror(errno)), Clock::now());
      return;
    }
  }

  // Splits client i's received bytes into messages and handles them; false if it was closed.
  bool Parse(std::size_t i) {  // mu held
    Client* c = clients[i].get();
    igtl_wire::Message m;
    std::string why;
    for (;;) {
      const auto r = c->parser.Next(&m, &why);
      if (r == igtl_wire::StreamParser::Result::kNeedMore) return true;
      if (r == igtl_wire::StreamParser::Result::kDropped) {
        Refuse(Refusal::kOversized, c->name, why);
      } else if (r == igtl_wire::StreamParser::Result::kFatal) {
        Refuse(Refusal::kHeader, c->name, why + "; connection closed");
        Close(i, "unrecoverable stream", false);
        return false;
      } else {
        Handle(c, m);
      }
    }
  }

  void SendQueued(Client* c) {  // mu held
    const ssize_t n =
        ::send(c->fd, c->out.data() + c->out_pos, c->out.size() - c->out_pos, MSG_NOSIGNAL);
    if (n > 0) c->out_pos += static_cast<std::size_t>(n);
    if (c->out_pos == c->out.size()) {
      c->out.clear();
      c->out_pos = 0;
    }
  }

  // Sends and receives on the polled client socket p (if that client is still connected):
  // reads what has arrived (up to 1 MB a round, so one client cannot hold the others up).
  void Serve(const pollfd& p) {  // mu held
    std::size_t i = 0;
    while (i < clients.size() && clients[i]->fd != p.fd) ++i;
    if (i == clients.size()) return;
    Client* c = clients[i].get();
    if (p.revents & POLLOUT) SendQueued(c);
    if (!(p.revents & (POLLIN | POLLHUP | POLLERR))) return;
    for (int round = 0; round < 16; ++round) {
      const ssize_t n = ::recv(c->fd, rx.data(), rx.size(), 0);
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return;
      if (n <= 0) return Close(i, n == 0 ? "closed by peer" : std::strerror(errno), true);
      c->parser.Append(rx.data(), static_cast<std::size_t>(n));
      if (!Parse(i)) return;
    }
  }

  // At the client limit: serves the clients once more, without waiting, so that those that
  // have already hung up are closed before a newcomer is refused.
  void Reap() {  // mu held
    std::vector<pollfd> fds;
    for (const auto& c : clients) fds.push_back({c->fd, POLLIN, 0});
    if (::poll(fds.data(), fds.size(), 0) <= 0) return;
    for (const pollfd& p : fds) Serve(p);
  }

  std::vector<pollfd> PollSet() const {
    std::lock_guard<std::mutex> lock(mu);
    std::vector<pollfd> fds{{listen_fd, POLLIN, 0}, {wake[0], POLLIN, 0}};
    for (const auto& c : clients) {
      fds.push_back(
          {c->fd, static_cast<short>(POLLIN | (c->out_pos < c->out.size() ? POLLOUT : 0)), 0});
    }
    return fds;
  }

  void Loop() {
    while (!stop.load()) {
      std::vector<pollfd> fds = PollSet();
      if (::poll(fds.data(), fds.size(), 100) < 0 && errno != EINTR) break;
      char drain[64];
      while (::read(wake[0], drain, sizeof(drain)) > 0) {
      }
      std::lock_guard<std::mutex> lock(mu);
      if (fds[0].revents & POLLIN) AcceptAll();
      // Clients may have been added after fds was built: only look at those polled.
      for (std::size_t k = fds.size(); k-- > 2;) Serve(fds[k]);
      log.Tick(Clock::now());
    }
  }

  void Queue(const std::vector<std::uint8_t>& bytes, std::uint64_t* sent) {  // mu held
    for (auto& c : clients) {
      if (c->out.size() - c->out_pos + bytes.size() > kMaxQueuedBytes) {
        if (!c->overflow_logged)
          log.Write("slow clients", c->name + " is not reading: messages to it dropped",
                    Clock::now());
        c->overflow_logged = true;
        continue;
      }
      c->out.insert(c->out.end(), bytes.begin(), bytes.end());
      ++*sent;
    }
  }

  // Gives the network thread up to 1 s to send what is queued (the last forces and notices).
  void Flush() {
    for (int i = 0; i < 100; ++i) {
      {
        std::lock_guard<std::mutex> lock(mu);
        bool pending = false;
        for (const auto& c : clients) pending = pending || c->out_pos < c->out.size();
        if (!pending || stop.load()) return;
      }
      Wake();
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }

  // The refusals of the whole run by kind, and the held-back log lines' counts.
  void Summarise() {
    std::lock_guard<std::mutex> lock(mu);
    log.Tick(Clock::now(), /*all=*/true);
    std::string text;
    for (int k = 0; k < kRefusalKinds; ++k) {
      const std::uint64_t n = stats.refused[static_cast<std::size_t>(k)];
      if (n > 0)
        text += fmt::format("{}{} {}", text.empty() ? "" : ", ", RefusalName(Refusal(k)), n);
    }
    if (!text.empty()) log.Always("refused this run: " + text);
    if (stats.ignored > 0) log.Always(fmt::format("ignored {} mapped TRANSFORMs", stats.ignored));
  }

  void Shutdown() {
    Flush();
    if (stop.exchange(true)) return;
    Wake();
    if (thread.joinable()) thread.join();
    Summarise();
    for (auto& c : clients) ::close(c->fd);
    clients.clear();
    if (listen_fd >= 0) ::close(listen_fd);
    if (wake[0] >= 0) ::close(wake[0]);
    if (wake[1] >= 0) ::close(wake[1]);
    listen_fd = wake[0] = wake[1] = -1;
  }
};

IgtlServer::IgtlServer(const Model& model, IgtlServerOptions options)
    : impl_(std::make_unique<Impl>(model, std::move(options))) {}

IgtlServer::~IgtlServer() { impl_->Shutdown(); }

int IgtlServer::port() const { return impl_->bound_port; }

void IgtlServer::Frame(std::int64_t /*step*/, double t_s, InputFrame* out) {
  Impl& s = *impl_;
  if (s.opt.realtime) {
    const auto now = Clock::now();
    const auto at = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(t_s));
    if (!s.have_origin) {
      s.origin = now - at;
      s.have_origin = true;
    }
    s.lag_s = std::max(0.0, std::chrono::duration<double>(now - (s.origin + at)).count());
    std::this_thread::sleep_until(s.origin + at);
  }
  std::lock_guard<std::mutex> lock(s.mu);
  *out = s.state;
  for (int k = 0; k < kToolSlots; ++k) {
    out->tools[k].buttons = static_cast<std::uint8_t>(s.state.tools[k].buttons | s.latched[k]);
    if (!s.posed[static_cast<std::size_t>(k)]) out->tools[k].instrument = -1;  // no pose yet
    s.latched[k] = 0;
  }
  s.last_t = t_s;
}

void IgtlServer::Feedback(const FeedbackFrame& feedback) {
  Impl& s = *impl_;
  {
    std::lock_guard<std::mutex> lock(s.mu);
    if (s.clients.empty()) return;
    for (int k = 0; k < kToolSlots; ++k) {
      s.Queue(igtl_wire::EncodeSensor(fmt::format("Slot{}Force", k), feedback.force_n[k], s.last_t),
              &s.stats.forces_sent);
    }
  }
  s.Wake();
}

void IgtlServer::Notify(const std::string& text, double t_s) {
  Impl& s = *impl_;
  {
    std::lock_guard<std::mutex> lock(s.mu);
    if (s.clients.empty()) return;
    s.Queue(igtl_wire::EncodeString("Warning", text, t_s), &s.stats.notices_sent);
  }
  s.Wake();
}

bool IgtlServer::Finished(double) const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->session_end || impl_->stop.load();
}

double IgtlServer::RealtimeLagS() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->lag_s;
}

IgtlServerStats IgtlServer::stats() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->stats;
}

bool IgtlServer::WaitUntilApplied(std::uint64_t count, double timeout_s) const {
  std::unique_lock<std::mutex> lock(impl_->mu);
  return impl_->cv.wait_for(lock, std::chrono::duration<double>(timeout_s),
                            [&] { return impl_->stats.applied >= count; });
}

bool IgtlServer::WaitForClient(double timeout_s) const {
  std::unique_lock<std::mutex> lock(impl_->mu);
  return impl_->cv.wait_for(lock, std::chrono::duration<double>(timeout_s),
                            [&] { return impl_->stats.clients > 0; });
}

void IgtlServer::Stop() { impl_->Shutdown(); }

}  // namespace arthrosim::input
