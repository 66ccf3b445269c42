#include "op_scene.h"

#include <cmath>
#include <limits>
#include <numeric>

#include "arthrosim/io/scenario_loader.h"

namespace arthrosim::testing {

mesh::TetMesh GridMesh(const Vec3& lo, const std::array<int, 3>& n, double cell) {
  mesh::TetMesh m;
  const int nx = n[0] + 1, ny = n[1] + 1, nz = n[2] + 1;
  m.nodes.resize(3, nx * ny * nz);
  auto id = [&](int i, int j, int k) { return i + nx * (j + ny * k); };
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) m.nodes.col(id(i, j, k)) = lo + cell * Vec3(i, j, k);
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i) {
        const int c[8] = {id(i, j, k),         id(i + 1, j, k),        id(i, j + 1, k),
                          id(i + 1, j + 1, k), id(i, j, k + 1),        id(i + 1, j, k + 1),
                          id(i, j + 1, k + 1), id(i + 1, j + 1, k + 1)};
        const int paths[6][4] = {{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7},
                                 {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}};
        for (const auto& p : paths) {
          mesh::Tet t{c[p[0]], c[p[1]], c[p[2]], c[p[3]]};
          const Vec3 a = m.nodes.col(t[0]);
          if ((m.nodes.col(t[1]) - a).dot((m.nodes.col(t[2]) - a).cross(m.nodes.col(t[3]) - a)) <
              0) {
            std::swap(t[2], t[3]);
          }
          m.tets.push_back(t);
        }
      }
  return m;
}

Model GridModel(const mesh::TetMesh& mesh, const std::function<bool(const Vec3&)>& fixed) {
  Model m =
      io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/scenes/small.yaml");
  SoftBodyModel& b = m.soft_bodies[0];
  b.rest_mesh = mesh;
  b.fixed_nodes.clear();
  for (int i = 0; i < mesh.nodes.cols(); ++i) {
    if (fixed(mesh.nodes.col(i))) b.fixed_nodes.push_back(i);
  }
  m.regions.clear();
  m.landmarks.clear();
  m.instruments.clear();
  const std::pair<const char*, InstrumentKind> kinds[] = {
      {"scissors", InstrumentKind::kScissors},
      {"cutter", InstrumentKind::kCutter},
      {"shaver", InstrumentKind::kShaver},
      {"electrocautery", InstrumentKind::kElectrocautery},
      {"grasper", InstrumentKind::kGrasper}};
  for (const auto& [name, kind] : kinds) {
    InstrumentModel im;
    im.name = name;
    im.kind = kind;
    im.portal = "lateral";
    m.instruments.push_back(im);
  }
  return m;
}

InputFrame ToolInput(const Model& m, const std::string& name, const Vec3& position,
                     const Vec3& tool_x, const Vec3& tool_z, double jaw, int buttons) {
  InputFrame f;
  f.camera.pose = m.camera.initial_pose;
  f.tools[0].instrument = m.FindInstrument(name);
  f.tools[0].pose.position_mm = position;
  Mat3 r;
  r.col(0) = tool_x.normalized();
  r.col(2) = tool_z.normalized();
  r.col(1) = r.col(2).cross(r.col(0));
  f.tools[0].pose.orientation = Quat(r);
  f.tools[0].jaw = jaw;
  f.tools[0].buttons = static_cast<std::uint8_t>(buttons);
  return f;
}

int AliveComponents(const State& s, int body) {
  const SoftBodyState& b = s.soft_bodies[static_cast<std::size_t>(body)];
  std::vector<int> parent(static_cast<std::size_t>(b.x.cols()));
  std::iota(parent.begin(), parent.end(), 0);
  std::function<int(int)> find = [&](int i) {
    while (parent[static_cast<std::size_t>(i)] != i) i = parent[static_cast<std::size_t>(i)];
    return i;
  };
  std::vector<std::uint8_t> used(parent.size(), 0);
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    for (int k = 0; k < 4; ++k) {
      used[static_cast<std::size_t>(b.tets[t][k])] = 1;
      parent[static_cast<std::size_t>(find(b.tets[t][k]))] = find(b.tets[t][0]);
    }
  }
  int count = 0;
  for (std::size_t i = 0; i < parent.size(); ++i) {
    if (used[i] && find(static_cast<int>(i)) == static_cast<int>(i)) ++count;
  }
  return count;
}

double AliveRestVolume(const State& s, int body) {
  const SoftBodyState& b = s.soft_bodies[static_cast<std::size_t>(body)];
  double v = 0;
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    const mesh::Tet& e = b.tets[t];
    const Vec3 a = b.x_rest.col(e[0]);
    v += (b.x_rest.col(e[1]) - a).dot((b.x_rest.col(e[2]) - a).cross(b.x_rest.col(e[3]) - a)) / 6;
  }
  return v;
}

std::vector<Event> EventsOf(const State& s, const std::string& kind) {
  std::vector<Event> out;
  for (const Event& e : s.events) {
    if (e.kind == kind) out.push_back(e);
  }
  return out;
}

static std::string Value(const std::string& detail, const std::string& key) {
  const std::string k = key + "=";
  std::size_t at = 0;
  while ((at = detail.find(k, at)) != std::string::npos) {
    if (at == 0 || detail[at - 1] == ' ') {
      const std::size_t end = detail.find(' ', at);
      return detail.substr(at + k.size(), end == std::string::npos ? end : end - at - k.size());
    }
    at += k.size();
  }
  return "";
}

long long DetailInt(const std::string& detail, const std::string& key) {
  const std::string v = Value(detail, key);
  return v.empty() ? -1 : std::stoll(v);
}

double DetailNumber(const std::string& detail, const std::string& key) {
  const std::string v = Value(detail, key);
  return v.empty() ? std::numeric_limits<double>::quiet_NaN() : std::stod(v);
}

}  // namespace arthrosim::testing
