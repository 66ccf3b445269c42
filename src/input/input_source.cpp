#include "arthrosim/input/input_source.h"

#include <cstring>

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

}  // namespace

const char* DeviceName(Device device) {
  switch (device) {
    case Device::kSlot0:
      return "slot0";
    case Device::kSlot1:
      return "slot1";
    case Device::kScope:
      return "scope";
  }
  return "?";
}

std::optional<Device> ParseDevice(const std::string& name) {
  if (name == "slot0") return Device::kSlot0;
  if (name == "slot1") return Device::kSlot1;
  if (name == "scope" || name == "camera") return Device::kScope;
  return std::nullopt;
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
