#pragma once
// The expert repair's run file and the helpers that read it, shared by the expert_repair_test
// files (expert_repair_test.cpp: each step's outcome; expert_soundness_test.cpp: nothing through
// bone, threads not stretched; expert_tendon_edge_test.cpp: the edge's distance to the
// footprint). The run is made (or read) once per test binary: expert_run.cpp.
//
// ARTHROSIM_EXPERT_SCRIPT=FILE runs another script through the same checks (a variant with a step
// left out must fail that step's test); ARTHROSIM_EXPERT_RUN=RUN.h5 checks an existing run file of
// the shoulder scene instead of running one (the CTest ExpertRepair reads build/test_runs).
#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "arthrosim/collision/tool_bone_query.h"
#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/io/run_reader.h"

namespace arthrosim::expert {

/// The run, made once for all tests of the binary and (when made here) removed at the end.
struct ExpertRun {
  std::string path;
  std::unique_ptr<io::RunReader> reader;
  Model model;
  std::vector<Event> events;  // every event of the run
  State first, last;
  // Every 25th frame and the last (reading every frame would cost minutes): time, scope, tools.
  std::vector<double> time_s;
  std::vector<CameraState> camera;
  std::vector<std::array<ToolState, kToolSlots>> tools;
};

/// The run: the first call runs the arthrosim binary on the shoulder scene with the expert
/// script (or ARTHROSIM_EXPERT_SCRIPT), or opens ARTHROSIM_EXPERT_RUN, and reads it.
const ExpertRun& TheRun();
/// The run's scene, its last frame and every event.
const Model& Shoulder();
const State& Last();
const std::vector<Event>& Events();

/// Position (mm) of the scene's landmark `name` (a test failure and the origin if absent).
Vec3 LandmarkMm(const std::string& name);
/// The scene's region `name` (a test failure and the first region if absent).
const Region& RegionNamed(const std::string& name);
/// p inside the region's box (faces included).
bool InBox(const Region& r, const Vec3& p);
/// Index of soft body `name` in the run's frames; of bone `name` in the scene.
std::size_t SoftIndex(const std::string& name);
std::size_t BoneIndex(const std::string& name);

/// Periods [in, out] (s) during which `instrument` was in a tool slot, in order, from the
/// tool_change events (tool = the new instrument, detail "slotN from 'old'").
std::vector<std::pair<double, double>> Insertions(const std::string& instrument);
/// Events of `kind` on `body` (empty: any body) between t0 and t1 (s).
std::vector<Event> EventsIn(const std::string& kind, const std::string& body, double t0, double t1);
/// The value of `key=` in an event detail (0 when absent), and its sum over `events`.
double DetailValue(const Event& e, const std::string& key);
double SumDetail(const std::vector<Event>& events, const std::string& key);
/// The text of `key=` in an event detail ("" when absent).
std::string DetailText(const Event& e, const std::string& key);
/// The first event of `kind` (kind empty = none found).
Event FirstEvent(const std::string& kind);
/// Time of the first thread_cut event, s (infinity if none).
double FirstThreadCutS();

/// Mean distance of the scope tip from `at` over the sampled frames in [t0, t1], mm (1e300 when
/// no sampled frame lies there).
double ScopeDistanceMm(double t0, double t1, const Vec3& at);
/// The last frame at or before time t_s.
State FrameAt(double t_s);
/// A thread's alive nodes from `from` to its first dead node.
std::vector<Vec3> LimbFrom(const ThreadState& th, int from);
/// The piece (component label) holding every node of a fixed-end region, -1 if split.
int PieceOf(const std::vector<int>& label, const std::string& region);
/// A query world over one bone surface only.
collision::BoneQueryWorld WorldOf(const BoneState& bone);
/// Volume of `bone` inside the box of `r`, mm^3, by the signed distance sampled on a grid of
/// `h_mm` cells (cell centres).
double VolumeInBox(const BoneState& bone, const Region& r, double h_mm);
/// Area of triangle t of the nodes x, mm^2.
double TriArea(const Points& x, const mesh::Tri& t);
/// Distance of p from the line through `a` along unit `axis`, mm.
double FromAxisMm(const Vec3& p, const Vec3& a, const Vec3& axis);

}  // namespace arthrosim::expert
