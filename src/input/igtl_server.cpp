// The live OpenIGTLink server: one network thread (poll loop), device state behind a mutex.
// Wall-clock reads happen only here (pacing Frame to real time) and never in file/script sources.
#include "arthrosim/input/igtl_server.h"

#include <fmt/format.h>
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
#include <map>
#include <mutex>
#include <sstream>
#include <thread>
#include <vector>

#include "igtl_wire.h"

namespace arthrosim::input {
namespace {

constexpr std::size_t kMaxQueuedBytes = 1 << 20;

bool ParseNumber(const std::string& s, double* v) {
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), *v);
  return ec == std::errc() && p == s.data() + s.size() && std::isfinite(*v);
}

/// Device name of a TRANSFORM -> device; -1 if unknown.
int TransformDevice(const std::string& name) {
  const std::optional<Device> d = ValueIn(igtl_wire::kTransformNames, name);
  return d ? static_cast<int>(*d) : -1;
}

}  // namespace

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
    igtl_wire::StreamParser parser;
    std::vector<std::uint8_t> out;  // queued bytes (guarded by mu)
    std::size_t out_pos = 0;
    std::map<std::string, double> last_ts;  // per device name, this connection only
    bool overflow_logged = false;
    explicit Client(std::size_t max_body) : parser(max_body) {}
  };

  const Model& model;
  IgtlServerOptions opt;
  int listen_fd = -1;
  int bound_port = 0;
  int wake[2] = {-1, -1};
  std::thread thread;
  std::atomic<bool> stop{false};

  mutable std::mutex mu;
  mutable std::condition_variable cv;
  InputFrame state;
  std::array<std::uint8_t, kToolSlots> latched{};
  bool session_end = false;
  IgtlServerStats stats;
  std::vector<std::unique_ptr<Client>> clients;
  double last_t = 0;
  double lag_s = 0;                                  // of the last Frame (realtime pacing)
  std::array<bool, kToolSlots> posed{false, false};  // a TRANSFORM arrived for the slot
  bool have_origin = false;
  std::chrono::steady_clock::time_point origin;

  Impl(const Model& m, IgtlServerOptions o) : model(m), opt(std::move(o)), state(IdleFrame(m)) {
    if (!opt.log)
      opt.log = [](const std::string& s) { std::fprintf(stderr, "igtl: %s\n", s.c_str()); };
    listen_fd = igtl_wire::Listen(opt.bind_address, opt.port, &bound_port);
    if (::pipe(wake) != 0) throw std::runtime_error("pipe() failed");
    igtl_wire::SetNonBlocking(wake[0]);
    igtl_wire::SetNonBlocking(wake[1]);
    thread = std::thread([this] { Loop(); });
  }

  void Wake() {
    const char c = 1;
    [[maybe_unused]] const ssize_t n = ::write(wake[1], &c, 1);
  }

  void Drop(const std::string& why) {  // mu held
    ++stats.dropped;
    opt.log("dropped: " + why);
  }

  void Handle(Client* c, const igtl_wire::Message& m) {  // mu held
    // Out-of-order: a timestamped message older than the last one of that device is stale.
    if (m.timestamp_s > 0) {
      auto it = c->last_ts.find(m.device + "/" + m.type);
      if (it != c->last_ts.end() && m.timestamp_s < it->second) {
        return Drop(fmt::format("{} '{}': timestamp {:.6f} older than {:.6f} (out of order)",
                                m.type, m.device, m.timestamp_s, it->second));
      }
    }
    std::string why;
    if (m.type == "TRANSFORM") {
      const int dev = TransformDevice(m.device);
      if (dev < 0)
        return Drop(fmt::format(
            "TRANSFORM: unknown device '{}' (Slot0ToReference, Slot1ToReference, ScopeToReference)",
            m.device));
      const std::optional<Pose> pose = igtl_wire::DecodeTransform(m, &why);
      if (!pose) return Drop(why);
      (dev == 2 ? state.camera.pose : state.tools[dev].pose) = *pose;
      if (dev < kToolSlots) posed[static_cast<std::size_t>(dev)] = true;
    } else if (m.type == "STRING") {
      const std::optional<std::string> text = igtl_wire::DecodeString(m, &why);
      if (!text) return Drop(why);
      if (*text == "session end") {
        session_end = true;
      } else if (!ApplyCommandString(model, *text, &state, &latched, &why)) {
        return Drop(why);
      }
    } else {
      return Drop(fmt::format("unsupported message type {} from '{}'", m.type, m.device));
    }
    if (m.timestamp_s > 0) c->last_ts[m.device + "/" + m.type] = m.timestamp_s;
    ++stats.applied;
    cv.notify_all();
  }

  void Close(std::size_t i, const std::string& why) {  // mu held
    opt.log(fmt::format("client {} disconnected: {} (device state kept)", clients[i]->id, why));
    ::close(clients[i]->fd);
    clients.erase(clients.begin() + static_cast<std::ptrdiff_t>(i));
    stats.clients = static_cast<int>(clients.size());
    cv.notify_all();
  }

  void Loop() {
    std::vector<std::uint8_t> buf(64 * 1024);
    while (!stop.load()) {
      std::vector<pollfd> fds;
      {
        std::lock_guard<std::mutex> lock(mu);
        fds.push_back({listen_fd, POLLIN, 0});
        fds.push_back({wake[0], POLLIN, 0});
        for (const auto& c : clients) {
          fds.push_back(
              {c->fd, static_cast<short>(POLLIN | (c->out_pos < c->out.size() ? POLLOUT : 0)), 0});
        }
      }
      if (::poll(fds.data(), fds.size(), 100) < 0 && errno != EINTR) break;
      char drain[64];
      while (::read(wake[0], drain, sizeof(drain)) > 0) {
      }
      std::lock_guard<std::mutex> lock(mu);
      if (fds[0].revents & POLLIN) {
        const int fd = ::accept(listen_fd, nullptr, nullptr);
        if (fd >= 0) {
          if (static_cast<int>(clients.size()) >= opt.max_clients) {
            opt.log("refused a client: too many connections");
            ::close(fd);
          } else {
            igtl_wire::SetNonBlocking(fd);
            auto c = std::make_unique<Client>(opt.max_body_bytes);
            c->fd = fd;
            c->id = ++stats.connections;
            clients.push_back(std::move(c));
            stats.clients = static_cast<int>(clients.size());
            opt.log(fmt::format("client {} connected", stats.connections));
            cv.notify_all();
          }
        }
      }
      // Clients may have been added after fds was built: only look at those polled.
      for (std::size_t k = fds.size(); k-- > 2;) {
        const int fd = fds[k].fd;
        std::size_t i = 0;
        while (i < clients.size() && clients[i]->fd != fd) ++i;
        if (i == clients.size()) continue;
        Client* c = clients[i].get();
        if (fds[k].revents & POLLOUT) {
          const ssize_t n =
              ::send(c->fd, c->out.data() + c->out_pos, c->out.size() - c->out_pos, MSG_NOSIGNAL);
          if (n > 0) c->out_pos += static_cast<std::size_t>(n);
          if (c->out_pos == c->out.size()) {
            c->out.clear();
            c->out_pos = 0;
          }
        }
        if (!(fds[k].revents & (POLLIN | POLLHUP | POLLERR))) continue;
        const ssize_t n = ::recv(c->fd, buf.data(), buf.size(), 0);
        if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) {
          Close(i, n == 0 ? "closed by peer" : std::strerror(errno));
          continue;
        }
        if (n < 0) continue;
        c->parser.Append(buf.data(), static_cast<std::size_t>(n));
        igtl_wire::Message m;
        std::string why;
        for (;;) {
          const auto r = c->parser.Next(&m, &why);
          if (r == igtl_wire::StreamParser::Result::kNeedMore) break;
          if (r == igtl_wire::StreamParser::Result::kDropped) {
            Drop(why);
            continue;
          }
          if (r == igtl_wire::StreamParser::Result::kFatal) {
            Drop(why);
            Close(i, "unrecoverable stream");
            break;
          }
          Handle(c, m);
        }
      }
    }
  }

  void Queue(const std::vector<std::uint8_t>& bytes, std::uint64_t* sent) {  // mu held
    for (auto& c : clients) {
      if (c->out.size() - c->out_pos + bytes.size() > kMaxQueuedBytes) {
        if (!c->overflow_logged)
          opt.log(fmt::format("client {} is not reading: messages to it dropped", c->id));
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

  void Shutdown() {
    Flush();
    if (stop.exchange(true)) return;
    Wake();
    if (thread.joinable()) thread.join();
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
    const auto now = std::chrono::steady_clock::now();
    const auto at = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(t_s));
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
