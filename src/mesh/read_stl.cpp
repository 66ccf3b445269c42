// STL reader, ASCII and binary. Vertices with bit-identical coordinates are merged (first
// appearance order) so the surface comes out indexed and, for a watertight part, closed.
// Facets that collapse to a repeated vertex are dropped with a warning.
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>

#include "mesh_builder.h"

namespace arthrosim::mesh::detail {
namespace {

class StlReader {
 public:
  explicit StlReader(Cursor& c) : c_(c) {}

  MeshData Read() {
    const std::string_view all = c_.bytes();
    bool binary = false;
    if (all.size() >= 84) {
      std::uint32_t n = 0;
      std::memcpy(&n, all.data() + 80, 4);
      binary = 84 + 50 * static_cast<std::uint64_t>(n) == all.size();
    }
    std::size_t first = 0;
    while (first < all.size() && Cursor::IsSpace(all[first])) ++first;
    const bool ascii = !binary && all.substr(first, 5) == "solid";
    if (binary) {
      ReadBinary();
    } else if (ascii) {
      ReadAscii();
    } else if (all.size() >= 84) {
      std::uint32_t n = 0;
      std::memcpy(&n, all.data() + 80, 4);
      c_.FailAt(80, "triangle count",
                "binary STL declares " + std::to_string(n) + " triangles, which need " +
                    std::to_string(84 + 50 * static_cast<std::uint64_t>(n)) +
                    " bytes, but the file has " + std::to_string(all.size()) +
                    " (truncated or not an STL file)");
    } else {
      c_.FailAt(0, "header",
                "not an STL file: neither ASCII (starting with 'solid') nor binary (84+ bytes)");
    }
    if (dropped_ > 0) {
      b_.Warn(std::to_string(dropped_) + " degenerate STL facet(s) with repeated vertices dropped");
    }
    return b_.Finish(binary ? "stl-binary" : "stl");
  }

 private:
  std::int32_t Vertex(double x, double y, double z) {
    const std::array<double, 3> key{x, y, z};
    const auto [it, inserted] = index_.emplace(key, static_cast<std::int32_t>(b_.num_nodes()));
    if (inserted) b_.AddNode(b_.num_nodes() + 1, x, y, z);
    return it->second;
  }

  void AddFacet(const std::int32_t* v) {
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) {
      ++dropped_;
      return;
    }
    b_.AddElement(2, v, {});
  }

  void ReadBinary() {
    c_.SetBinaryMode(true);
    c_.SkipBytes(80, "header");
    const std::uint32_t n = c_.Bin<std::uint32_t>("triangle count");
    for (std::uint32_t t = 0; t < n; ++t) {
      c_.SkipBytes(12, "facet normal");
      std::int32_t v[3];
      for (int k = 0; k < 3; ++k) {
        const std::size_t at = c_.pos();
        float p[3];
        for (float& f : p) f = c_.Bin<float>("vertex");
        for (const float f : p) {
          if (!std::isfinite(f)) {
            c_.FailAt(at, "vertex", "non-finite coordinate in facet " + std::to_string(t));
          }
        }
        v[k] = Vertex(p[0], p[1], p[2]);
      }
      c_.SkipBytes(2, "attribute byte count");
      AddFacet(v);
    }
  }

  void ReadAscii() {
    bool in_solid = false;
    for (;;) {
      const std::string_view t = c_.TryToken();
      if (t.empty()) break;
      if (t == "solid") {
        if (in_solid) c_.Fail("solid", "'solid' inside a solid (missing endsolid)");
        c_.RestOfLine();
        in_solid = true;
      } else if (t == "endsolid") {
        if (!in_solid) c_.Fail("endsolid", "'endsolid' without 'solid'");
        c_.RestOfLine();
        in_solid = false;
      } else if (t == "facet") {
        if (!in_solid) c_.Fail("facet", "'facet' outside 'solid'");
        c_.Expect("normal", "facet normal");
        for (int k = 0; k < 3; ++k) c_.Real("facet normal");
        c_.Expect("outer", "outer loop");
        c_.Expect("loop", "outer loop");
        std::int32_t v[3];
        for (int k = 0; k < 3; ++k) {
          c_.Expect("vertex", "vertex");
          const double x = c_.Finite("vertex x");
          const double y = c_.Finite("vertex y");
          const double z = c_.Finite("vertex z");
          v[k] = Vertex(x, y, z);
        }
        c_.Expect("endloop", "endloop");
        c_.Expect("endfacet", "endfacet");
        AddFacet(v);
      } else {
        c_.Fail("keyword", "expected 'facet' or 'endsolid' but found '" + Cursor::Shorten(t) + "'");
      }
    }
    if (in_solid) c_.Fail("endsolid", "missing 'endsolid' at end of file (truncated?)");
  }

  Cursor& c_;
  MeshBuilder b_;
  std::map<std::array<double, 3>, std::int32_t> index_;
  std::int64_t dropped_ = 0;
};

}  // namespace

MeshData ReadStl(Cursor& cur) { return StlReader(cur).Read(); }

}  // namespace arthrosim::mesh::detail
