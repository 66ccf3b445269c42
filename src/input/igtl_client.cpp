#include "arthrosim/input/igtl_client.h"

#include <fmt/format.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <thread>

#include "igtl_wire.h"

namespace arthrosim::input {
namespace {

const char* TransformName(Device d) { return NameIn(igtl_wire::kTransformNames, d, ""); }

class Connection {
 public:
  Connection(const StreamClientOptions& o) : parser_(1 << 16) {
    fd_ = igtl_wire::Connect(o.host, o.port, o.connect_timeout_s);
    if (fd_ < 0) throw std::runtime_error(fmt::format("cannot connect to {}:{}", o.host, o.port));
  }
  ~Connection() { ::close(fd_); }

  void Send(const std::vector<std::uint8_t>& bytes, StreamResult* r) {
    std::size_t off = 0;
    while (off < bytes.size()) {
      const ssize_t n = ::send(fd_, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
      if (n > 0) {
        off += static_cast<std::size_t>(n);
      } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        Receive(10, r);  // server busy: read its forces meanwhile so neither side blocks
      } else {
        throw std::runtime_error("connection lost while sending");
      }
    }
    ++r->messages_sent;
  }

  /// Reads whatever arrives within timeout_ms and collects SENSOR forces and STRING notices.
  /// Returns false once the server has closed the connection.
  bool Receive(int timeout_ms, StreamResult* r) {
    pollfd p{fd_, POLLIN | POLLOUT, 0};
    p.events = POLLIN;
    if (::poll(&p, 1, timeout_ms) <= 0) return true;
    std::uint8_t buf[8192];
    bool open = true;
    for (;;) {
      const ssize_t n = ::recv(fd_, buf, sizeof(buf), 0);
      if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR))
        open = false;
      if (n <= 0) break;
      parser_.Append(buf, static_cast<std::size_t>(n));
    }
    igtl_wire::Message m;
    std::string why;
    for (;;) {
      const auto res = parser_.Next(&m, &why);
      if (res == igtl_wire::StreamParser::Result::kNeedMore ||
          res == igtl_wire::StreamParser::Result::kFatal)
        break;
      if (res != igtl_wire::StreamParser::Result::kMessage) continue;
      if (m.type == "STRING") {
        const std::optional<std::string> text = igtl_wire::DecodeString(m, &why);
        if (text) r->notices.push_back({m.timestamp_s, m.device, *text});
        continue;
      }
      if (m.type != "SENSOR") continue;
      const int slot = m.device == "Slot0Force" ? 0 : m.device == "Slot1Force" ? 1 : -1;
      const std::optional<Vec3> f = igtl_wire::DecodeSensor(m, &why);
      if (slot >= 0 && f) r->forces.push_back({m.timestamp_s, slot, *f});
    }
    return open;
  }

 private:
  int fd_ = -1;
  igtl_wire::StreamParser parser_;
};

}  // namespace

std::string CommandStringForRow(const SessionRow& row) {
  if (row.device == Device::kScope) {
    return fmt::format("scope lens_roll={:.17g} head_roll={:.17g}", row.lens_roll_rad,
                       row.head_roll_rad);
  }
  return fmt::format("{} instrument={} jaw={:.17g} buttons={}", DeviceName(row.device),
                     row.instrument.empty() ? "none" : row.instrument, row.jaw,
                     static_cast<int>(row.buttons));
}

StreamResult StreamSession(const SessionTable& table, const StreamClientOptions& o,
                           const std::atomic<bool>* cancel) {
  StreamResult r;
  Connection c(o);
  const auto start = std::chrono::steady_clock::now();
  const double t0 = table.rows.empty() ? 0.0 : table.rows.front().t_s;
  for (const SessionRow& row : table.rows) {
    if (cancel != nullptr && cancel->load()) break;
    if (o.speed > 0) {
      const auto due = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                   std::chrono::duration<double>((row.t_s - t0) / o.speed));
      while (std::chrono::steady_clock::now() < due) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
            due - std::chrono::steady_clock::now());
        c.Receive(static_cast<int>(std::max<std::int64_t>(0, left.count())), &r);
        if (left.count() <= 0) break;
      }
    }
    Pose pose{row.position_mm, row.orientation};
    // Timestamps are the recording's own (offset so they are > 0; 0 means "unset").
    const double ts = row.t_s - t0 + 1.0;
    c.Send(igtl_wire::EncodeTransform(TransformName(row.device), pose, ts), &r);
    c.Send(igtl_wire::EncodeString("Command", CommandStringForRow(row), ts), &r);
    c.Receive(0, &r);
  }
  if (o.send_end) c.Send(igtl_wire::EncodeString("Command", "session end", 0), &r);
  const auto end = std::chrono::steady_clock::now() +
                   std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                       std::chrono::duration<double>(o.linger_s));
  while (std::chrono::steady_clock::now() < end && c.Receive(10, &r)) {
  }
  return r;
}

}  // namespace arthrosim::input
