// Bad input: every problem is an InputError naming the line (ASCII) or byte offset (binary)
// and the field; garbage and mutated files never crash, hang or over-allocate.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "arthrosim/core/error.h"
#include "arthrosim/mesh/mesh_io.h"
#include "arthrosim/mesh/mesh_validate.h"
#include "mesh_test_util.h"

namespace arthrosim::mesh {
namespace {

using testing::DataPath;

// A valid MSH 2.2 file; each test breaks one line of it.
std::vector<std::string> Msh22Lines() {
  return {"$MeshFormat", "2.2 0 8", "$EndMeshFormat",    "$Nodes",      "4",
          "1 0 0 0",     "2 1 0 0", "3 0 1 0",           "4 0 0 1",     "$EndNodes",
          "$Elements",   "1",       "1 4 2 0 1 1 2 3 4", "$EndElements"};
}

std::string Join(const std::vector<std::string>& lines) {
  std::string s;
  for (const std::string& l : lines) s += l + "\n";
  return s;
}

/// Parses and returns the InputError (fails the test if none or another exception is thrown).
InputError ErrorOf(const std::string& name, const std::string& body) {
  try {
    ParseMesh(name, body);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << name << ": expected an InputError";
  return InputError(name, -1, "", "none");
}

std::string Msh22With(int line_1based, const std::string& text) {
  std::vector<std::string> l = Msh22Lines();
  l[static_cast<std::size_t>(line_1based - 1)] = text;
  return Join(l);
}

TEST(MeshErrorsTest, ValidBaseFileParses) {
  const MeshData d = ParseMesh("ok.msh", Join(Msh22Lines()));
  EXPECT_EQ(d.volume.tets.size(), 1u);
}

TEST(MeshErrorsTest, NanCoordinateNamesLineAndField) {
  const InputError e = ErrorOf("nan.msh", Msh22With(8, "3 0 nan 0"));
  EXPECT_EQ(e.line(), 8);
  EXPECT_EQ(e.field(), "node y");
  EXPECT_NE(std::string(e.what()).find("non-finite"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("nan.msh:8"), std::string::npos) << e.what();
}

TEST(MeshErrorsTest, BadNumberNamesLineAndField) {
  const InputError e = ErrorOf("bad.msh", Msh22With(7, "2 1 0 zero"));
  EXPECT_EQ(e.line(), 7);
  EXPECT_EQ(e.field(), "node z");
  EXPECT_NE(std::string(e.what()).find("expected a number"), std::string::npos) << e.what();
}

TEST(MeshErrorsTest, NodeIndexOutOfRange) {
  const InputError e = ErrorOf("idx.msh", Msh22With(13, "1 4 2 0 1 1 2 3 9"));
  EXPECT_EQ(e.line(), 13);
  EXPECT_EQ(e.field(), "element node");
  EXPECT_NE(std::string(e.what()).find("node tag 9"), std::string::npos) << e.what();
}

TEST(MeshErrorsTest, TruncatedFile) {
  std::vector<std::string> l = Msh22Lines();
  l.resize(12);  // ends after the element count
  const InputError e = ErrorOf("cut.msh", Join(l));
  EXPECT_GE(e.line(), 12);
  EXPECT_NE(std::string(e.what()).find("end of file"), std::string::npos) << e.what();
  // Every shorter prefix (cut at any byte) is an error too, never a crash.
  const std::string full = Join(Msh22Lines());
  for (std::size_t n = 0; n + 1 < full.size(); ++n) {
    EXPECT_THROW(ParseMesh("cut.msh", full.substr(0, n)), InputError) << "prefix " << n;
  }
}

TEST(MeshErrorsTest, HugeDeclaredCountIsRejectedBeforeAllocating) {
  const InputError e = ErrorOf("huge.msh", Msh22With(5, "999999999999"));
  EXPECT_EQ(e.line(), 5);
  EXPECT_EQ(e.field(), "number of nodes");
  EXPECT_NE(std::string(e.what()).find("exceeds"), std::string::npos) << e.what();
  const InputError v = ErrorOf("huge.vtk",
                               "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n"
                               "POINTS 4000000000000 double\n0 0 0\n");
  EXPECT_EQ(v.line(), 5);
  EXPECT_EQ(v.field(), "POINTS count");
}

TEST(MeshErrorsTest, UnsupportedVersionAndElementType) {
  const InputError v = ErrorOf("v3.msh", Msh22With(2, "3.0 0 8"));
  EXPECT_EQ(v.line(), 2);
  EXPECT_EQ(v.field(), "version");
  const InputError t = ErrorOf("t11.msh", Msh22With(13, "1 11 2 0 1 1 2 3 4 1 2 3 4 1 2"));
  EXPECT_EQ(t.line(), 13);
  EXPECT_EQ(t.field(), "element type");
  EXPECT_NE(std::string(t.what()).find("unsupported element type 11"), std::string::npos);
}

TEST(MeshErrorsTest, UnknownExtension) {
  const InputError e = ErrorOf("mesh.ply", "ply\n");
  EXPECT_EQ(e.field(), "extension");
  EXPECT_NE(std::string(e.what()).find(".msh"), std::string::npos);
  EXPECT_THROW(ReadMesh("/nonexistent/dir/x.msh"), InputError);
}

TEST(MeshErrorsTest, VtkErrorsNameLineAndField) {
  const std::string head =
      "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n"
      "POINTS 4 double\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n";  // lines 1-9
  const InputError idx = ErrorOf("i.vtk", head + "CELLS 1 5\n4 0 1 2 4\nCELL_TYPES 1\n10\n");
  EXPECT_EQ(idx.line(), 11);
  EXPECT_EQ(idx.field(), "cell point index");
  EXPECT_NE(std::string(idx.what()).find("out of range"), std::string::npos);
  const InputError type = ErrorOf("t.vtk", head + "CELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n12\n");
  EXPECT_EQ(type.line(), 13);
  EXPECT_EQ(type.field(), "cell type");
  const InputError inf = ErrorOf("f.vtk",
                                 "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n"
                                 "POINTS 2 double\n0 0 0\n1 inf 0\n");
  EXPECT_EQ(inf.line(), 7);
  EXPECT_EQ(inf.field(), "point y");
  const InputError bin = ErrorOf("b.vtk", "# vtk DataFile Version 3.0\nt\nBINARY\n");
  EXPECT_EQ(bin.line(), 3);
  EXPECT_EQ(bin.field(), "encoding");
}

TEST(MeshErrorsTest, ObjErrorsNameLineAndField) {
  const InputError idx = ErrorOf("i.obj", "v 0 0 0\nv 1 0 0\n# c\nv 0 1 0\nf 1 2 4\n");
  EXPECT_EQ(idx.line(), 5);
  EXPECT_EQ(idx.field(), "f vertex index");
  const InputError zero = ErrorOf("z.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
  EXPECT_EQ(zero.line(), 4);
  const InputError neg = ErrorOf("n.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
  EXPECT_EQ(neg.line(), 4);
  const InputError vt = ErrorOf("t.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/2 2/1 3/1\n");
  EXPECT_EQ(vt.field(), "f texture index");
  const InputError nan = ErrorOf("nan.obj", "v 0 0 0\nv NaN 0 0\n");
  EXPECT_EQ(nan.line(), 2);
  EXPECT_EQ(nan.field(), "v x");
  const InputError few = ErrorOf("few.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
  EXPECT_EQ(few.line(), 3);
}

TEST(MeshErrorsTest, StlErrors) {
  const InputError nan = ErrorOf("n.stl",
                                 "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
                                 "vertex 1 0 nan\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n");
  EXPECT_EQ(nan.line(), 5);
  EXPECT_EQ(nan.field(), "vertex z");
  const InputError cut =
      ErrorOf("c.stl", "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n");
  EXPECT_NE(std::string(cut.what()).find("end of file"), std::string::npos);
  // Binary with a count that does not match the size.
  std::string bin(84 + 50, '\0');
  const std::uint32_t n = 7;
  std::memcpy(bin.data() + 80, &n, 4);
  const InputError size = ErrorOf("b.stl", bin);
  EXPECT_NE(std::string(size.what()).find("byte offset 80"), std::string::npos) << size.what();
  // Binary with a NaN vertex.
  const std::uint32_t one = 1;
  std::memcpy(bin.data() + 80, &one, 4);
  const float nanf = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(bin.data() + 84 + 12 + 12 + 4, &nanf, 4);
  const InputError bnan = ErrorOf("b.stl", bin);
  EXPECT_NE(std::string(bnan.what()).find("byte offset 108"), std::string::npos) << bnan.what();
}

std::string Slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

TEST(MeshErrorsTest, BinaryMshTruncationAndHugeCountGiveByteOffsets) {
  const std::string full = Slurp(DataPath("box_msh41_bin.msh"));
  ASSERT_GT(full.size(), 1000u);
  const std::size_t nodes = full.find("$Nodes\n");
  ASSERT_NE(nodes, std::string::npos);
  // Cut inside the node data: the message cites a byte offset.
  const InputError e = ErrorOf("cut.msh", full.substr(0, nodes + 7 + 40));
  EXPECT_NE(std::string(e.what()).find("at byte offset"), std::string::npos) << e.what();
  EXPECT_EQ(e.line(), 0);
  // Every 13th prefix: always an InputError.
  for (std::size_t n = 0; n < full.size(); n += 13) {
    EXPECT_THROW(ParseMesh("cut.msh", full.substr(0, n)), InputError) << "prefix " << n;
  }
  // A declared node count of 10^12 in a 30 kB file.
  std::string huge = full;
  const std::uint64_t big = 1000000000000ull;
  std::memcpy(huge.data() + nodes + 7 + 8, &big, 8);
  const InputError h = ErrorOf("huge.msh", huge);
  EXPECT_EQ(h.field(), "number of nodes");
  EXPECT_NE(std::string(h.what()).find("exceeds"), std::string::npos) << h.what();
  EXPECT_NE(std::string(h.what()).find("byte offset " + std::to_string(nodes + 15)),
            std::string::npos)
      << h.what();
}

// Deterministic pseudo-random bytes (LCG): no dependence on std::random implementations.
struct Lcg {
  std::uint64_t s;
  std::uint32_t Next() {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<std::uint32_t>(s >> 33);
  }
};

TEST(MeshErrorsTest, GarbageBytesAreInputErrors) {
  Lcg rng{12345};
  for (const char* ext : {"msh", "vtk", "obj", "stl"}) {
    for (int trial = 0; trial < 20; ++trial) {
      std::string junk(static_cast<std::size_t>(1 + rng.Next() % 3000), '\0');
      for (char& c : junk) c = static_cast<char>(rng.Next() & 0xff);
      EXPECT_THROW(ParseMesh(std::string("junk.") + ext, junk), InputError) << ext << " " << trial;
    }
  }
}

TEST(MeshErrorsTest, MutatedFilesNeverCrash) {
  // Each mutant either parses (and validates or fails validation cleanly) or is an InputError.
  Lcg rng{777};
  int parsed = 0, rejected = 0;
  for (const char* name : {"box_msh22.msh", "box_msh41.msh", "box_msh41_bin.msh", "box.vtk",
                           "box.stl", "box_bin.stl"}) {
    const std::string full = Slurp(DataPath(name));
    for (int trial = 0; trial < 60; ++trial) {
      std::string m = full;
      const int edits = 1 + static_cast<int>(rng.Next() % 4);
      for (int k = 0; k < edits; ++k) {
        const std::size_t at = rng.Next() % m.size();
        const std::uint32_t kind = rng.Next() % 3;
        if (kind == 0) m[at] = static_cast<char>(rng.Next() & 0xff);
        if (kind == 1) m[at] = "0123456789-.e \n$"[rng.Next() % 16];
        if (kind == 2) m.erase(at, 1 + rng.Next() % 8);
      }
      try {
        MeshData d = ParseMesh(name, m);
        OrientAndCheck(&d.volume, name);
        OrientAndCheck(&d.surface, name);
        ++parsed;
      } catch (const InputError&) {
        ++rejected;
      }
    }
  }
  EXPECT_GT(rejected, 0);
  EXPECT_EQ(parsed + rejected, 6 * 60);
}

}  // namespace
}  // namespace arthrosim::mesh
