#pragma once
// The plausible range of every physical quantity a scenario sets, in the unit the file writes it
// (docs/scenario-format.md, "Plausible ranges"). Outside [min, max] is an input error (exit 2):
// no tissue, thread, tool or clock has such a value, and accepting it would silently freeze or
// explode the simulation. Inside it but outside the usual part, the scenario runs with a warning.
#include <cstdint>

#include "arthrosim/core/yaml_fields.h"

namespace arthrosim::io::ranges {

// Time. A step beyond 0.1 s cannot resolve a hand's motion; the usual steps are 1-40 ms.
inline constexpr QuantityRange kTimeStep{0, true, 0.1, 1e-4, 0.04, "s"};
inline constexpr QuantityRange kDuration{0, true, 86400, 1e-3, 3600, "s"};
inline constexpr QuantityRange kFlushInterval{0, true, 3600, 0.01, 60, "s"};
// Full State checkpoints: each is a few hundred kB on the shoulder scene; more often than every
// 0.1 s is a unit slip, rarer than every 10 minutes leaves little to resume from.
inline constexpr QuantityRange kCheckpointInterval{0, true, 86400, 0.1, 600, "s"};

// Soft tissue (SI as written). Muscle is ~1e4-1e5 Pa, tendon ~1e9 Pa; a simulated 1 Pa tissue
// or a 1 GPa one still runs, beyond that no tissue is.
inline constexpr QuantityRange kYoungModulus{0, true, 1e10, 1e3, 2e9, "Pa"};
inline constexpr QuantityRange kDensity{0, true, 1e5, 500, 3000, "kg/m^3"};
inline constexpr QuantityRange kRayleighMass{0, false, 1e4, 0, 100, "1/s"};
inline constexpr QuantityRange kRayleighStiffness{0, false, 10, 0, 0.1, "s"};

// Divergence guard: tissue and thread in an arthroscopy move at well under 1 m/s; below
// 0.1 m/s a fast hand would be taken for a diverged solve, beyond 1 km/s nothing is caught.
inline constexpr QuantityRange kDivergenceSpeed{0, true, 1e6, 1e2, 1e5, "mm/s"};

// Suture thread. USP sizes 5-0 .. 5 are 0.1-0.7 mm across.
inline constexpr QuantityRange kThreadDiameter{0, true, 20, 0.05, 2, "mm"};
inline constexpr QuantityRange kThreadStretchStiffness{0, true, 1e9, 10, 1e6, "N"};
inline constexpr QuantityRange kThreadMaxSpeed{0, true, 1e6, 10, 1e4, "mm/s"};

// Bone and instruments.
inline constexpr QuantityRange kBoneHardness{0, true, 100, 0.1, 10, "(1 = cortical)"};
inline constexpr QuantityRange kShaftDiameter{0, true, 30, 1, 10, "mm"};

// Contact, in mm and N/mm.
inline constexpr QuantityRange kContactDistance{0, true, 100, 0.01, 10, "mm"};
inline constexpr QuantityRange kContactStiffness{0, true, 1e7, 1e-2, 1e5, "N/mm"};

// Haptics: a desktop device renders a few N; 1 kN would break any device.
inline constexpr QuantityRange kHapticMaxForce{0, true, 1000, 0.1, 50, "N"};

// Gravity, as the length of the vector: up to 10 g; the usual is Earth's 9 810 mm/s^2 or none
// (below 0.1 g the file was most likely written in m/s^2).
inline constexpr double kMaxGravityMmS2 = 98100;
inline constexpr double kUsualMinGravityMmS2 = 981;
inline constexpr double kUsualMaxGravityMmS2 = 15000;

// Counts that size memory or loops: beyond these a value is an error, not an allocation
// failure or a step that never ends.
inline constexpr std::int64_t kMaxIterations = 100000;    // solver iterations per step
inline constexpr std::int64_t kMaxPasses = 1000;          // substeps, Newton and CCD passes
inline constexpr std::int64_t kMaxOutputEvery = 1000000;  // steps between written frames
inline constexpr std::int64_t kMaxThreadNodes = 100000;   // 100 m of thread at 1 mm

}  // namespace arthrosim::io::ranges
