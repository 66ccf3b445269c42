#include "igtl_wire.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <igtlMessageHeader.h>
#include <igtlSensorMessage.h>
#include <igtlStringMessage.h>
#include <igtlTransformMessage.h>
#include <igtl_unit.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace arthrosim::input::igtl_wire {
namespace {

std::uint64_t BigEndian(const std::uint8_t* p, int n) {
  std::uint64_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | p[i];
  return v;
}

std::string FixedString(const std::uint8_t* p, std::size_t n) {
  std::size_t len = 0;
  while (len < n && p[len] != 0) ++len;
  return std::string(reinterpret_cast<const char*>(p), len);
}

bool Printable(const std::uint8_t* p, std::size_t n) {
  bool ended = false;
  for (std::size_t i = 0; i < n; ++i) {
    if (p[i] == 0) {
      ended = true;
    } else if (ended || p[i] < 0x20 || p[i] > 0x7e) {
      return false;
    }
  }
  return true;
}

std::vector<std::uint8_t> Packed(igtl::MessageBase* m) {
  m->Pack();
  const auto* p = static_cast<const std::uint8_t*>(m->GetPackPointer());
  return std::vector<std::uint8_t>(p, p + m->GetPackSize());
}

void Stamp(igtl::MessageBase* m, double t_s) {
  if (!(t_s > 0)) {  // 0 means "no timestamp"; unset, OpenIGTLink sends a stale one
    m->SetTimeStamp(0, 0);
    return;
  }
  const double sec = std::floor(t_s);
  const double frac = std::ldexp(t_s - sec, 32);
  m->SetTimeStamp(static_cast<unsigned int>(sec),
                  static_cast<unsigned int>(std::min(frac, 4294967295.0)));
}

/// Unpacks `m` into `msg` with a CRC check; false (and *why) on failure.
bool UnpackInto(const Message& m, igtl::MessageBase* msg, std::string* why) {
  igtl::MessageHeader::Pointer h = igtl::MessageHeader::New();
  h->InitPack();
  std::memcpy(h->GetPackPointer(), m.bytes.data(), kHeaderBytes);
  h->Unpack();
  msg->SetMessageHeader(h);
  msg->AllocatePack();
  // OpenIGTLink sizes the body from the header it unpacked (a version 2 header may leave it
  // smaller than the bytes received): copy only into a body of exactly the message's size.
  if (msg->GetPackBodySize() < 0 ||
      static_cast<std::size_t>(msg->GetPackBodySize()) != m.bytes.size() - kHeaderBytes) {
    *why = fmt::format("{} '{}': malformed header", m.type, m.device);
    return false;
  }
  std::memcpy(msg->GetPackBodyPointer(), m.bytes.data() + kHeaderBytes,
              m.bytes.size() - kHeaderBytes);
  const int r = msg->Unpack(1);
  if (!(r & igtl::MessageHeader::UNPACK_BODY)) {
    *why = fmt::format("{} '{}': CRC mismatch or malformed body", m.type, m.device);
    return false;
  }
  return true;
}

}  // namespace

void StreamParser::Append(const std::uint8_t* data, std::size_t n) {
  if (pos_ > 0) {  // drop what Next consumed: the buffer holds at most one incomplete message
    buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(pos_));
    pos_ = 0;
  }
  buf_.insert(buf_.end(), data, data + n);
}

StreamParser::Result StreamParser::Next(Message* out, std::string* why) {
  if (skip_ > 0) {
    const std::uint64_t k = std::min<std::uint64_t>(skip_, buf_.size() - pos_);
    pos_ += k;
    skip_ -= k;
    if (skip_ > 0) return Result::kNeedMore;
  }
  if (buf_.size() - pos_ < kHeaderBytes) {
    if (pos_ > 0) {  // compact
      buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(pos_));
      pos_ = 0;
    }
    return Result::kNeedMore;
  }
  const std::uint8_t* h = buf_.data() + pos_;
  const std::uint64_t version = BigEndian(h, 2);
  if ((version != 1 && version != 2) || !Printable(h + 2, 12) || !Printable(h + 14, 20) ||
      h[2] == 0) {
    *why = fmt::format("bad header (version {}): stream out of sync", version);
    return Result::kFatal;
  }
  const std::string type = FixedString(h + 2, 12);
  const std::string device = FixedString(h + 14, 20);
  const std::uint64_t ts = BigEndian(h + 34, 8);
  const std::uint64_t body = BigEndian(h + 42, 8);
  if (body > max_body_) {
    *why = fmt::format("{} '{}': body of {} bytes exceeds the limit of {}", type, device, body,
                       max_body_);
    pos_ += kHeaderBytes;
    skip_ = body;
    return Result::kDropped;
  }
  if (buf_.size() - pos_ < kHeaderBytes + body) return Result::kNeedMore;
  out->type = type;
  out->device = device;
  out->timestamp_s =
      static_cast<double>(ts >> 32) + std::ldexp(static_cast<double>(ts & 0xffffffffull), -32);
  out->bytes.assign(h, h + kHeaderBytes + body);
  pos_ += kHeaderBytes + body;
  return Result::kMessage;
}

std::vector<std::uint8_t> EncodeTransform(const std::string& device, const Pose& pose, double t_s) {
  igtl::TransformMessage::Pointer m = igtl::TransformMessage::New();
  m->SetDeviceName(device.c_str());
  igtl::Matrix4x4 mat;
  const Mat3 r = pose.orientation.toRotationMatrix();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) mat[i][j] = static_cast<float>(r(i, j));
    mat[i][3] = static_cast<float>(pose.position_mm[i]);
    mat[3][i] = 0.0f;
  }
  mat[3][3] = 1.0f;
  m->SetMatrix(mat);
  Stamp(m, t_s);
  return Packed(m);
}

