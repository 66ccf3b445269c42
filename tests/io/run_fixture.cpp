#include "run_fixture.h"

#include <sys/wait.h>
#include <algorithm>
#include <limits>

#include <cstdlib>
#include <filesystem>

#include "arthrosim/core/hash.h"

namespace arthrosim::io::testing {
namespace {

Points Cols(std::initializer_list<Vec3> pts) {
  Points p(3, static_cast<Eigen::Index>(pts.size()));
  Eigen::Index i = 0;
  for (const Vec3& v : pts) p.col(i++) = v;
  return p;
}

Points CubeRest() {
  Points p(3, 8);
  for (int i = 0; i < 8; ++i) {
    p.col(i) = Vec3(10.0 * (i & 1), 10.0 * ((i >> 1) & 1), 10.0 * ((i >> 2) & 1));
  }
  return p;
}

const std::vector<mesh::Tet> kCubeTets{
    {1, 2, 4, 7}, {0, 1, 2, 4}, {3, 2, 1, 7}, {5, 1, 4, 7}, {6, 4, 2, 7}};
const std::vector<mesh::Tet> kSplitTets{{8, 2, 4, 7}, {1, 8, 4, 7}, {1, 2, 8, 7}, {1, 2, 4, 8}};

Points BicepsRest() { return Cols({{0, 0, 20}, {5, 0, 20}, {0, 5, 20}, {0, 0, 25}}); }

Points ThreadRest() {
  Points p(3, 6);
  for (int i = 0; i < 6; ++i) p.col(i) = Vec3(2.0 * i, -5.0, 0.0);
  return p;
}

mesh::TriMesh BoneRest() {
  mesh::TriMesh m;
  m.nodes = Cols({{0, 0, -10}, {10, 0, -10}, {0, 10, -10}, {0, 0, -20}});
  m.tris = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  return m;
}

Pose MakePose(const Vec3& p, double angle, const Vec3& axis) {
  Pose pose;
  pose.position_mm = p;
  pose.orientation = Quat(Eigen::AngleAxisd(angle, axis));
  return pose;
}

// A constraint end on node `node` of entity `index` of `kind` alone.
ConstraintEnd NodeEnd(ConstraintEnd::Kind kind, std::int32_t index, std::int32_t node) {
  ConstraintEnd e;
  e.kind = kind;
  e.index = index;
  e.nodes = {node, -1, -1, -1};
  e.weights = {1, 0, 0, 0};
  return e;
}

// A constraint end on tool slot `slot`, `offset_mm` in the tool frame.
ConstraintEnd ToolEnd(std::int32_t slot, const Vec3& offset_mm) {
  ConstraintEnd e;
  e.kind = ConstraintEnd::Kind::kTool;
  e.index = slot;
  e.offset_mm = offset_mm;
  return e;
}

}  // namespace

Model MakeModel() {
  Model m;
  m.name = "io-synthetic";
  m.scenario_path = "tests/io/synthetic.yaml";
  m.scenario_text = "name: io-synthetic\n# synthetic run for the io tests: \xc3\xa9\n";
  m.scenario_sha256 = Sha256Hex(m.scenario_text);
  m.options.dt_s = 0.01;
  m.options.flush_interval_s = 0.1;
  m.options.output_every_steps = 2;

  SoftBodyModel cuff;
  cuff.name = "cuff";
  cuff.rest_mesh.nodes = CubeRest();
  cuff.rest_mesh.tets = kCubeTets;
  m.soft_bodies.push_back(cuff);
  SoftBodyModel biceps;
  biceps.name = "biceps";
  biceps.rest_mesh.nodes = BicepsRest();
  biceps.rest_mesh.tets = {{0, 1, 2, 3}};
  m.soft_bodies.push_back(biceps);

  BoneModel bone;
  bone.name = "humerus";
  bone.surface = BoneRest();
  bone.hardness = 2.0;
  m.bones.push_back(bone);

  ThreadModel thread;
  thread.name = "suture";
  thread.initial.nodes = ThreadRest();
  for (int i = 0; i + 1 < 6; ++i) thread.initial.edges.push_back({i, i + 1});
  m.threads.push_back(thread);

  auto instrument = [&](const char* name, InstrumentKind kind, const char* portal) {
    InstrumentModel im;
    im.name = name;
    im.kind = kind;
    im.portal = portal;
    m.instruments.push_back(im);
  };
  instrument("grasper", InstrumentKind::kGrasper, "lateral");
  instrument("burr", InstrumentKind::kBurr, "anterior");
  instrument("scissors", InstrumentKind::kScissors, "lateral");
  return m;
}

State MakeFrame(const Model& model, int f) {
  (void)model;
  const double fd = f;
  State s;
  s.step = 2 * f;
  s.time_s = 0.01 * static_cast<double>(s.step);
  s.rng_state = 0x9E3779B97F4A7C15ull * static_cast<std::uint64_t>(f + 1);

  auto move = [&](Points& x) {  // node i moves by (0.1 f, 0.01 f i, -0.05 f^2)
    for (Eigen::Index i = 0; i < x.cols(); ++i) {
      x.col(i) += Vec3(0.1 * fd, 0.01 * fd * static_cast<double>(i), -0.05 * fd * fd);
    }
  };
  auto empty_soft = [](SoftBodyState& b) {
    b.v.resize(3, 0);
    b.x_rest.resize(3, 0);
    b.dv_warm.resize(3, 0);
  };

  SoftBodyState cuff;
  cuff.x = CubeRest();
  cuff.tets = kCubeTets;
  if (f >= 6) {
    cuff.x.conservativeResize(3, 9);
    cuff.x.col(8) = Vec3(5, 5, 5);  // centroid of tet 0
    cuff.tets.insert(cuff.tets.end(), kSplitTets.begin(), kSplitTets.end());
  }
  move(cuff.x);
  cuff.tet_alive.assign(cuff.tets.size(), 1);
  if (f >= 3) cuff.tet_alive[4] = 0;
  if (f >= 6) cuff.tet_alive[0] = 0;
  empty_soft(cuff);
  s.soft_bodies.push_back(std::move(cuff));

  SoftBodyState biceps;
  biceps.x = BicepsRest();
  biceps.tets = {{0, 1, 2, 3}};
  biceps.tet_alive = {1};
  empty_soft(biceps);
  s.soft_bodies.push_back(std::move(biceps));

  BoneState bone;
  bone.surface = BoneRest();
  if (f >= 4) {
    bone.surface.nodes.col(0) = Vec3(0.5, 0.5, -10.5);
    bone.removed_volume_mm3 = 0.25 * (fd - 3.0);
  }
  if (f >= 7) {
    bone.surface.nodes.conservativeResize(3, 5);
    bone.surface.nodes.col(4) = Vec3(5, 5, -10);
    bone.surface.tris = {{0, 2, 4}, {0, 4, 1}, {0, 1, 3}, {1, 4, 3}, {4, 2, 3}, {0, 3, 2}};
  }
  s.bones.push_back(bone);

  ThreadState thread;
  thread.x = ThreadRest();
  for (Eigen::Index i = 0; i < 6; ++i) {
    thread.x.col(i) += Vec3(0.0, 0.2 * fd, 0.3 * static_cast<double>(i) * fd);
  }
  thread.v.resize(3, 0);
  thread.node_alive.assign(6, 1);
  if (f >= 5) thread.node_alive[3] = 0;
  s.threads.push_back(thread);

  ToolState& a = s.tools[0];
  a.instrument = f >= 2 ? 0 : -1;
  a.pose = MakePose(Vec3(1.0 + fd, 2, 3), 0.1 * fd, Vec3::UnitZ());
  a.jaw = 0.1 * fd;
  a.buttons = static_cast<std::uint8_t>(f % 4);
  a.force_n = Vec3(0.5 * fd, 0, -fd);
  ToolState& b = s.tools[1];
  b.instrument = (f >= 4 && f <= 7) ? 1 : -1;
  b.pose = MakePose(Vec3(-1, fd, 0.5 * fd), 0.2 * fd, Vec3::UnitX());
  b.jaw = 0;
  b.buttons = 1;
  b.force_n = Vec3(0, fd, 0);

  s.camera.pose = MakePose(Vec3(0, 0, 50.0 + fd), 0.0, Vec3::UnitZ());
  s.camera.lens_roll_rad = 0.01 * fd;
  s.camera.head_roll_rad = -0.02 * fd;

  if (f >= 3 && f < 8) {
    SpringConstraint c;
    c.id = 1;
    c.tag = "grasp";
    c.a = NodeEnd(ConstraintEnd::Kind::kSoftBody, 0, 5);
    c.b = ToolEnd(0, Vec3(0, 0, 1));
    c.stiffness_n_per_mm = 2.0;
    s.constraints.push_back(c);
  }
  if (f >= 6) {
    SpringConstraint c;
    c.id = 2;
    c.tag = "suture";
    c.a = NodeEnd(ConstraintEnd::Kind::kThread, 0, 0);
    c.b.kind = ConstraintEnd::Kind::kSoftBody;
    c.b.index = 0;
    c.b.nodes = {1, 2, 4, 7};
    c.b.weights = {0.25, 0.25, 0.25, 0.25};
    c.stiffness_n_per_mm = 5.0;
    c.rest_length_mm = 0.5;
    s.constraints.push_back(c);
  }
  s.next_constraint_id = 1 + (f >= 3 ? 1 : 0) + (f >= 6 ? 1 : 0);

  if (f >= 4 && f <= 6) {  // burr touching the bone
    ToolContact c;
    c.tool_slot = 1;
    c.body_kind = ConstraintEnd::Kind::kBone;
    c.body = 0;
    c.position_mm = Vec3(0.1 * fd, 0, -10);
    s.tool_contacts.push_back(c);
  }

  auto event = [&](const char* kind, const char* tool, const char* body, const char* detail,
                   const Vec3& p) {
    s.events.push_back(Event{s.step, s.time_s, kind, tool, body, detail, p});
  };
  if (f == 2) event("insert", "grasper", "", "slot 0", Vec3(3, 2, 3));
  if (f == 3) {
    event("grasp", "grasper", "cuff", "node 5", Vec3(10, 0, 10));
    event("remove", "scissors", "cuff", "tet 4", Vec3(1, 2, 3));
  }
  if (f == 4)
    event("contact_start", "burr", "humerus",
          "Oberfl\xc3\xa4"
          "che",
          Vec3(0, 0, -10));
  if (f == 5) event("cut", "", "suture", "node 3", Vec3(6, -4, 4.5));
  if (f == 7) event("reshape", "burr", "humerus", "edge split 1-2", Vec3(5, 5, -10));
  return s;
}

std::string TestDir(const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(ARTHROSIM_BINARY_DIR) / "io-test-tmp" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

namespace {
std::string Python() {
  // Debian's interpreter has python3-h5py; a pyenv/venv python3 first on PATH may not.
  return std::filesystem::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
}
int Status(int raw) { return raw == -1 ? -1 : (WIFEXITED(raw) ? WEXITSTATUS(raw) : -1); }
}  // namespace

double MaxPositionError(const State& a, const State& b) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  if (a.soft_bodies.size() != b.soft_bodies.size() || a.threads.size() != b.threads.size()) {
    return kInf;
  }
  double worst = 0;
  auto visit = [&](const Points& x, const Points& y) {
    if (x.cols() != y.cols()) {
      worst = kInf;
    } else if (x.size() > 0) {
      worst = std::max(worst, (x - y).cwiseAbs().maxCoeff());
    }
  };
  for (std::size_t i = 0; i < a.soft_bodies.size(); ++i) {
    visit(a.soft_bodies[i].x, b.soft_bodies[i].x);
  }
  for (std::size_t i = 0; i < a.threads.size(); ++i) visit(a.threads[i].x, b.threads[i].x);
  return worst;
}

bool EqualWithinPositionBound(const State& got, const State& want, double bound_mm) {
  if (!(MaxPositionError(got, want) <= bound_mm)) return false;
  State same = got;
  for (std::size_t i = 0; i < same.soft_bodies.size(); ++i) {
    same.soft_bodies[i].x = want.soft_bodies[i].x;
  }
  for (std::size_t i = 0; i < same.threads.size(); ++i) same.threads[i].x = want.threads[i].x;
  return BitwiseEqual(same, want);
}

bool HavePythonH5py() {
  return Status(std::system((Python() + " -c 'import h5py, numpy' 2>/dev/null").c_str())) == 0;
}

int RunPython(const std::string& script, const std::string& args) {
  const std::string cmd =
      Python() + " " + ARTHROSIM_SOURCE_DIR + "/tests/io/" + script + " " + args;
  return Status(std::system(cmd.c_str()));
}

}  // namespace arthrosim::io::testing
