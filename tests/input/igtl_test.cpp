// Live OpenIGTLink server on loopback (127.0.0.1, ephemeral ports): streaming, bad messages,
// disconnects, forces back to the client, and record -> replay equality.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <set>
#include <thread>

#include "arthrosim/core/error.h"
#include "arthrosim/core/scope_aim.h"
#include "arthrosim/input/igtl_client.h"
#include "arthrosim/input/igtl_server.h"
#include "arthrosim/input/open_source.h"
#include "arthrosim/input/pose_math.h"
#include "arthrosim/input/recorded_source.h"
#include "arthrosim/input/recorder.h"
#include "igtl_wire.h"
#include "test_model.h"

namespace arthrosim::input {
namespace {

using testing::MakeTestModel;
using testing::TempPath;

struct Log {
  std::mutex mu;
  std::vector<std::string> lines;
  bool Contains(const std::string& s) {
    std::lock_guard<std::mutex> l(mu);
    for (const auto& x : lines) {
      if (x.find(s) != std::string::npos) return true;
    }
    return false;
  }
};

IgtlServerOptions Options(Log* log, bool realtime = false) {
  IgtlServerOptions o;
  o.port = 0;
  o.realtime = realtime;
  o.log = [log](const std::string& s) {
    std::lock_guard<std::mutex> l(log->mu);
    log->lines.push_back(s);
  };
  return o;
}

// A 1 kHz session: slot0 grasper sweeping with short presses, slot1 hook, scope rolling.
SessionTable MakeSession(int samples) {
  SessionTable t;
  t.file = "generated";
  for (int i = 0; i < samples; ++i) {
    const double ts = i * 0.001;
    SessionRow a;
    a.t_s = ts;
    a.device = Device::kSlot0;
    a.instrument = i < samples / 2 ? "grasper" : "scissors";
    a.position_mm = Vec3(10 * std::sin(ts * 9), 5 * ts, -3 + ts);
    a.orientation = AimAlong(Vec3(std::cos(ts), 0.3, 1), 0.5 * ts);
    a.jaw = 0.5 + 0.5 * std::sin(ts * 20);
    a.buttons = (i % 23 == 0) ? 1 : 0;  // 1 ms presses
    SessionRow b = a;
    b.device = Device::kSlot1;
    b.instrument = "hook";
    b.position_mm = Vec3(1, 2, 3) * ts;
    b.jaw = 0;
    b.buttons = (i % 41 == 0) ? 2 : 0;
    SessionRow c;
    c.t_s = ts;
    c.device = Device::kScope;
    c.position_mm = Vec3(-30, 0, 8) + Vec3(ts, ts, 0);
    c.orientation = AimScopeView(c.position_mm, Vec3(0, 0, 5), 0.0);
    c.lens_roll_rad = ts;
    c.head_roll_rad = -ts;
    t.rows.push_back(a);
    t.rows.push_back(b);
    t.rows.push_back(c);
  }
  return t;
}

void SendAll(int fd, const std::vector<std::uint8_t>& b) {
  std::size_t off = 0;
  while (off < b.size()) {
    const ssize_t n = ::send(fd, b.data() + off, b.size() - off, MSG_NOSIGNAL);
    if (n > 0) {
      off += static_cast<std::size_t>(n);
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
}

TEST(Igtl, LoopbackStreamingAppliesPosesAndCommands) {
  const Model m = MakeTestModel();
  Log log;
  IgtlServer server(m, Options(&log));
  ASSERT_GT(server.port(), 0);
  const SessionTable table = MakeSession(100);
  StreamClientOptions co;
  co.port = server.port();
  co.speed = 0;
  co.linger_s = 0;
  StreamResult r;
  std::thread client([&] { r = StreamSession(table, co); });
  client.join();
  EXPECT_EQ(r.messages_sent, 2 * table.rows.size() + 1);
  ASSERT_TRUE(server.WaitUntilApplied(2 * table.rows.size(), 5.0));
  for (int i = 0; i < 200 && !server.Finished(0); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_TRUE(server.Finished(0));  // "session end"
  InputFrame f;
  server.Frame(0, 0.0, &f);
  const SessionRow& a = table.rows[table.rows.size() - 3];
  const SessionRow& c = table.rows.back();
  EXPECT_EQ(f.tools[0].instrument, m.FindInstrument("scissors"));
  EXPECT_EQ(f.tools[1].instrument, m.FindInstrument("hook"));
  EXPECT_NEAR((f.tools[0].pose.position_mm - a.position_mm).norm(), 0, 1e-5);  // float on the wire
  EXPECT_NEAR(f.tools[0].pose.orientation.angularDistance(a.orientation), 0, 1e-6);
  EXPECT_EQ(f.tools[0].jaw, a.jaw);  // STRING carries 17 digits
  EXPECT_EQ(f.camera.lens_roll_rad, c.lens_roll_rad);
  EXPECT_NEAR((f.camera.pose.position_mm - c.position_mm).norm(), 0, 1e-5);
  // Presses since the last frame are latched: rows 0, 23, 46, 69, 92 pressed button 1.
  EXPECT_EQ(f.tools[0].buttons & 1, 1);
  server.Frame(1, 0.01, &f);
  EXPECT_EQ(f.tools[0].buttons, 0);  // the last sample had it released
  EXPECT_EQ(server.stats().dropped, 0u);
}

// An instrument chosen before its first pose arrives is not inserted (it would sit at the
// identity pose, inside the anatomy, and push on it): it appears with its first TRANSFORM.
TEST(Igtl, InstrumentHasNoPoseUntilItsFirstTransform) {
  const Model m = MakeTestModel();
  Log log;
  IgtlServer server(m, Options(&log));
  const int fd = igtl_wire::Connect("127.0.0.1", server.port(), 2.0);
  ASSERT_GE(fd, 0);
  SendAll(fd, igtl_wire::EncodeString("Command", "slot0 instrument=grasper", 1.0));
  ASSERT_TRUE(server.WaitUntilApplied(1, 2.0));
  InputFrame f;
  server.Frame(1, 0.02, &f);
  EXPECT_EQ(f.tools[0].instrument, -1);
  Pose p;
  p.position_mm = Vec3(4, 5, 6);
  SendAll(fd, igtl_wire::EncodeTransform("Slot0ToReference", p, 2.0));
  ASSERT_TRUE(server.WaitUntilApplied(2, 2.0));
  server.Frame(2, 0.04, &f);
  EXPECT_EQ(f.tools[0].instrument, m.FindInstrument("grasper"));
  EXPECT_NEAR((f.tools[0].pose.position_mm - p.position_mm).norm(), 0, 1e-5);
  ::close(fd);
}

// A step that starts late (the previous one took longer than dt) is reported, not hidden.
TEST(Igtl, RealtimePacingMeasuresTheLag) {
  const Model m = MakeTestModel();
  Log log;
  IgtlServer server(m, Options(&log, /*realtime=*/true));
  InputFrame f;
  server.Frame(1, 0.02, &f);
  EXPECT_EQ(server.RealtimeLagS(), 0.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // a 300 ms step
  server.Frame(2, 0.04, &f);
  EXPECT_GE(server.RealtimeLagS(), 0.25);
}

TEST(Igtl, MalformedOversizedAndOutOfOrderMessagesAreDropped) {
  const Model m = MakeTestModel();
  Log log;
  IgtlServerOptions o = Options(&log);
  o.max_body_bytes = 4096;
  IgtlServer server(m, o);
  int fd = igtl_wire::Connect("127.0.0.1", server.port(), 2.0);
  ASSERT_GE(fd, 0);
  Pose a;
  a.position_mm = Vec3(1, 2, 3);
  Pose b;
  b.position_mm = Vec3(9, 9, 9);
  SendAll(fd, igtl_wire::EncodeTransform("Slot0ToReference", a, 5.0));
  ASSERT_TRUE(server.WaitUntilApplied(1, 2.0));
  SendAll(fd, igtl_wire::EncodeTransform("Slot0ToReference", b, 4.0));  // older: out of order
  std::vector<std::uint8_t> bad_crc = igtl_wire::EncodeTransform("Slot0ToReference", b, 6.0);
  bad_crc.back() ^= 0x55;
  SendAll(fd, bad_crc);
  SendAll(fd, igtl_wire::EncodeTransform("Slot7ToReference", b, 6.0));
  SendAll(fd, igtl_wire::EncodeString("Command", "slot0 speed=3", 6.0));
  SendAll(fd, igtl_wire::EncodeString("Command", "slot0 instrument=laser", 6.0));
  SendAll(fd, igtl_wire::EncodeString("Command", "slot0 jaw=nan", 6.0));
  SendAll(fd, igtl_wire::EncodeString("Command",
                                      "slot3 jaw=1\nigtl: forged " + std::string(500, 'x'), 6.0));
  std::vector<std::uint8_t> other = igtl_wire::EncodeString("Pointer", "x", 6.0);
  std::memcpy(other.data() + 2, "POSITION\0\0\0\0", 12);  // unsupported type, valid framing
  SendAll(fd, other);
  // Oversized: a header announcing 100 kB, then the 100 kB, then a good message.
  std::vector<std::uint8_t> big = igtl_wire::EncodeString("Command", "slot0 jaw=1", 6.0);
  big.resize(igtl_wire::kHeaderBytes);
  const std::uint64_t size = 100000;
  for (int i = 0; i < 8; ++i) big[42 + i] = static_cast<std::uint8_t>(size >> (56 - 8 * i));
  big.resize(igtl_wire::kHeaderBytes + size, 0xab);
  SendAll(fd, big);
  SendAll(fd, igtl_wire::EncodeString("Command", "slot0 jaw=0.5 instrument=grasper", 7.0));
  ASSERT_TRUE(server.WaitUntilApplied(2, 2.0));
  EXPECT_EQ(server.stats().dropped, 9u);
  InputFrame f;
  server.Frame(0, 0, &f);
  EXPECT_EQ(f.tools[0].pose.position_mm, Vec3(1, 2, 3));
  EXPECT_EQ(f.tools[0].jaw, 0.5);
  EXPECT_EQ(f.tools[0].instrument, m.FindInstrument("grasper"));
  EXPECT_TRUE(log.Contains("out of order"));
  EXPECT_TRUE(log.Contains("CRC mismatch"));
  EXPECT_TRUE(log.Contains("refused device from client 1 (127.0.0.1:"));
  EXPECT_TRUE(log.Contains("TRANSFORM 'Slot7ToReference': unknown device name"));
  EXPECT_TRUE(log.Contains("unknown key 'speed'"));
  EXPECT_TRUE(log.Contains("STRING 'slot3 jaw=1?igtl: forged xxx"));  // one line, cut short
  EXPECT_TRUE(log.Contains("xxx': unknown device 'slot3'"));
  {
    std::lock_guard<std::mutex> l(log.mu);
    for (const std::string& line : log.lines) EXPECT_LT(line.size(), 500u) << line;
  }
  EXPECT_TRUE(log.Contains("exceeds the limit of 4096"));
  EXPECT_TRUE(log.Contains("POSITION 'Pointer': unsupported message type"));
  const IgtlServerStats st = server.stats();
  for (Refusal k :
       {Refusal::kOrder, Refusal::kCrc, Refusal::kDevice, Refusal::kType, Refusal::kOversized})
    EXPECT_EQ(st.refused[static_cast<std::size_t>(k)], 1u) << RefusalName(k);
  EXPECT_EQ(st.refused[static_cast<std::size_t>(Refusal::kCommand)], 4u);
  // Garbage that cannot be resynchronised closes that connection; the server lives on.
  std::vector<std::uint8_t> junk(80, 0xff);
  SendAll(fd, junk);
  for (int i = 0; i < 200 && server.stats().clients > 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(server.stats().clients, 0);
  EXPECT_TRUE(log.Contains("refused header from client 1"));
  ::close(fd);
  fd = igtl_wire::Connect("127.0.0.1", server.port(), 2.0);
  ASSERT_GE(fd, 0);
  SendAll(fd, igtl_wire::EncodeTransform("Slot1ToReference", b, 1.0));
  EXPECT_TRUE(server.WaitUntilApplied(3, 2.0));
  ::close(fd);
}

// A message without a timestamp has 0 on the wire. OpenIGTLink leaves the field as it finds it:
// 'session end' (unstamped) went out with an earlier message's time and could be refused as out
// of order, so that the session never ended.
TEST(Igtl, UnstampedMessagesCarryNoTimestamp) {
  for (int i = 0; i < 3; ++i) {
    const std::vector<std::uint8_t> stamped = igtl_wire::EncodeString("Command", "x", 5.5 + i);
    const std::vector<std::uint8_t> unstamped =
        igtl_wire::EncodeString("Command", "session end", 0);
    EXPECT_NE(std::vector<std::uint8_t>(stamped.begin() + 34, stamped.begin() + 42),
              std::vector<std::uint8_t>(8, 0));
    EXPECT_EQ(std::vector<std::uint8_t>(unstamped.begin() + 34, unstamped.begin() + 42),
              std::vector<std::uint8_t>(8, 0));
  }
}

long RssKb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  }
  return 0;
}

// A stream whose every read ends inside a message body (the rest of one message, then the
// header and a byte of the next): the parser keeps only the incomplete message. It once kept
// everything until a read ended between messages: 500 000 transforms grew it by 53 MB.
TEST(Igtl, ParserHoldsOnlyTheIncompleteMessage) {
  igtl_wire::StreamParser parser(1 << 16);
  const std::vector<std::uint8_t> m = igtl_wire::EncodeTransform("Slot0ToReference", Pose{}, 1.0);
  const std::size_t cut = igtl_wire::kHeaderBytes + 1;
  std::vector<std::uint8_t> chunk(m.begin() + static_cast<std::ptrdiff_t>(cut), m.end());
  chunk.insert(chunk.end(), m.begin(), m.begin() + static_cast<std::ptrdiff_t>(cut));
  parser.Append(m.data(), cut);
  igtl_wire::Message out;
  std::string why;
  const long before = RssKb();
  int messages = 0;
  for (int i = 0; i < 500000; ++i) {
    parser.Append(chunk.data(), chunk.size());
    while (parser.Next(&out, &why) == igtl_wire::StreamParser::Result::kMessage) ++messages;
  }
  EXPECT_EQ(messages, 500000);
  EXPECT_EQ(parser.Pending().size(), cut);
#if !defined(__SANITIZE_ADDRESS__)        // ASan's quarantine keeps freed blocks: RSS says nothing
  EXPECT_LT(RssKb() - before, 8 * 1024);  // kB
#else
  (void)before;
#endif
}

// A burst of connects that each send half a header and hang up, as fast as the client can: each
// is accepted at once (the backlog once held 4, and the server took one connection per poll
// round, so a fifth connect's SYN was dropped and repeated by the kernel 1 s later), and each
// cut-short message is refused with a log line.
TEST(Igtl, BackToBackConnectsAreAcceptedAtOnce) {
  const Model m = MakeTestModel();
  Log log;
  IgtlServer server(m, Options(&log));
  const std::vector<std::uint8_t> half(igtl_wire::kHeaderBytes / 2, 0);
  std::vector<std::uint8_t> head = igtl_wire::EncodeString("Command", "slot0 jaw=1", 1.0);
  head.resize(20);
  double worst_s = 0;
  for (int i = 0; i < 50; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const int fd = igtl_wire::Connect("127.0.0.1", server.port(), 5.0);
    worst_s = std::max(
        worst_s, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    ASSERT_GE(fd, 0);
    SendAll(fd, head);
    ::close(fd);
  }
  EXPECT_LT(worst_s, 0.05);
  for (int i = 0;
       i < 200 && server.stats().refused[static_cast<std::size_t>(Refusal::kPartial)] < 50; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(server.stats().connections, 50u);
  EXPECT_EQ(server.stats().refused[static_cast<std::size_t>(Refusal::kPartial)], 50u);
  EXPECT_TRUE(log.Contains("disconnected mid-message: 20 of the 58 header bytes"));
}

// Two bridges at once, one per hand: each drives its own slot and gets every force; a pose for
// the other's slot is refused while that one is driving it, and taken once it has gone.
TEST(Igtl, TwoClientsDriveOneDeviceEach) {
  const Model m = MakeTestModel();
  Log log;
  IgtlServer server(m, Options(&log));
  const int a = igtl_wire::Connect("127.0.0.1", server.port(), 2.0);
  const int b = igtl_wire::Connect("127.0.0.1", server.port(), 2.0);
  ASSERT_GE(a, 0);
  ASSERT_GE(b, 0);
  Pose pa, pb, pc;
  pa.position_mm = Vec3(1, 0, 0);
  pb.position_mm = Vec3(0, 2, 0);
  pc.position_mm = Vec3(0, 0, 3);
  SendAll(a, igtl_wire::EncodeTransform("Slot0ToReference", pa, 1.0));
  ASSERT_TRUE(server.WaitUntilApplied(1, 2.0));
  SendAll(b, igtl_wire::EncodeTransform("Slot1ToReference", pb, 1.0));
  ASSERT_TRUE(server.WaitUntilApplied(2, 2.0));
  SendAll(b, igtl_wire::EncodeTransform("Slot0ToReference", pc, 2.0));
  for (int i = 0; i < 200 && server.stats().dropped == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(server.stats().refused[static_cast<std::size_t>(Refusal::kOwner)], 1u);
  EXPECT_TRUE(log.Contains("refused owner from client 2 (127.0.0.1:"));
  EXPECT_TRUE(log.Contains("slot0 is driven by client 1"));
  EXPECT_EQ(server.stats().clients, 2);
  InputFrame f;
  server.Frame(1, 0.02, &f);
  EXPECT_EQ(f.tools[0].pose.position_mm, pa.position_mm);
  EXPECT_EQ(f.tools[1].pose.position_mm, pb.position_mm);
  server.Feedback(FeedbackFrame{});
  for (const int fd : {a, b}) {  // both get the step's two forces
    igtl_wire::StreamParser parser(1 << 16);
    igtl_wire::Message msg;
    std::string why;
    int forces = 0;
    for (int i = 0; i < 200 && forces < 2; ++i) {
      std::uint8_t buf[1024];
      const ssize_t n = ::recv(fd, buf, sizeof(buf), MSG_DONTWAIT);
      if (n > 0) parser.Append(buf, static_cast<std::size_t>(n));
      while (parser.Next(&msg, &why) == igtl_wire::StreamParser::Result::kMessage) ++forces;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    EXPECT_EQ(forces, 2) << "client fd " << fd;
  }
  ::close(a);
  for (int i = 0; i < 200 && server.stats().clients > 1; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  SendAll(b, igtl_wire::EncodeTransform("Slot0ToReference", pc, 3.0));
  ASSERT_TRUE(server.WaitUntilApplied(3, 2.0));
  server.Frame(2, 0.04, &f);
  EXPECT_EQ(f.tools[0].pose.position_mm, pc.position_mm);
  ::close(b);
}

// A tracker's own names drive a slot or the scope without renaming on the device side; names
// mapped to nothing are dropped silently.
TEST(Igtl, MappedDeviceNamesDriveTheirDevice) {
  const Model m = MakeTestModel();
  Log log;
  IgtlServerOptions o = Options(&log);
  AddIgtlDeviceName("StylusToTracker=slot0", &o.device_names);
  AddIgtlDeviceName("ProbeToTracker=scope", &o.device_names);
  AddIgtlDeviceName("ReferenceToTracker=ignore", &o.device_names);
  IgtlServer server(m, o);
  EXPECT_TRUE(log.Contains("TRANSFORM device names: ProbeToTracker -> scope"));
  const int fd = igtl_wire::Connect("127.0.0.1", server.port(), 2.0);
  ASSERT_GE(fd, 0);
  Pose p, q;
  p.position_mm = Vec3(4, 5, 6);
  q.position_mm = Vec3(-1, -2, -3);
  SendAll(fd, igtl_wire::EncodeTransform("ReferenceToTracker", q, 1.0));
  SendAll(fd, igtl_wire::EncodeTransform("StylusToTracker", p, 1.0));
  SendAll(fd, igtl_wire::EncodeTransform("ProbeToTracker", q, 1.0));
  ASSERT_TRUE(server.WaitUntilApplied(2, 2.0));
  InputFrame f;
  server.Frame(1, 0.02, &f);
  EXPECT_EQ(f.tools[0].pose.position_mm, p.position_mm);
  EXPECT_EQ(f.camera.pose.position_mm, q.position_mm);
  EXPECT_EQ(server.stats().ignored, 1u);
  EXPECT_EQ(server.stats().dropped, 0u);
  ::close(fd);
}

TEST(Igtl, DeviceMappingRejectsBadSpecs) {
  IgtlDeviceNames names;
  AddIgtlDeviceName("StylusToTracker=slot1", &names);
  AddIgtlDeviceName("StylusToTracker=slot1", &names);  // the same again is fine
  EXPECT_EQ(names.at("StylusToTracker"), Device::kSlot1);
  for (const char* bad : {"StylusToTracker=slot0", "X=slot3", "X=camera", "X", "=slot0",
                          "A name=slot0", "ABCDEFGHIJKLMNOPQRSTU=slot0"}) {
    EXPECT_THROW(AddIgtlDeviceName(bad, &names), InputError) << bad;
  }
  try {
    AddIgtlDeviceName("X=hand", &names);
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown target 'hand' (slot0, slot1, scope, ignore)"),
              std::string::npos)
        << e.what();
  }
}

// A flood of one bad kind writes a few lines a second and one count for the rest.
TEST(Igtl, RefusalLogIsLimitedPerKind) {
  const Model m = MakeTestModel();
  Log log;
  IgtlServer server(m, Options(&log));
  const int fd = igtl_wire::Connect("127.0.0.1", server.port(), 2.0);
  ASSERT_GE(fd, 0);
  std::vector<std::uint8_t> bad = igtl_wire::EncodeTransform("Slot0ToReference", Pose{}, 1.0);
  bad.back() ^= 0x55;
  std::vector<std::uint8_t> flood;
  for (int i = 0; i < 500; ++i) flood.insert(flood.end(), bad.begin(), bad.end());
  SendAll(fd, flood);
  SendAll(fd, igtl_wire::EncodeTransform("Slot7ToReference", Pose{}, 1.0));
  for (int i = 0; i < 400 && server.stats().dropped < 501; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ::close(fd);
  server.Stop();
  std::uint64_t lines = 0, summed = 0;
  for (const std::string& l : log.lines) {
    if (l.rfind("refused crc from client 1", 0) == 0) ++lines;
    unsigned long long n = 0;
    if (std::sscanf(l.c_str(), "refused crc: %llu more", &n) == 1) summed += n;
  }
  EXPECT_EQ(lines, 5u);
  EXPECT_EQ(lines + summed, 500u);
  EXPECT_TRUE(log.Contains("refused device from client 1"));  // its own kind: not held back
  EXPECT_TRUE(log.Contains("refused this run: crc 500, device 1"));
}

TEST(Igtl, DisconnectKeepsStateAndReconnectWorks) {
  const Model m = MakeTestModel();
  Log log;
  IgtlServer server(m, Options(&log));
  Pose a, b;
  a.position_mm = Vec3(4, 5, 6);
  b.position_mm = Vec3(7, 8, 9);
  int fd = igtl_wire::Connect("127.0.0.1", server.port(), 2.0);
  SendAll(fd, igtl_wire::EncodeTransform("ScopeToReference", a, 10.0));
  SendAll(fd, igtl_wire::EncodeString("Command", "scope lens_roll=0.25", 10.0));
  ASSERT_TRUE(server.WaitUntilApplied(2, 2.0));
  ::close(fd);
  for (int i = 0; i < 200 && server.stats().clients > 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(server.stats().clients, 0);
  InputFrame f;
  server.Frame(0, 0, &f);
  EXPECT_EQ(f.camera.pose.position_mm, a.position_mm);
  EXPECT_EQ(f.camera.lens_roll_rad, 0.25);
  EXPECT_FALSE(server.Finished(0));
  fd = igtl_wire::Connect("127.0.0.1", server.port(), 2.0);
  SendAll(fd, igtl_wire::EncodeTransform("ScopeToReference", b, 1.0));  // new connection, new clock
  ASSERT_TRUE(server.WaitUntilApplied(3, 2.0));
  server.Frame(1, 0.02, &f);
  EXPECT_EQ(f.camera.pose.position_mm, b.position_mm);
  EXPECT_EQ(f.camera.lens_roll_rad, 0.25);
  EXPECT_EQ(server.stats().connections, 2u);
  EXPECT_TRUE(log.Contains("device state kept"));
  ::close(fd);
}

TEST(Igtl, ForcesArriveAtTheClient) {
  const Model m = MakeTestModel();
  Log log;
  IgtlServer server(m, Options(&log));
  const SessionTable table = MakeSession(5);
  StreamClientOptions co;
  co.port = server.port();
  co.speed = 0;
  co.linger_s = 1.0;
  co.send_end = false;
  StreamResult r;
  std::thread client([&] { r = StreamSession(table, co); });
  ASSERT_TRUE(server.WaitUntilApplied(2 * table.rows.size(), 5.0));
  for (int k = 1; k <= 5; ++k) {
    InputFrame f;
    server.Frame(k, k * 0.02, &f);
    FeedbackFrame fb;
    fb.force_n[0] = Vec3(0.1 * k, -0.2, 1.0 / 3.0);
    fb.force_n[1] = Vec3(0, k, 0);
    server.Feedback(fb);
  }
  client.join();
  ASSERT_EQ(r.forces.size(), 10u);
  for (int k = 1; k <= 5; ++k) {
    const ForceSample& s0 = r.forces[2 * (k - 1)];
    const ForceSample& s1 = r.forces[2 * (k - 1) + 1];
    EXPECT_EQ(s0.slot, 0);
    EXPECT_EQ(s1.slot, 1);
    EXPECT_EQ(s0.force_n, Vec3(0.1 * k, -0.2, 1.0 / 3.0));  // float64 on the wire: exact
    EXPECT_EQ(s1.force_n, Vec3(0, k, 0));
    EXPECT_NEAR(s0.t_s, k * 0.02, 1e-9);
  }
  EXPECT_EQ(server.stats().forces_sent, 10u);
}

TEST(Igtl, RecordedLiveRunReplaysBitForBit) {
  const Model m = MakeTestModel();
  Log log;
  auto owned = std::make_unique<IgtlServer>(m, Options(&log, /*realtime=*/true));
  IgtlServer* server = owned.get();
  const std::string path = TempPath("live_session.csv");
  RecordingSource rec(std::move(owned), path, m);
  const SessionTable table = MakeSession(400);  // 0.4 s at 1 kHz
  StreamClientOptions co;
  co.port = server->port();
  co.speed = 1.0;
  co.linger_s = 0;
  std::thread client([&] { StreamSession(table, co); });
  ASSERT_TRUE(server->WaitForClient(5.0));
  const double dt = 0.01;
  std::vector<InputFrame> live;
  for (int k = 0; k < 45; ++k) {  // paced to wall time by the server
    InputFrame f;
    rec.Frame(k, k * dt, &f);
    live.push_back(f);
  }
  client.join();
  RecordedSource replay(ReadSessionCsv(path), m, dt);
  std::set<double> xs;
  int pressed = 0;
  for (int k = 0; k < 45; ++k) {
    InputFrame f;
    replay.Frame(k, k * dt, &f);
    ASSERT_TRUE(BitwiseEqual(f, live[k])) << "step " << k;
    xs.insert(live[k].tools[0].pose.position_mm.x());
    pressed += live[k].tools[0].buttons;
  }
  EXPECT_GT(xs.size(), 10u);  // the live run did move
  EXPECT_GT(pressed, 3);      // and 1 ms presses were latched into steps
}

}  // namespace
}  // namespace arthrosim::input
