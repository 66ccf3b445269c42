#pragma once
// A small synthetic run for the scoring tests, written with io::RunWriter frame by frame from
// closed formulas, with switches that inject exactly one error each. The clean run: the camera
// looks at the `view` landmark; the burr (slot 0, frames 10-40) reaches the target region on a
// minimum-jerk path and removes 1 mm^3 there at frame 30; the awl (slot 0, frames 50-80) punches
// a hole at `site` at frame 70 (depth 15 mm, angle 45 deg) while touching the humerus with 1 N.
#include <string>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/scoring/plan.h"

namespace arthrosim::scoring::testing {

struct SynthSpec {
  int frames = 100;              ///< dt 0.02 s
  double hole_angle_deg = 45;    ///< detail angle_deg of the hole event
  double hole_depth_mm = 15;     ///< detail depth_mm
  double hole_offset_mm = 0;     ///< hole event position moved along +x from the site
  double hole_volume_mm3 = 0;    ///< > 0: the hole event books this volume_mm3 (a removal)
  int hole_frame = 70;           ///< frame of the hole event (awl inserted 50..80)
  int stray_hole_frame = -1;     ///< >= 0: an earlier hole event 10 mm off the site here
  int burr_frame = 30;           ///< frame of the burr event (burr inserted 10..40)
  bool burr_late = false;        ///< burr inserted frames 85..95, removal at 90 (after the hole)
  bool hole_by_grasper = false;  ///< the hole event names the grasper
  bool burr_outside_target = false;  ///< the burr removes outside the target region
  bool burr_on_muscle = false;       ///< the burr event is on the protected muscle
  std::vector<int>
      muscle_burr_frames;           ///< more burr events on the protected muscle, at these frames
  double muscle_touch_force_n = 0;  ///< > 0: grasper touches the muscle frames 85..95
  bool camera_away = false;         ///< the camera looks away from every landmark
  /// The camera looks at the same point from below the humerus: every awl tip position (on the
  /// site, above the bone's top face) is in its view cone but behind the bone.
  bool camera_below_bone = false;
  double head_roll_rad = 0;      ///< camera-head roll (horizon)
  bool awl_idle = false;         ///< the awl rests still for its whole insertion
  bool burr_zigzag = false;      ///< the burr path zig-zags (3x longer)
  double position_noise_mm = 0;  ///< added to the awl pose x at frame `noise_frame`
  int noise_frame = -1;
  Vec3 tendon_shift_mm = Vec3::Zero();  ///< the tendon's nodes moved by this in every frame
  /// Nonzero: the tendon's tet is cut away and a second tet (nodes 1, 2, 3 and a new node 4)
  /// holds the tissue, so node 0 is debris, moved by this from where it was.
  Vec3 tendon_debris_shift_mm = Vec3::Zero();
};

/// The synthetic Model (scenario name "scoring-synthetic").
Model MakeSynthModel();
/// Writes the run to `path`.
void WriteSynthRun(const std::string& path, const SynthSpec& spec);
/// The plan text for the synthetic run (look, burr, hole; protected muscle).
std::string SynthPlanText();
/// Directory for a test's files (created empty) below the build directory.
std::string TestDir(const std::string& name);

}  // namespace arthrosim::scoring::testing
