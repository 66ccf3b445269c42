#pragma once
// The instructor overlay: time, inserted instruments, contact-force bars, plan step and verdict.
#include "arthrosim/render/image.h"
#include "arthrosim/render/scene.h"
#include "text.h"

namespace arthrosim::render {

/// Contact force (N) that fills a force bar.
inline constexpr double kForceBarFullScaleN = 20.0;

/// Draws `overlay` over `image` (text size scales with the image height).
void DrawOverlay(const Overlay& overlay, Font* font, Image* image);

}  // namespace arthrosim::render
