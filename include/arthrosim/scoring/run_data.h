#pragma once
// What scoring needs from a run file, read once through io::RunReader (docs/hdf5-layout.md):
// per-frame times, instrument tips and forces, camera, bone removed volumes, tool contacts,
// events, and the last frame's State. Scoring never simulates.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::scoring {

/// One instrument over the run, one entry per frame.
struct InstrumentSeries {
  std::string name;
  std::string kind;                  ///< InstrumentKindName
  std::vector<std::uint8_t> active;  ///< 1 while inserted in a tool slot
  std::vector<Pose> pose;            ///< tip pose (meaningful while active)
  std::vector<double> force_n;       ///< |contact force| on the instrument, N (0 when out)
  std::vector<std::int8_t> slot;     ///< tool slot holding it, -1 if none
  /// 1 while inserted with its tip seen by the scope: in the view cone and not hidden behind
  /// tissue or bone of that frame (TipVisible, margin = the instrument's tip radius).
  std::vector<std::uint8_t> tip_visible;
};

struct RunData {
  std::string path;
  Model model;
  std::vector<double> time_s;                         ///< per frame
  std::vector<std::int64_t> step;                     ///< per frame
  std::vector<InstrumentSeries> instruments;          ///< Model order
  std::vector<CameraState> camera;                    ///< per frame
  std::vector<std::vector<double>> bone_removed_mm3;  ///< [bone][frame]
  std::vector<std::vector<ToolContact>> contacts;     ///< per frame
  /// [landmark][frame] (Model::landmarks order): 1 when the scope sees the landmark, in the view
  /// cone and not hidden behind that frame's tissue or bone (FrameSight::SeesLandmark).
  std::vector<std::vector<std::uint8_t>> landmark_visible;
  std::vector<Event> events;  ///< every event, in order
  State last;                 ///< the last frame
  bool video_beside = false;  ///< a .mp4 with the run's stem sits next to it
  std::string video_path;

  std::int64_t frames() const { return static_cast<std::int64_t>(time_s.size()); }
  /// First frame whose time is >= t_s (frames() - 1 if none).
  std::int64_t FrameAt(double t_s) const;
};

/// Loads the Model of a run: `scenario_override` if non-empty, else the scenario text stored
/// in the run (meshes resolved next to its stored path).
/// @throws InputError if the scenario or its meshes cannot be found or read.
Model LoadRunModel(const std::string& run_path, const std::string& scenario_override);

/// Reads a run file. `model` (from LoadRunModel, or built by a caller) must match the run.
/// @throws InputError if the file is not a readable run or does not match the model.
RunData ReadRunData(const std::string& run_path, Model model);

/// Whether the scope sees `point_mm` in frame `k`: inside the image circle (half the model's
/// field of view around the oblique view direction) and between the near and far planes.
bool PointInView(const Model& model, const CameraState& camera, const Vec3& point_mm);

/// Angle (deg, [0, 180]) between the image up of the scope and world +z projected into the
/// image plane; 0 when the view looks straight up or down (no horizon).
double HorizonDeviationDeg(const Model& model, const CameraState& camera);

}  // namespace arthrosim::scoring
