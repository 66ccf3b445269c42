#include "arthrosim/input/input_source.h"

#include <cstring>

#include "arthrosim/core/enum_names.h"

namespace arthrosim::input {
namespace {

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

bool SameBits(const Pose& a, const Pose& b) {
  for (int i = 0; i < 3; ++i) {
    if (!SameBits(a.position_mm[i], b.position_mm[i])) return false;
  }
  for (int i = 0; i < 4; ++i) {
    if (!SameBits(a.orientation.coeffs()[i], b.orientation.coeffs()[i])) return false;
  }
  return true;
}

constexpr EnumName<Device> kDeviceNames[] = {
    {Device::kSlot0, "slot0"}, {Device::kSlot1, "slot1"}, {Device::kScope, "scope"}};

}  // namespace

const char* DeviceName(Device device) { return NameIn(kDeviceNames, device, "?"); }

std::optional<Device> ParseDevice(const std::string& name) {
  if (name == "camera") return Device::kScope;  // an alias
  return ValueIn(kDeviceNames, name);
}

InputFrame IdleFrame(const Model& model) {
  InputFrame f;
  f.camera.pose = model.camera.initial_pose;
  return f;
}

bool BitwiseEqual(const InputFrame& a, const InputFrame& b) {
  for (int s = 0; s < kToolSlots; ++s) {
    const ToolCommand& x = a.tools[s];
    const ToolCommand& y = b.tools[s];
    if (x.instrument != y.instrument || x.buttons != y.buttons || !SameBits(x.jaw, y.jaw) ||
        !SameBits(x.pose, y.pose)) {
      return false;
    }
  }
  return SameBits(a.camera.pose, b.camera.pose) &&
         SameBits(a.camera.lens_roll_rad, b.camera.lens_roll_rad) &&
         SameBits(a.camera.head_roll_rad, b.camera.head_roll_rad);
}

}  // namespace arthrosim::input
