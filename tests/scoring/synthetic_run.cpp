#include "synthetic_run.h"

#include <cmath>
#include <filesystem>
#include <numbers>

#include "arthrosim/core/hash.h"
#include "arthrosim/core/state.h"
#include "arthrosim/io/run_writer.h"
#include "arthrosim/render/scene.h"

namespace arthrosim::scoring::testing {
namespace {

const Vec3 kSite(0, 0, 0);        // on the humerus top face
const Vec3 kView(0, 0, 5);        // what the camera looks at
const Vec3 kBurrTarget(5, 5, 0);  // inside region "target"
const Vec3 kOutside(-8, -8, 0);   // outside it
const Vec3 kMuscle(0, 40, 5);     // the muscle's tet

Points Cols(std::initializer_list<Vec3> pts) {
  Points p(3, static_cast<Eigen::Index>(pts.size()));
  Eigen::Index i = 0;
  for (const Vec3& v : pts) p.col(i++) = v;
  return p;
}

mesh::TriMesh Humerus() {
  mesh::TriMesh m;  // a tetrahedron whose top face lies in z = 0
  m.nodes = Cols({{-10, -10, 0}, {10, -10, 0}, {0, 10, 0}, {0, 0, -10}});
  m.tris = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  return m;
}

Points TetAt(const Vec3& o) {
  return Cols({o, o + Vec3(4, 0, 0), o + Vec3(0, 4, 0), o + Vec3(0, 0, 4)});
}

double MinJerk(double s) { return s * s * s * (10 - 15 * s + 6 * s * s); }

// The tendon's tet cut away, a second one (nodes 1, 2, 3 and a new node 4 on the far side of
// their face) holding the tissue: node 0 belongs to no alive element (debris), moved by `shift`.
void LeaveDebrisNode(const Vec3& shift, State* s) {
  SoftBodyState& b = s->soft_bodies[0];
  Points x(3, 5);
  x.leftCols(4) = b.x;
  x.col(4) = (b.x.col(1) + b.x.col(2) + b.x.col(3)) / 3.0 + Vec3(2, 2, 2);
  x.col(0) += shift;
  b.x = x;
  b.x_rest = x;
  b.v = Points::Zero(3, 5);
  b.dv_warm = Points::Zero(3, 5);
  b.tets = {{0, 1, 2, 3}, {1, 2, 3, 4}};
  b.tet_alive = {0, 1};
}

}  // namespace

Model MakeSynthModel() {
  Model m;
  m.name = "scoring-synthetic";
  m.scenario_path = "tests/scoring/synthetic.yaml";
  m.scenario_text = "name: scoring-synthetic\n";
  m.scenario_sha256 = Sha256Hex(m.scenario_text);
  m.options.dt_s = 0.02;
  m.options.flush_interval_s = 1.0;
  for (const char* name : {"tendon", "muscle"}) {
    SoftBodyModel b;
    b.name = name;
    b.rest_mesh.nodes = TetAt(std::string(name) == "muscle" ? kMuscle : Vec3(-20, 0, 2));
    b.rest_mesh.tets = {{0, 1, 2, 3}};
    m.soft_bodies.push_back(b);
  }
  BoneModel bone;
  bone.name = "humerus";
  bone.surface = Humerus();
  m.bones.push_back(bone);
  auto instrument = [&](const char* name, InstrumentKind kind) {
    InstrumentModel im;
    im.name = name;
    im.kind = kind;
    im.portal = "lateral";
    m.instruments.push_back(im);
  };
  instrument("burr", InstrumentKind::kBurr);
  instrument("awl", InstrumentKind::kAwl);
  instrument("grasper", InstrumentKind::kGrasper);
  m.portals.push_back({"lateral", Vec3(40, 0, 20)});
  m.landmarks.push_back({"site", "humerus", kSite});
  m.landmarks.push_back({"view", "", kView});
  m.landmarks.push_back({"footprint", "humerus", Vec3(-20, 0, 2)});
  Region target{"target", "humerus", {}, Vec3(2, 2, -1), Vec3(8, 8, 1)};
  m.regions.push_back(target);
  Region belly{
      "belly", "muscle", {0, 1, 2, 3}, kMuscle - Vec3::Constant(1), kMuscle + Vec3::Constant(5)};
  m.regions.push_back(belly);
  Region edge{"edge", "tendon", {0, 1, 2, 3}, Vec3(-21, -1, 1), Vec3(-15, 5, 7)};
  m.regions.push_back(edge);
  // The footprint's bone bed: the tendon's centroid (-19, 1, 3) lies 1 mm medial of it.
  Region bed{"bed", "humerus", {}, Vec3(-18, -5, -1), Vec3(-8, 5, 8)};
  m.regions.push_back(bed);
  return m;
}

std::string SynthPlanText() {
  return R"(name: synth
scenario: scoring-synthetic
pass_score: 70
motion: {max_outside_volume: 0.5, max_idle_share: 0.8, min_tip_in_view: 0.5, max_horizon: 20}
protected:
  - {name: belly, body: muscle, max_force: 2.0, max_contact_time: 0, zero_damage: true, critical: true}
steps:
  - id: look
    title: Look at the field
    instruments: [camera]
    complete:
      - in_view: {landmark: view, min_time: 0.2}
    time_budget: 5
  - id: burr
    title: Burr the target
    instruments: [burr]
    operation: burr
    target: {region: target}
    requires: [look]
    complete:
      - bone_removed: {bone: humerus, min_volume: 0.5}
    time_budget: 1.0
  - id: hole
    title: Punch the hole
    instruments: [awl]
    operation: hole
    target: {landmark: site}
    requires: [burr]
    complete:
      - event: {kind: hole, body: humerus, landmark: site, within: 3,
                detail: {depth_mm: {min: 12, max: 20}, angle_deg: {min: 35, max: 55}}}
    time_budget: 0.5
  - id: reduce
    title: Tendon edge on the footprint
    instruments: [grasper]
    complete:
      - distance: {region: edge, landmark: footprint, max: 2}
    time_budget: 10
)";
}

