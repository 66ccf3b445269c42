// The OpenIGTLink message decoders (src/input/igtl_wire.h) on bad messages: each must be refused
// with a reason, never read or write past the message (tests/fuzz/fuzz_igtl.cpp fuzzes them).
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "igtl_wire.h"

namespace arthrosim::input {
namespace {

// The messages framed from the bytes of `path` (one OpenIGTLink stream).
std::vector<igtl_wire::Message> Messages(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                        std::istreambuf_iterator<char>());
  igtl_wire::StreamParser parser(4096);
  parser.Append(bytes.data(), bytes.size());
  std::vector<igtl_wire::Message> out;
  igtl_wire::Message m;
  std::string why;
  while (parser.Next(&m, &why) == igtl_wire::StreamParser::Result::kMessage) out.push_back(m);
  return out;
}

TEST(IgtlDecode, SensorArrayLengthBeyondItsBodyIsRefusedBeforeUnpacking) {
  // A SENSOR body of 3 values (34 bytes, CRC right) whose array length byte says 255: OpenIGTLink
  // would byte-swap and copy 255 values, 2 KB past the end of the message.
  const std::vector<igtl_wire::Message> m =
      Messages(std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/bad/igtl_sensor_larray255.bin");
  ASSERT_EQ(m.size(), 1u);
  std::string why;
  EXPECT_FALSE(igtl_wire::DecodeSensor(m[0], &why).has_value());
  EXPECT_NE(why.find("SENSOR 'Slot0Force': array length 255, expected 3"), std::string::npos)
      << why;
  // The same values with the right length decode.
  std::vector<std::uint8_t> good = igtl_wire::EncodeSensor("Slot0Force", Vec3(1, 2, 3), 5.0);
  igtl_wire::StreamParser parser(4096);
  parser.Append(good.data(), good.size());
  igtl_wire::Message g;
  ASSERT_EQ(parser.Next(&g, &why), igtl_wire::StreamParser::Result::kMessage);
  const std::optional<Vec3> v = igtl_wire::DecodeSensor(g, &why);
  ASSERT_TRUE(v.has_value()) << why;
  EXPECT_EQ(*v, Vec3(1, 2, 3));
}

TEST(IgtlDecode, BodyOpenIgtlinkSizesSmallerThanTheMessageIsRefused) {
  // Found by fuzz_igtl: a version 2 STRING message (22-byte body) for which OpenIGTLink allocated
  // a smaller body than the bytes received; the copy into it overflowed the heap.
  const std::vector<igtl_wire::Message> m =
      Messages(std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/bad/igtl_string_v2_body.bin");
  ASSERT_FALSE(m.empty());
  ASSERT_EQ(m[0].type, "STRING");
  std::string why;
  EXPECT_FALSE(igtl_wire::DecodeString(m[0], &why).has_value());
  EXPECT_NE(why.find("STRING 'Command': malformed header"), std::string::npos) << why;
}

}  // namespace
}  // namespace arthrosim::input
