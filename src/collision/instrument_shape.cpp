#include "arthrosim/collision/instrument_shape.h"

namespace arthrosim::collision {
void InstrumentPrimitivesLocal(const InstrumentModel& m, double jaw,
                               std::vector<ToolPrimitive>* out) {
  const InstrumentParts parts = InstrumentPartsLocal(m, jaw);
  out->clear();
  for (int i = 0; i < parts.count; ++i) {
    const InstrumentPart& p = parts.parts[static_cast<std::size_t>(i)];
    Simplex core;
    core.n = p.n;
    core.v = p.v;
    out->push_back(ToolPrimitive{p.part, p.side, core, p.radius_mm, p.contacts});
  }
}

std::vector<ToolPrimitive> InstrumentPrimitivesLocal(const InstrumentModel& m, double jaw) {
  std::vector<ToolPrimitive> out;
  InstrumentPrimitivesLocal(m, jaw, &out);
  return out;
}

void ToolPrimitivesWorld(const Model& model, const ToolState& tool,
                         std::vector<ToolPrimitive>* prims) {
  prims->clear();
  if (tool.instrument < 0 || tool.instrument >= static_cast<int>(model.instruments.size())) {
    return;
  }
  InstrumentPrimitivesLocal(model.instruments[static_cast<std::size_t>(tool.instrument)], tool.jaw,
                            prims);
  for (ToolPrimitive& p : *prims) {
    for (int i = 0; i < p.core.n; ++i) p.core.v[i] = tool.pose.Apply(p.core.v[i]);
  }
}

std::vector<ToolPrimitive> ToolPrimitivesWorld(const Model& model, const ToolState& tool) {
  std::vector<ToolPrimitive> prims;
  ToolPrimitivesWorld(model, tool, &prims);
  return prims;
}

}  // namespace arthrosim::collision
