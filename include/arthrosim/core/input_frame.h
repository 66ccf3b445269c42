#pragma once
// One step's worth of input, whatever its source (recorded file, synthetic script, live
// device). The core only ever sees this record: it does not know where it came from.
#include <array>
#include <cstdint>

#include "arthrosim/core/state.h"
#include "arthrosim/core/types.h"

namespace arthrosim {

/// Command for one instrument slot (hand/portal).
struct ToolCommand {
  std::int32_t instrument = -1;  ///< index into Model::instruments; -1 = withdrawn
  Pose pose;                     ///< desired tip pose, world, mm
  double jaw = 0;                ///< 0 open ... 1 closed
  std::uint8_t buttons = 0;      ///< bit 0 = button 1, bit 1 = button 2 (latched per step)
};

/// Command for the arthroscope.
struct CameraCommand {
  Pose pose;
  double lens_roll_rad = 0;
  double head_roll_rad = 0;
};

struct InputFrame {
  std::array<ToolCommand, kToolSlots> tools;
  CameraCommand camera;
};

/// Force fed back to the input side after a step (haptics): per slot, N, world frame.
struct FeedbackFrame {
  std::array<Vec3, kToolSlots> force_n{Vec3::Zero(), Vec3::Zero()};
};

}  // namespace arthrosim
