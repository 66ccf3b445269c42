#pragma once
// Shared helpers for the mesh tests.
#include <filesystem>
#include <string>
#include <utility>

#include "arthrosim/mesh/mesh_io.h"
#include "arthrosim/mesh/mesh_validate.h"

namespace arthrosim::mesh::testing {

/// Path of a committed test file under tests/testdata/mesh.
inline std::string DataPath(const std::string& name) {
  return std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/mesh/" + name;
}

/// A fresh scratch path in the build tree (unique per test name).
inline std::string TempPath(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(ARTHROSIM_BINARY_DIR) / "mesh_test_tmp";
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

/// A conforming tet mesh of the box [0, n*h]^3: n^3 cubes, each split into the 6 Kuhn tets
/// along its main diagonal; all tets positively oriented. Volume (n*h)^3.
inline TetMesh KuhnCube(int n, double h) {
  TetMesh m;
  const int s = n + 1;
  m.nodes.resize(3, s * s * s);
  for (int k = 0; k < s; ++k) {
    for (int j = 0; j < s; ++j) {
      for (int i = 0; i < s; ++i) m.nodes.col(i + s * (j + s * k)) = Vec3(i * h, j * h, k * h);
    }
  }
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  const int step[3] = {1, s, s * s};
  for (int k = 0; k < n; ++k) {
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        const int base = i + s * (j + s * k);
        for (const auto& p : perms) {
          Tet t{base, base + step[p[0]], base + step[p[0]] + step[p[1]],
                base + step[0] + step[1] + step[2]};
          if (TetSignedVolume(m.nodes, t) < 0) std::swap(t[2], t[3]);
          m.tets.push_back(t);
        }
      }
    }
  }
  return m;
}

}  // namespace arthrosim::mesh::testing