void WriteSynthRun(const std::string& path, const SynthSpec& spec) {
  const Model model = MakeSynthModel();
  State s = MakeInitialState(model);
  const Vec3 eye = spec.camera_below_bone ? Vec3(0, -1, -30) : Vec3(0, -30, 25);
  const Vec3 look = spec.camera_away ? Vec3(0, -80, 60) : kView;
  const Pose cam = render::AimScope(eye, look, Vec3::UnitZ(), 30.0 * std::numbers::pi / 180.0);
  auto frame_state = [&](int f) {
    s.step = f;
    s.time_s = 0.02 * f;
    s.events.clear();
    s.tool_contacts.clear();
    s.camera.pose = cam;
    s.camera.head_roll_rad = spec.head_roll_rad;
    s.soft_bodies[0].x = model.soft_bodies[0].rest_mesh.nodes.colwise() + spec.tendon_shift_mm;
    if (!spec.tendon_debris_shift_mm.isZero()) LeaveDebrisNode(spec.tendon_debris_shift_mm, &s);
    for (ToolState& t : s.tools) {
      t.instrument = -1;
      t.force_n = Vec3::Zero();
    }
    ToolState& t0 = s.tools[0];
    const int burr_in = spec.burr_late ? 85 : 10, burr_out = spec.burr_late ? 95 : 40;
    const int burr_frame = spec.burr_late ? 90 : spec.burr_frame;
    if (f >= burr_in && f <= burr_out) {  // burr: min-jerk reach from 20 mm above the target
      t0.instrument = 0;
      const double a = MinJerk(std::min(1.0, (f - burr_in) / 15.0));
      const Vec3 target = spec.burr_outside_target ? kOutside : kBurrTarget;
      t0.pose.position_mm = target + Vec3(0, 0, 20.0 * (1 - a));
      if (spec.burr_zigzag && f > 10 && f < 25) t0.pose.position_mm.x() += (f % 2 ? 6.0 : -6.0);
      if (f == burr_frame) {
        const std::string body = spec.burr_on_muscle ? "muscle" : "humerus";
        s.events.push_back({f, s.time_s, "burr", "burr", body, "volume_mm3=1", target});
        s.bones[0].removed_volume_mm3 += 1.0;
      }
    }
    for (int muscle_frame : spec.muscle_burr_frames)
      if (f == muscle_frame)
        s.events.push_back({f, s.time_s, "burr", "burr", "muscle", "volume_mm3=0.1", kMuscle});
    if (f >= 50 && f <= 80) {  // awl: 10 mm down onto the site at 50 mm/s, then held
      t0.instrument = 1;
      const double z = spec.awl_idle ? 0.0 : std::max(0.0, 10.0 - (f - 50));
      t0.pose.position_mm = kSite + Vec3(0, 0, z);
      if (f == spec.noise_frame) t0.pose.position_mm.x() += spec.position_noise_mm;
      if (f >= 65 && f <= 75) {
        t0.force_n = Vec3(0, 0, 1.0);
        s.tool_contacts.push_back({0, ConstraintEnd::Kind::kBone, 0, kSite});
      }
      if (f == spec.stray_hole_frame) {  // a first hole 10 mm off the site
        s.events.push_back({f, s.time_s, "hole", "awl", "humerus", "depth_mm=15 angle_deg=45",
                            kSite + Vec3(10, 0, 0)});
      }
      if (f == spec.hole_frame) {
        std::string detail = "depth_mm=" + std::to_string(spec.hole_depth_mm) +
                             " angle_deg=" + std::to_string(spec.hole_angle_deg);
        if (spec.hole_volume_mm3 > 0)
          detail += " volume_mm3=" + std::to_string(spec.hole_volume_mm3);
        s.events.push_back({f, s.time_s, "hole", spec.hole_by_grasper ? "grasper" : "awl",
                            "humerus", detail, kSite + Vec3(spec.hole_offset_mm, 0, 0)});
      }
    }
    if (spec.muscle_touch_force_n > 0 && f >= 85 && f <= 95) {
      ToolState& t1 = s.tools[1];
      t1.instrument = 2;
      t1.pose.position_mm = kMuscle + Vec3(1, 1, 1);
      t1.force_n = Vec3(spec.muscle_touch_force_n, 0, 0);
      s.tool_contacts.push_back({1, ConstraintEnd::Kind::kSoftBody, 1, kMuscle + Vec3(1, 1, 1)});
    }
  };
  frame_state(0);
  io::RunWriterOptions options;
  options.write_xdmf = false;
  io::RunWriter writer(path, model, s, options);
  for (int f = 1; f < spec.frames; ++f) {
    frame_state(f);
    writer.Append(s);
  }
  writer.Close();
}

std::string TestDir(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::path(ARTHROSIM_BINARY_DIR) / "test_output" / "scoring" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

}  // namespace arthrosim::scoring::testing
