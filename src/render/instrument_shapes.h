#pragma once
// Drawable shapes of the instruments in the tool frame (tip at the origin, +z forward, shaft
// back along -z, jaws opening in the x-z plane), placed at the tool pose.
#include "arthrosim/core/model.h"
#include "arthrosim/render/scene.h"

namespace arthrosim::render {

/// Appends the instrument's shaft and tip to `metal` and its dark parts (insulation, inner
/// blade) to `dark`. jaw: 0 open ... 1 closed.
void AppendInstrument(const InstrumentModel& instrument, double jaw, const Pose& pose,
                      SceneMesh* metal, SceneMesh* dark);

/// Appends the arthroscope sheath: a cylinder from the tip back along -z.
void AppendScope(const Pose& pose, double diameter_mm, SceneMesh* mesh);

}  // namespace arthrosim::render
