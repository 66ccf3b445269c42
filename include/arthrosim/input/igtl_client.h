#pragma once
// Streams a recorded session to an IgtlServer over OpenIGTLink, as a device bridge would
// (TRANSFORM per device + a command STRING per sample), and collects the SENSOR force messages
// and the STRING notices (live feedback) the server sends back. Used by the igtl_stream_client
// program and the loopback tests.
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "arthrosim/input/session.h"

namespace arthrosim::input {

struct StreamClientOptions {
  std::string host = "127.0.0.1";
  int port = 18944;
  double speed = 1.0;  ///< 1 = the recording's own pace; 0 = as fast as possible
  /// Keep receiving forces and notices this long after the last sample, s (less if the server
  /// closes the connection first).
  double linger_s = 0.2;
  double connect_timeout_s = 5;
  bool send_end = true;  ///< finish with the STRING "session end"
};

struct ForceSample {
  double t_s = 0;  ///< the server's step time of the force (message timestamp)
  int slot = 0;
  Vec3 force_n = Vec3::Zero();
};

/// A STRING message from the server (live feedback, device "Warning").
struct NoticeSample {
  double t_s = 0;  ///< the server's simulated time of the notice (message timestamp)
  std::string device;
  std::string text;
};

struct StreamResult {
  std::uint64_t messages_sent = 0;
  std::vector<ForceSample> forces;
  std::vector<NoticeSample> notices;  ///< in arrival order
};

/// The command STRING that carries a row's non-pose data ("slot0 instrument=grasper jaw=0.5
/// buttons=1", "scope lens_roll=0.1 head_roll=0"); doubles round-trip exact.
std::string CommandStringForRow(const SessionRow& row);

/// Streams `table` in file order. Throws std::runtime_error if it cannot connect or the server
/// goes away. `cancel`, if given, stops the stream early when set.
StreamResult StreamSession(const SessionTable& table, const StreamClientOptions& options,
                           const std::atomic<bool>* cancel = nullptr);

}  // namespace arthrosim::input