std::vector<std::uint8_t> EncodeString(const std::string& device, const std::string& text,
                                       double t_s) {
  igtl::StringMessage::Pointer m = igtl::StringMessage::New();
  m->SetDeviceName(device.c_str());
  m->SetString(text.c_str());
  Stamp(m, t_s);
  return Packed(m);
}

std::vector<std::uint8_t> EncodeSensor(const std::string& device, const Vec3& values, double t_s) {
  igtl::SensorMessage::Pointer m = igtl::SensorMessage::New();
  m->SetDeviceName(device.c_str());
  m->SetLength(3);
  igtl::Unit::Pointer unit = igtl::Unit::New();
  unit->Init();
  unit->Append(IGTL_UNIT_SI_DERIVED_NEWTON, 1);
  m->SetUnit(unit);
  for (unsigned i = 0; i < 3; ++i) m->SetValue(i, values[i]);
  Stamp(m, t_s);
  return Packed(m);
}

std::optional<Pose> DecodeTransform(const Message& m, std::string* why) {
  if (m.bytes.size() != kHeaderBytes + 48) {
    *why = fmt::format("TRANSFORM '{}': body of {} bytes, expected 48", m.device,
                       m.bytes.size() - kHeaderBytes);
    return std::nullopt;
  }
  igtl::TransformMessage::Pointer msg = igtl::TransformMessage::New();
  if (!UnpackInto(m, msg, why)) return std::nullopt;
  igtl::Matrix4x4 mat;
  msg->GetMatrix(mat);
  Mat3 r;
  Pose pose;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r(i, j) = mat[i][j];
    pose.position_mm[i] = mat[i][3];
  }
  if (!r.allFinite() || !pose.position_mm.allFinite() ||
      (r.transpose() * r - Mat3::Identity()).cwiseAbs().maxCoeff() > 1e-3 || r.determinant() < 0) {
    *why = fmt::format("TRANSFORM '{}': not a finite rigid transform", m.device);
    return std::nullopt;
  }
  pose.orientation = Quat(r);
  pose.orientation.normalize();
  return pose;
}

std::optional<std::string> DecodeString(const Message& m, std::string* why) {
  const std::size_t body = m.bytes.size() - kHeaderBytes;
  if (body < 4 || BigEndian(m.bytes.data() + kHeaderBytes + 2, 2) != body - 4) {
    *why = fmt::format("STRING '{}': length field does not match the body", m.device);
    return std::nullopt;
  }
  igtl::StringMessage::Pointer msg = igtl::StringMessage::New();
  if (!UnpackInto(m, msg, why)) return std::nullopt;
  return std::string(msg->GetString());
}

std::optional<Vec3> DecodeSensor(const Message& m, std::string* why) {
  if (m.bytes.size() != kHeaderBytes + 10 + 3 * 8) {
    *why = fmt::format("SENSOR '{}': expected 3 values", m.device);
    return std::nullopt;
  }
  // OpenIGTLink unpacks as many values as the body's array length (its first byte) says, even
  // past the end of the body: that length is checked first.
  if (m.bytes[kHeaderBytes] != 3) {
    *why = fmt::format("SENSOR '{}': array length {}, expected 3", m.device, m.bytes[kHeaderBytes]);
    return std::nullopt;
  }
  igtl::SensorMessage::Pointer msg = igtl::SensorMessage::New();
  if (!UnpackInto(m, msg, why)) return std::nullopt;
  if (msg->GetLength() != 3) {
    *why = "SENSOR: expected 3 values";
    return std::nullopt;
  }
  return Vec3(msg->GetValue(0), msg->GetValue(1), msg->GetValue(2));
}

int Listen(const std::string& address, int port, int* bound_port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) throw std::runtime_error("socket(): " + std::string(std::strerror(errno)));
  const int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  if (::inet_pton(AF_INET, address.c_str(), &a.sin_addr) != 1) {
    ::close(fd);
    throw std::runtime_error("bad bind address '" + address + "' (expected IPv4 dotted quad)");
  }
  if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0 || ::listen(fd, SOMAXCONN) != 0) {
    const std::string err = std::strerror(errno);
    ::close(fd);
    throw std::runtime_error(fmt::format("cannot listen on {}:{}: {}", address, port, err));
  }
  socklen_t len = sizeof(a);
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  *bound_port = ntohs(a.sin_port);
  SetNonBlocking(fd);
  return fd;
}

int Connect(const std::string& host, int port, double timeout_s) {
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  if (::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &res) != 0 ||
      res == nullptr)
    return -1;
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  SetNonBlocking(fd);
  int rc = ::connect(fd, res->ai_addr, res->ai_addrlen);
  ::freeaddrinfo(res);
  if (rc != 0 && errno == EINPROGRESS) {
    pollfd p{fd, POLLOUT, 0};
    rc = ::poll(&p, 1, static_cast<int>(timeout_s * 1000)) == 1 ? 0 : -1;
    int err = 0;
    socklen_t len = sizeof(err);
    ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
    if (err != 0) rc = -1;
  }
  if (rc != 0) {
    ::close(fd);
    return -1;
  }
  const int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
  return fd;
}

void SetNonBlocking(int fd) { ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL, 0) | O_NONBLOCK); }

}  // namespace arthrosim::input::igtl_wire
