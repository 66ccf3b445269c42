#pragma once
// Aiming the arthroscope at a point. The scope tip frame (model.h): the shaft runs along +z, and
// an oblique lens of angle a tilts the direction of view from the shaft toward +y, so at zero
// lens roll the view direction is (0, sin a, cos a) and the image up (0, cos a, -sin a) in the
// tip frame, which is what render::ScopeViewFrame computes. Every scripted and scenario aim (a
// trajectory's `look_at` and `follow`, a scenario's `camera.look_at`) and the renderer's AimScope
// go through here, so the point aimed at lands in the image centre.
#include "arthrosim/core/types.h"

namespace arthrosim {

/// Unit direction of view in the scope tip frame at zero lens roll: (0, sin a, cos a) for the
/// lens angle a (rad).
Vec3 ScopeViewDirectionLocal(double lens_angle_rad);

/// Orientation of a scope tip at `eye` (mm) whose oblique view (lens angle `lens_angle_rad`,
/// zero lens and head roll) points at `target` (mm), with its image up as close as possible to
/// `up_hint` (need not be unit). When the view is parallel to `up_hint`, world +y is used, and
/// if it is parallel to that too, any perpendicular. Returns identity if eye == target.
/// lens_angle_rad = 0 aims the shaft itself (a forward-viewing scope). Deterministic: the same
/// inputs give the same bits.
Quat AimScopeView(const Vec3& eye, const Vec3& target, double lens_angle_rad,
                  const Vec3& up_hint = Vec3::UnitZ());

}  // namespace arthrosim
