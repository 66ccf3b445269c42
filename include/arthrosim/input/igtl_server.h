#pragma once
// Live devices over OpenIGTLink (docs/haptics.md, docs/trajectory-format.md "Live input"). A
// background thread accepts clients on 127.0.0.1:18944 by default, applies TRANSFORM messages
// (Slot0ToReference, Slot1ToReference, ScopeToReference, or names mapped with
// IgtlServerOptions::device_names) and STRING commands ("slot0 instrument=grasper jaw=0.8
// buttons=1"), and sends the force of each slot back as a SENSOR message (Slot0Force,
// Slot1Force, N) after every step, and live feedback to the trainee as STRING messages from the
// device "Warning". Several clients may be connected at once (e.g. one bridge per hand); each
// device's pose comes from one client at a time. Malformed, oversized, truncated, unknown and
// out-of-order messages are refused with one log line each (rate-limited per kind); state
// survives client disconnects.
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "arthrosim/input/input_source.h"

namespace arthrosim::input {

/// Why a message or a connection was refused; each kind is logged and counted on its own.
enum class Refusal : std::uint8_t {
  kHeader,     ///< a header that cannot be parsed: the stream is out of sync, connection closed
  kOversized,  ///< body larger than max_body_bytes (skipped)
  kCrc,        ///< body CRC does not match the header's
  kMalformed,  ///< wrong body size (truncated), bad length field, not a rigid transform
  kType,       ///< a message type the server does not take (only TRANSFORM, STRING)
  kDevice,     ///< a TRANSFORM device name that is neither a default nor mapped
  kOrder,      ///< timestamp older than the previous one of that device on that connection
  kCommand,    ///< a STRING command with an unknown device, key, instrument or bad value
  kOwner,      ///< a TRANSFORM for a device another client is driving
  kPartial,    ///< the client disconnected in the middle of a message
  kClients,    ///< a connection beyond max_clients (closed at once)
};
inline constexpr int kRefusalKinds = 11;
/// The kind's word in log lines: "header", "oversized", "crc", "malformed", "type", "device",
/// "order", "command", "owner", "partial", "clients".
const char* RefusalName(Refusal kind);

struct IgtlServerOptions {
  std::string bind_address = "127.0.0.1";  ///< IPv4 address to listen on
  int port = 18944;                        ///< 0 = ephemeral (see IgtlServer::port())
  bool realtime = true;                    ///< Frame(t) waits until wall time reaches t
  std::size_t max_body_bytes = 64 * 1024;  ///< larger messages are skipped
  int max_clients = 4;
  /// TRANSFORM device names besides the defaults (a tracker's own names, e.g. StylusToTracker).
  IgtlDeviceNames device_names;
  /// Log lines per kind (each refusal kind, connects, disconnects) written one by one in any
  /// second; the rest of that second is summed up in one line ("... N more in the last 1.0 s").
  int log_lines_per_second = 5;
  /// Where log lines go (default: stderr, "igtl: " prefixed). Called from the network thread.
  std::function<void(const std::string&)> log;
};

struct IgtlServerStats {
  std::uint64_t applied = 0;  ///< messages that changed the device state
  std::uint64_t dropped = 0;  ///< refused messages and connections (sum of refused)
  std::array<std::uint64_t, kRefusalKinds> refused{};  ///< by Refusal
  std::uint64_t ignored = 0;       ///< TRANSFORMs of names mapped to nothing (not logged)
  std::uint64_t connections = 0;   ///< clients accepted so far (not counting kClients refusals)
  std::uint64_t forces_sent = 0;   ///< SENSOR messages queued to clients
  std::uint64_t notices_sent = 0;  ///< STRING messages (Notify) queued to clients
  int clients = 0;                 ///< connected now
};

class IgtlServer : public InputSource {
 public:
  /// Binds and starts the network thread; throws std::runtime_error if it cannot listen.
  IgtlServer(const Model& model, IgtlServerOptions options);
  ~IgtlServer() override;
  IgtlServer(const IgtlServer&) = delete;
  IgtlServer& operator=(const IgtlServer&) = delete;

  /// The port actually bound.
  int port() const;
  /// Latest device state; buttons are OR-ed over everything received since the last Frame. A
  /// slot whose TRANSFORM has not arrived yet has no instrument (-1): it has no pose to be at.
  void Frame(std::int64_t step, double t_s, InputFrame* out) override;
  /// Queues one SENSOR message per slot (force in N, world frame) to every client.
  void Feedback(const FeedbackFrame& feedback) override;
  /// Queues a STRING message, device name "Warning", timestamp t_s, to every connected client.
  void Notify(const std::string& text, double t_s) override;
  /// True after a client sent the STRING "session end" or Stop() was called.
  bool Finished(double t_s) const override;
  /// With realtime pacing: how late (s) the last Frame(t) was called after wall time t.
  double RealtimeLagS() const override;

  IgtlServerStats stats() const;
  /// Blocks until stats().applied >= count or timeout_s passes; returns whether reached.
  bool WaitUntilApplied(std::uint64_t count, double timeout_s) const;
  /// Blocks until a client is connected (or timeout); returns whether one is.
  bool WaitForClient(double timeout_s) const;
  /// Sends what is still queued (up to 1 s), then stops the network thread and closes all
  /// sockets (also done by the destructor).
  void Stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Parses a command STRING into (device, key=value pairs) and applies it to *frame; returns
/// false with *why on any unknown device, key, instrument or bad value (nothing applied).
/// Also used by the client to build messages. Exposed for tests.
bool ApplyCommandString(const Model& model, const std::string& text, InputFrame* frame,
                        std::array<std::uint8_t, kToolSlots>* latched, std::string* why);

}  // namespace arthrosim::input
