// Readers and writers: the same gmsh-generated box read through every format path, round trips
// of each writer, and the format features (sparse tags, OBJ index forms, groups).
#include "arthrosim/mesh/mesh_io.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <vector>

#include "arthrosim/core/error.h"
#include "arthrosim/mesh/mesh_validate.h"
#include "arthrosim/mesh/surface.h"
#include "mesh_test_util.h"

namespace arthrosim::mesh {
namespace {

using testing::DataPath;
using testing::TempPath;

// The box in tests/testdata/mesh/box.geo: [0,4] x [0,2] x [0,1] mm.
constexpr double kBoxVolume = 8.0;
constexpr double kBoxArea = 2 * (4 * 2 + 4 * 1 + 2 * 1);

double TriArea(const Points& p, const Tri& t) {
  return 0.5 * (p.col(t[1]) - p.col(t[0])).cross(p.col(t[2]) - p.col(t[0])).norm();
}

const PhysicalGroup* FindGroup(const MeshData& d, const std::string& name) {
  for (const PhysicalGroup& g : d.groups) {
    if (g.name == name) return &g;
  }
  return nullptr;
}

// Triangles as sorted coordinate triples, so meshes with different node numbering compare.
std::vector<std::array<double, 9>> GeometricTris(const TriMesh& m) {
  std::vector<std::array<double, 9>> out;
  for (const Tri& t : m.tris) {
    std::array<std::array<double, 3>, 3> v;
    for (int k = 0; k < 3; ++k) {
      for (int c = 0; c < 3; ++c) v[k][c] = m.nodes(c, t[k]);
    }
    // Rotate so the smallest vertex is first: keeps orientation, removes the start choice.
    const auto first = std::min_element(v.begin(), v.end()) - v.begin();
    std::rotate(v.begin(), v.begin() + first, v.end());
    std::array<double, 9> flat;
    for (int k = 0; k < 3; ++k) {
      for (int c = 0; c < 3; ++c) flat[3 * k + c] = v[k][c];
    }
    out.push_back(flat);
  }
  std::sort(out.begin(), out.end());
  return out;
}

void ExpectSameElements(const MeshData& a, const MeshData& b) {
  EXPECT_EQ(a.volume.tets, b.volume.tets);
  EXPECT_EQ(a.surface.tris, b.surface.tris);
  EXPECT_EQ(a.lines.edges, b.lines.edges);
}

void ExpectSameGroups(const MeshData& a, const MeshData& b) {
  ASSERT_EQ(a.groups.size(), b.groups.size());
  for (std::size_t i = 0; i < a.groups.size(); ++i) {
    EXPECT_EQ(a.groups[i].dim, b.groups[i].dim);
    EXPECT_EQ(a.groups[i].tag, b.groups[i].tag);
    EXPECT_EQ(a.groups[i].name, b.groups[i].name);
    EXPECT_EQ(a.groups[i].elements, b.groups[i].elements);
  }
  EXPECT_EQ(a.tet_physical, b.tet_physical);
  EXPECT_EQ(a.tri_physical, b.tri_physical);
  EXPECT_EQ(a.line_physical, b.line_physical);
}

TEST(GmshBoxTest, AllMshVariantsGiveTheSameMesh) {
  const MeshData m22 = ReadMesh(DataPath("box_msh22.msh"));
  const MeshData m41 = ReadMesh(DataPath("box_msh41.msh"));
  const MeshData bin = ReadMesh(DataPath("box_msh41_bin.msh"));
  EXPECT_EQ(m22.format, "msh2.2");
  EXPECT_EQ(m41.format, "msh4.1");
  EXPECT_EQ(bin.format, "msh4.1-binary");
  for (const MeshData* d : {&m41, &bin}) {
    ASSERT_EQ(d->num_nodes(), m22.num_nodes());
    // gmsh prints 16 significant digits in ASCII; binary is exact.
    EXPECT_LT((d->volume.nodes - m22.volume.nodes).cwiseAbs().maxCoeff(), 1e-14);
    ExpectSameElements(m22, *d);
    ExpectSameGroups(m22, *d);
  }
  EXPECT_EQ(m41.node_tags, bin.node_tags);
}

TEST(GmshBoxTest, GeometryAndNamedRegionsMatchTheGeoFile) {
  MeshData d = ReadMesh(DataPath("box_msh41_bin.msh"));
  ASSERT_GT(d.volume.tets.size(), 100u);
  const Points& p = d.volume.nodes;
  EXPECT_NEAR(p.row(0).minCoeff(), 0.0, 1e-12);
  EXPECT_NEAR(p.row(0).maxCoeff(), 4.0, 1e-12);
  EXPECT_NEAR(p.row(1).maxCoeff(), 2.0, 1e-12);
  EXPECT_NEAR(p.row(2).maxCoeff(), 1.0, 1e-12);
  TetQualityReport rep = OrientAndCheck(&d.volume, "box");
  EXPECT_EQ(rep.degenerate.size(), 0u);
  EXPECT_NEAR(TotalVolume(d.volume), kBoxVolume, 1e-12 * kBoxVolume);

  // Group names and tags from box.geo; surface 5 (z = 0) is in both surface groups.
  const PhysicalGroup* tendon = FindGroup(d, "tendon");
  const PhysicalGroup* skin = FindGroup(d, "skin");
  const PhysicalGroup* foot = FindGroup(d, "footprint");
  const PhysicalGroup* edge = FindGroup(d, "edge");
  ASSERT_TRUE(tendon && skin && foot && edge);
  EXPECT_EQ(tendon->dim, 3);
  EXPECT_EQ(tendon->tag, 7);
  EXPECT_EQ(tendon->elements.size(), d.volume.tets.size());
  EXPECT_EQ(skin->tag, 4);
  EXPECT_EQ(skin->elements.size(), d.surface.tris.size());
  EXPECT_EQ(foot->tag, 3);
  EXPECT_EQ(edge->dim, 1);
  EXPECT_EQ(edge->tag, 11);
  double skin_area = 0, foot_area = 0;
  for (const std::int32_t t : skin->elements) skin_area += TriArea(p, d.surface.tris[t]);
  for (const std::int32_t t : foot->elements) {
    foot_area += TriArea(p, d.surface.tris[t]);
    for (const std::int32_t n : d.surface.tris[t]) EXPECT_EQ(p(2, n), 0.0);
    EXPECT_EQ(d.tri_physical[t], 3);  // first group in file order is footprint
  }
  EXPECT_NEAR(skin_area, kBoxArea, 1e-12 * kBoxArea);
  EXPECT_NEAR(foot_area, 8.0, 1e-12 * 8.0);
  // The curve "edge" spans the box's 1 mm edge on x = y = 0.
  double len = 0;
  for (const Edge& e : d.lines.edges) len += (p.col(e[1]) - p.col(e[0])).norm();
  EXPECT_NEAR(len, 1.0, 1e-12);
  // The skin is the tets' boundary, as the same node indices.
  EXPECT_EQ(GeometricTris(d.surface).size(), ExtractBoundary(d.volume.tets).size());
  EXPECT_NEAR(EnclosedVolume(BoundaryTriMesh(d.volume)), kBoxVolume, 1e-12 * kBoxVolume);
}

TEST(GmshBoxTest, VtkAndStlExportsAgreeWithMsh) {
  const MeshData msh = ReadMesh(DataPath("box_msh41_bin.msh"));
  const MeshData vtk = ReadMesh(DataPath("box.vtk"));
  ASSERT_EQ(vtk.num_nodes(), msh.num_nodes());
  EXPECT_LT((vtk.volume.nodes - msh.volume.nodes).cwiseAbs().maxCoeff(), 1e-14);
  ExpectSameElements(msh, vtk);
  const auto ref = GeometricTris(msh.surface);
  for (const char* name : {"box.stl", "box_bin.stl"}) {
    SCOPED_TRACE(name);
    const MeshData stl = ReadMesh(DataPath(name));
    ASSERT_EQ(stl.surface.tris.size(), msh.surface.tris.size());
    // Merged vertices: exactly the distinct surface nodes.
    std::vector<std::int32_t> used;
    for (const Tri& t : msh.surface.tris) used.insert(used.end(), t.begin(), t.end());
    std::sort(used.begin(), used.end());
    used.erase(std::unique(used.begin(), used.end()), used.end());
    EXPECT_EQ(stl.num_nodes(), static_cast<std::int64_t>(used.size()));
    // STL stores float32 (binary) or ~7-10 digits (ASCII): map each STL vertex to the msh node
    // within 1e-6 mm, then compare oriented triangles as node-index triples.
    std::vector<std::int32_t> to_msh(static_cast<std::size_t>(stl.num_nodes()), -1);
    for (Eigen::Index i = 0; i < stl.surface.nodes.cols(); ++i) {
      for (const std::int32_t n : used) {
        if ((stl.surface.nodes.col(i) - msh.surface.nodes.col(n)).cwiseAbs().maxCoeff() < 1e-6) {
          EXPECT_EQ(to_msh[static_cast<std::size_t>(i)], -1) << "two msh nodes match";
          to_msh[static_cast<std::size_t>(i)] = n;
        }
      }
      ASSERT_GE(to_msh[static_cast<std::size_t>(i)], 0) << "STL vertex " << i << " matches no node";
    }
    TriMesh mapped;
    mapped.nodes = msh.surface.nodes;
    for (const Tri& t : stl.surface.tris) {
      mapped.tris.push_back({to_msh[static_cast<std::size_t>(t[0])],
                             to_msh[static_cast<std::size_t>(t[1])],
                             to_msh[static_cast<std::size_t>(t[2])]});
    }
    EXPECT_EQ(GeometricTris(mapped), ref);
    EXPECT_NEAR(EnclosedVolume(stl.surface), kBoxVolume, 1e-5);
  }
}

TEST(ConvenienceReadersTest, PickTheRightElements) {
  const TetMesh tets = ReadTetMesh(DataPath("box_msh22.msh"));
  EXPECT_GT(tets.tets.size(), 0u);
  const TriMesh tris = ReadTriMesh(DataPath("box_msh22.msh"));
  EXPECT_GT(tris.tris.size(), 0u);
  const LineMesh lines = ReadLineMesh(DataPath("box_msh22.msh"));
  EXPECT_EQ(lines.edges.size(), 2u);
  EXPECT_THROW(ReadTetMesh(DataPath("box.stl")), InputError);
  EXPECT_THROW(ReadLineMesh(DataPath("box.stl")), InputError);

  // A tet-only file: ReadTriMesh gives the boundary with the same node indices.
  MeshData only = ReadMesh(DataPath("box_msh41.msh"));
  only.surface.tris.clear();
  only.lines.edges.clear();
  only.groups.clear();
  only.tri_physical.clear();
  only.line_physical.clear();
  const std::string path = TempPath("tets_only.msh");
  WriteMsh41Ascii(path, only);
  const TriMesh b = ReadTriMesh(path);
  EXPECT_EQ(b.nodes, only.volume.nodes);
  const std::vector<BoundaryFace> faces = ExtractBoundary(only.volume.tets);
  ASSERT_EQ(b.tris.size(), faces.size());
  for (std::size_t i = 0; i < faces.size(); ++i) EXPECT_EQ(b.tris[i], faces[i].nodes);
}

// `a` written to the temporary file `name` by `write` and read back.
MeshData WrittenAndRead(const MeshData& a, const std::string& name,
                        void (*write)(const std::string&, const MeshData&)) {
  const std::string path = TempPath(name);
  write(path, a);
  return ReadMesh(path);
}

TEST(RoundTripTest, Msh41KeepsEverythingBitExact) {
  const MeshData a = ReadMesh(DataPath("box_msh41_bin.msh"));
  const MeshData b = WrittenAndRead(a, "round.msh", WriteMsh41Ascii);
  EXPECT_EQ(b.volume.nodes, a.volume.nodes);  // shortest round-trip text: bit-exact
  ExpectSameElements(a, b);
  ExpectSameGroups(a, b);
}

TEST(RoundTripTest, VtkKeepsNodesElementsAndPhysicalTags) {
  const MeshData a = ReadMesh(DataPath("box_msh22.msh"));
  const MeshData b = WrittenAndRead(a, "round.vtk", WriteVtk);
  EXPECT_EQ(b.volume.nodes, a.volume.nodes);
  ExpectSameElements(a, b);
  EXPECT_EQ(b.tet_physical, a.tet_physical);
  EXPECT_EQ(b.tri_physical, a.tri_physical);
  EXPECT_EQ(b.line_physical, a.line_physical);
}

TEST(RoundTripTest, ObjKeepsTrianglesAndLines) {
  const MeshData a = ReadMesh(DataPath("box_msh41.msh"));
  const MeshData b = WrittenAndRead(a, "round.obj", WriteObj);
  EXPECT_EQ(b.surface.nodes, a.surface.nodes);
  EXPECT_EQ(b.surface.tris, a.surface.tris);
  EXPECT_EQ(b.lines.edges, a.lines.edges);
}

TEST(RoundTripTest, StlBinaryKeepsFloatExactSurface) {
  // A box with float32-exact coordinates: the triangles come back bit-identical (the merged
  // node numbering follows first use, so compare geometry).
  TriMesh cube;
  cube.nodes.resize(3, 8);
  for (int i = 0; i < 8; ++i) {
    cube.nodes.col(i) = Vec3(0.5 * (i & 1), 1.25 * ((i >> 1) & 1), -2.0 * ((i >> 2) & 1));
  }
  cube.tris = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
               {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  const std::string path = TempPath("round.stl");
  WriteStlBinary(path, cube);
  const MeshData b = ReadMesh(path);
  EXPECT_EQ(b.format, "stl-binary");
  EXPECT_EQ(b.num_nodes(), 8);
  EXPECT_EQ(GeometricTris(b.surface), GeometricTris(cube));  // float-exact coordinates
  EXPECT_NEAR(std::abs(EnclosedVolume(b.surface)), 0.5 * 1.25 * 2.0, 1e-15);
}

// The volume of `m` is the one tet `t`.
void ExpectOnlyTet(const MeshData& m, const Tet& t) {
  ASSERT_EQ(m.volume.tets.size(), 1u);
  EXPECT_EQ(m.volume.tets[0], t);
}

TEST(MshTest, SparseNodeTagsAreRenumberedInFileOrder) {
  const std::string v2 =
      "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n"
      "100 0 0 0\n7 1 0 0\n5000000000 0 1 0\n3 0 0 1\n$EndNodes\n"
      "$Elements\n2\n1 15 2 0 1 7\n2 4 2 0 1 100 7 5000000000 3\n$EndElements\n";
  const MeshData a = ParseMesh("sparse.msh", v2);
  ExpectOnlyTet(a, Tet{0, 1, 2, 3});
  EXPECT_EQ(a.node_tags, (std::vector<std::int64_t>{100, 7, 5000000000, 3}));
  EXPECT_EQ(a.volume.nodes.col(2), Vec3(0, 1, 0));

  const std::string v4 =
      "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 0 1\n"
      "1 0 0 0 1 1 1 0 0\n$EndEntities\n$Nodes\n2 4 3 90\n"
      "3 1 0 2\n90\n12\n0 0 1\n0 1 0\n"
      "3 1 1 2\n3\n40\n1 0 0 0.1 0.2 0.3\n0 0 0 0.4 0.5 0.6\n$EndNodes\n"
      "$Elements\n1 1 1 1\n3 1 4 1\n1 40 3 12 90\n$EndElements\n";
  const MeshData b = ParseMesh("sparse4.msh", v4);
  ExpectOnlyTet(b, Tet{3, 2, 1, 0});
  EXPECT_EQ(b.volume.nodes.col(3), Vec3(0, 0, 0));  // parametric u v w skipped
  EXPECT_EQ(b.volume.nodes.col(0), Vec3(0, 0, 1));
}

TEST(MshTest, DuplicateElementsOfMsh2AreMergedAcrossGroups) {
  // MSH 2 repeats an element once per physical group; here the repeats are not adjacent.
  const std::string msh =
      "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
      "$PhysicalNames\n2\n3 1 \"a\"\n3 2 \"b\"\n$EndPhysicalNames\n"
      "$Nodes\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n$EndNodes\n"
      "$Elements\n4\n"
      "1 4 2 1 1 1 2 3 4\n"
      "2 4 2 1 1 2 3 4 5\n"
      "3 4 2 2 1 1 2 3 4\n"
      "4 4 2 2 9 1 2 3 4\n"  // same nodes, another entity: a distinct element
      "$EndElements\n";
  const MeshData d = ParseMesh("dup.msh", msh);
  EXPECT_EQ(d.volume.tets, (std::vector<Tet>{{0, 1, 2, 3}, {1, 2, 3, 4}, {0, 1, 2, 3}}));
  EXPECT_EQ(d.tet_physical, (std::vector<int>{1, 1, 2}));
  ASSERT_EQ(d.groups.size(), 2u);
  EXPECT_EQ(d.groups[0].name, "a");
  EXPECT_EQ(d.groups[0].elements, (std::vector<std::int32_t>{0, 1}));
  EXPECT_EQ(d.groups[1].name, "b");
  EXPECT_EQ(d.groups[1].elements, (std::vector<std::int32_t>{0, 2}));
}

TEST(ObjTest, IndexFormsNegativeIndicesFansLinesAndGroups) {
  const std::string obj =
      "# square, a pentagon fan and a polyline\n"
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
      "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"
      "g plate\n"
      "f 1/1 2/2 3/3\n"
      "f 1//1 3//1 4//1\n"
      "v 2 0 0\nv 3 0 0\nv 3 1 0\nv 2.5 2 0\nv 2 1 0\n"
      "o lid\n"
      "f -5/1/1 -4/2/1 -3/3/1 -2 -1\n"
      "g\n"
      "l 1 2 3\n";
  const MeshData d = ParseMesh("feat.obj", obj);
  ASSERT_EQ(d.num_nodes(), 9);
  const std::vector<Tri> expect = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}, {4, 7, 8}};
  EXPECT_EQ(d.surface.tris, expect);
  EXPECT_EQ(d.lines.edges, (std::vector<Edge>{{0, 1}, {1, 2}}));
  EXPECT_EQ(d.tri_physical, (std::vector<int>{1, 1, 2, 2, 2}));
  const PhysicalGroup* plate = FindGroup(d, "plate");
  const PhysicalGroup* lid = FindGroup(d, "lid");
  ASSERT_TRUE(plate && lid);
  EXPECT_EQ(plate->elements, (std::vector<std::int32_t>{0, 1}));
  EXPECT_EQ(lid->elements, (std::vector<std::int32_t>{2, 3, 4}));
  EXPECT_EQ(d.line_physical, (std::vector<int>{0, 0}));  // "g" with no name ends the group
}

TEST(VtkTest, ReadsVersion51OffsetsLayout) {
  const std::string vtk =
      "# vtk DataFile Version 5.1\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n"
      "POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\n"
      "CELLS 4 9\nOFFSETS vtktypeint64\n0 4 7 9\nCONNECTIVITY vtktypeint64\n0 1 2 3 0 2 1 2 3\n"
      "CELL_TYPES 3\n10\n5\n3\n";
  const MeshData d = ParseMesh("v51.vtk", vtk);
  EXPECT_EQ(d.volume.tets, (std::vector<Tet>{{0, 1, 2, 3}}));
  EXPECT_EQ(d.surface.tris, (std::vector<Tri>{{0, 2, 1}}));
  EXPECT_EQ(d.lines.edges, (std::vector<Edge>{{2, 3}}));
}

TEST(StlTest, AsciiMergesCoincidentVerticesAndDropsCollapsedFacets) {
  const std::string stl =
      "solid two\n"
      "facet normal 0 0 1\n outer loop\n vertex 0 0 0\n vertex 1 0 0\n vertex 0 1 0\n"
      " endloop\nendfacet\n"
      "facet normal 0 0 1\n outer loop\n vertex 1 0 0\n vertex 1 1 0\n vertex 0 1 0\n"
      " endloop\nendfacet\n"
      "facet normal 0 0 0\n outer loop\n vertex 1 0 0\n vertex 1 0 0\n vertex 0 1 0\n"
      " endloop\nendfacet\n"
      "endsolid two\n";
  const MeshData d = ParseMesh("two.stl", stl);
  EXPECT_EQ(d.num_nodes(), 4);
  EXPECT_EQ(d.surface.tris, (std::vector<Tri>{{0, 1, 2}, {1, 3, 2}}));
  ASSERT_EQ(d.warnings.size(), 1u);
}

}  // namespace
}  // namespace arthrosim::mesh
