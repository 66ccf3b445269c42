#pragma once
// Internal: OpenIGTLink (protocol v1/v2 header) framing over a byte stream, and the message
// kinds the live server speaks (TRANSFORM, STRING in, SENSOR out). Sockets are plain POSIX so
// the server can bind a chosen address, use an ephemeral port and poll without blocking.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "arthrosim/core/enum_names.h"
#include "arthrosim/core/types.h"
#include "arthrosim/input/input_source.h"

namespace arthrosim::input::igtl_wire {

inline constexpr std::size_t kHeaderBytes = 58;

/// The device name of each device's TRANSFORM messages.
inline constexpr EnumName<Device> kTransformNames[] = {{Device::kSlot0, "Slot0ToReference"},
                                                       {Device::kSlot1, "Slot1ToReference"},
                                                       {Device::kScope, "ScopeToReference"}};

/// A framed message whose header passed the sanity checks (body not yet CRC-checked).
struct Message {
  std::string type;  ///< "TRANSFORM", "STRING", "SENSOR", ...
  std::string device;
  double timestamp_s = 0;           ///< 0 = not set by the sender
  std::vector<std::uint8_t> bytes;  ///< header + body as received
};

/// Splits a TCP byte stream into messages.
class StreamParser {
 public:
  enum class Result { kNeedMore, kMessage, kDropped, kFatal };
  explicit StreamParser(std::size_t max_body_bytes) : max_body_(max_body_bytes) {}
  void Append(const std::uint8_t* data, std::size_t n);
  /// kMessage: *out filled. kDropped: an oversized body is being skipped (*why says so).
  /// kFatal: the stream cannot be resynchronised (bad header); close the connection.
  Result Next(Message* out, std::string* why);
  /// The bytes received and not yet returned by Next: the start of an incomplete message.
  std::vector<std::uint8_t> Pending() const {
    return {buf_.begin() + static_cast<std::ptrdiff_t>(pos_), buf_.end()};
  }
  /// True while the rest of an oversized body (already reported as kDropped) is being skipped.
  bool Skipping() const { return skip_ > 0; }

 private:
  std::vector<std::uint8_t> buf_;
  std::size_t pos_ = 0;
  std::uint64_t skip_ = 0;
  std::size_t max_body_;
};

std::vector<std::uint8_t> EncodeTransform(const std::string& device, const Pose& pose, double t_s);
std::vector<std::uint8_t> EncodeString(const std::string& device, const std::string& text,
                                       double t_s);
std::vector<std::uint8_t> EncodeSensor(const std::string& device, const Vec3& values, double t_s);

/// Each returns std::nullopt and sets *why if the body is malformed or its CRC is wrong.
std::optional<Pose> DecodeTransform(const Message& m, std::string* why);
std::optional<std::string> DecodeString(const Message& m, std::string* why);
std::optional<Vec3> DecodeSensor(const Message& m, std::string* why);

/// Listening TCP socket on address:port (port 0 = ephemeral); returns fd, sets *bound_port. The
/// backlog is SOMAXCONN: connections the server has not accepted yet wait in the kernel, not in
/// the client's SYN retry (1 s).
/// Throws std::runtime_error on failure.
int Listen(const std::string& address, int port, int* bound_port);
/// Connects to host:port within timeout_s; returns fd or -1.
int Connect(const std::string& host, int port, double timeout_s);
/// Makes fd non-blocking.
void SetNonBlocking(int fd);

}  // namespace arthrosim::input::igtl_wire
