// Gmsh MSH reader: 2.2 ASCII, 4.1 ASCII and 4.1 binary. Only linear simplices are kept
// (type 1 line, 2 triangle, 4 tetrahedron); points (15) are skipped, anything else is an error.
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "mesh_builder.h"

namespace arthrosim::mesh::detail {
namespace {

constexpr std::int64_t kMaxInt32 = std::numeric_limits<std::int32_t>::max();

/// Nodes per element type, with the element's dimension; dim -1 = unsupported.
struct ElementKind {
  int nodes = 0;
  int dim = -1;
};
ElementKind KindOf(std::int64_t type) {
  switch (type) {
    case 1:
      return {2, 1};
    case 2:
      return {3, 2};
    case 4:
      return {4, 3};
    case 15:
      return {1, 0};
    default:
      return {};
  }
}
std::string UnsupportedType(std::int64_t type) {
  return "unsupported element type " + std::to_string(type) +
         " (supported: 1 line, 2 triangle, 4 tetrahedron, 15 point; re-mesh with linear "
         "simplices, e.g. gmsh -3 -order 1)";
}

/// Reads values either as ASCII tokens or as binary (int = int32, size_t = uint64, double).
class Values {
 public:
  Values(Cursor& c, bool binary) : c_(c), bin_(binary) {}
  bool binary() const { return bin_; }
  void set_binary(bool b) {
    bin_ = b;
    c_.SetBinaryMode(b);
  }
  Cursor& cursor() { return c_; }

  [[noreturn]] void Fail(const std::string& field, const std::string& msg) {
    if (bin_) c_.FailAt(last_, field, msg);
    c_.Fail(field, msg);
  }
  std::int64_t Size(const std::string& field) {
    if (!bin_) {
      const std::int64_t v = c_.Int(field);
      if (v < 0) c_.Fail(field, "expected a non-negative integer but found " + std::to_string(v));
      return v;
    }
    last_ = c_.pos();
    const std::uint64_t v = c_.Bin<std::uint64_t>(field);
    if (v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
      Fail(field, "value " + std::to_string(v) + " too large");
    }
    return static_cast<std::int64_t>(v);
  }
  int Int(const std::string& field) {
    if (!bin_) return static_cast<int>(c_.IntIn(field, -kMaxInt32, kMaxInt32));
    last_ = c_.pos();
    return c_.Bin<std::int32_t>(field);
  }
  int IntIn(const std::string& field, int lo, int hi) {
    const int v = Int(field);
    if (v < lo || v > hi) {
      Fail(field, "value " + std::to_string(v) + " out of range [" + std::to_string(lo) + ", " +
                      std::to_string(hi) + "]");
    }
    return v;
  }
  double Real(const std::string& field) {
    if (!bin_) return c_.Real(field);
    last_ = c_.pos();
    return c_.Bin<double>(field);
  }
  double Finite(const std::string& field) {
    const double v = Real(field);
    if (!(v - v == 0.0)) Fail(field, "non-finite coordinate");
    return v;
  }
  /// A count of items needing at least the given bytes each (ASCII / binary).
  std::int64_t Count(const std::string& field, std::size_t ascii_min, std::size_t bin_min) {
    const std::int64_t n = Size(field);
    const std::size_t per = bin_ ? bin_min : ascii_min;
    if (static_cast<std::uint64_t>(n) > c_.remaining() / per + 1) {
      Fail(field, "declared count " + std::to_string(n) + " exceeds what the remaining " +
                      std::to_string(c_.remaining()) + " bytes of the file can hold (truncated?)");
    }
    return n;
  }

 private:
  Cursor& c_;
  bool bin_;
  std::size_t last_ = 0;
};

class MshReader {
 public:
  explicit MshReader(Cursor& c) : c_(c) {}

  MeshData Read() {
    ReadHeader();
    bool have_nodes = false, have_elements = false;
    for (;;) {
      const std::string_view tok = c_.TryToken();
      if (tok.empty()) break;
      if (tok.front() != '$') {
        c_.Fail("section",
                "expected a section header like $Nodes but found '" + Cursor::Shorten(tok) + "'");
      }
      const std::string name(tok.substr(1));
      c_.RestOfLine();  // binary data starts right after the header's newline
      if (name == "PhysicalNames") {
        ReadPhysicalNames();
      } else if (name == "Entities") {
        if (v4_)
          ReadEntities();
        else
          SkipSection(name);
      } else if (name == "PartitionedEntities") {
        c_.Fail("$PartitionedEntities", "partitioned meshes are not supported; save unpartitioned");
      } else if (name == "Nodes") {
        ReadOnce(name, &have_nodes, v4_ ? &MshReader::ReadNodes4 : &MshReader::ReadNodes2);
      } else if (name == "Elements") {
        if (!have_nodes) c_.Fail("$Elements", "$Elements before $Nodes");
        ReadOnce(name, &have_elements, v4_ ? &MshReader::ReadElements4 : &MshReader::ReadElements2);
      } else {
        SkipSection(name);  // $Periodic, $NodeData, comments...: not needed by the simulator
      }
    }
    if (!have_nodes) c_.Fail("$Nodes", "file has no $Nodes section");
    if (!have_elements) c_.Fail("$Elements", "file has no $Elements section");
    for (const auto& [key, name] : names_) {
      if (key.first >= 1 && key.first <= 3) b_.TouchGroup(key.first, key.second);
      b_.SetName(key.first, key.second, name);
    }
    return b_.Finish(v4_ ? (val_.binary() ? "msh4.1-binary" : "msh4.1") : "msh2.2");
  }

 private:
  void ReadHeader() {
    const std::string_view first = c_.Token("$MeshFormat");
    if (first != "$MeshFormat") {
      c_.Fail("$MeshFormat", "expected '$MeshFormat' at the start of a Gmsh file but found '" +
                                 Cursor::Shorten(first) + "'");
    }
    const std::string_view version = c_.Token("version");
    if (version == "4.1") {
      v4_ = true;
    } else if (version == "2.2" || version == "2.1" || version == "2" || version == "2.0") {
      v4_ = false;
    } else {
      c_.Fail("version", "unsupported MSH version '" + Cursor::Shorten(version) +
                             "' (supported: 2.2 ASCII, 4.1 ASCII, 4.1 binary)");
    }
    const std::int64_t file_type = c_.IntIn("file-type", 0, 1);
    const std::int64_t data_size = c_.Int("data-size");
    const bool binary = file_type == 1;
    if (binary && !v4_) c_.Fail("file-type", "binary MSH 2.2 is not supported (use 4.1 binary)");
    if (binary && data_size != 8) {
      c_.Fail("data-size",
              "expected data-size 8 for binary MSH, found " + std::to_string(data_size));
    }
    c_.RestOfLine();
    if (binary) {
      const std::size_t at = c_.pos();
      const std::int32_t one = c_.Bin<std::int32_t>("endianness marker");
      if (one != 1) {
        c_.FailAt(
            at, "endianness marker",
            "expected the integer 1 (little-endian binary); big-endian files are not supported");
      }
    }
    val_.set_binary(binary);
    c_.Expect("$EndMeshFormat", "$EndMeshFormat");
  }

  void SkipSection(const std::string& name) {
    const std::string end = "$End" + name;
    const std::size_t at = c_.bytes().find(end, c_.pos());
    if (at == std::string_view::npos) c_.Fail("$" + name, "missing '" + end + "' (truncated?)");
    c_.AdvanceTo(at + end.size());
  }

  void ExpectEnd(const std::string& name) { c_.Expect("$End" + name, "$End" + name); }

  void ReadPhysicalNames() {
    const std::int64_t n = c_.Count("number of physical names", 6);
    for (std::int64_t i = 0; i < n; ++i) {
      const int dim = static_cast<int>(c_.IntIn("physical dimension", 0, 3));
      const int tag = static_cast<int>(c_.IntIn("physical tag", -kMaxInt32, kMaxInt32));
      std::string_view rest = c_.RestOfLine();
      while (!rest.empty() && (rest.front() == ' ' || rest.front() == '\t')) rest.remove_prefix(1);
      while (!rest.empty() && (rest.back() == ' ' || rest.back() == '\t')) rest.remove_suffix(1);
      if (rest.size() < 2 || rest.front() != '"' || rest.back() != '"') {
        c_.Fail("physical name",
                "expected a double-quoted name but found '" + Cursor::Shorten(rest) + "'");
      }
      names_[{dim, tag}] = std::string(rest.substr(1, rest.size() - 2));
    }
    ExpectEnd("PhysicalNames");
  }

  // ---- MSH 2.2 -------------------------------------------------------------------------------

  void ReadNodes2() {
    const std::int64_t n = c_.Count("number of nodes", 8);
    for (std::int64_t i = 0; i < n; ++i) {
      const std::int64_t tag = c_.Int("node tag");
      const double x = c_.Finite("node x");
      const double y = c_.Finite("node y");
      const double z = c_.Finite("node z");
      b_.AddNode(tag, x, y, z);
    }
    index_.Build(b_.node_tags(), c_, "node tag");
    ExpectEnd("Nodes");
  }

  void ReadElements2() {
    const std::int64_t n = c_.Count("number of elements", 8);
    std::vector<int> phys;
    std::int32_t nodes[4];
    for (std::int64_t i = 0; i < n; ++i) {
      c_.Int("element tag");
      const std::int64_t type = c_.Int("element type");
      const ElementKind kind = KindOf(type);
      if (kind.dim < 0) c_.Fail("element type", UnsupportedType(type));
      const std::int64_t ntags = c_.IntIn("number of element tags", 0, 64);
      std::int64_t physical = 0, elementary = 0;
      for (std::int64_t k = 0; k < ntags; ++k) {
        const std::int64_t t = c_.IntIn("element tag value", -kMaxInt32, kMaxInt32);
        if (k == 0) physical = t;
        if (k == 1) elementary = t;
      }
      for (int k = 0; k < kind.nodes; ++k) nodes[k] = Node(c_.Int("element node"));
      if (kind.dim == 0) continue;
      phys.clear();
      if (physical != 0) phys.push_back(static_cast<int>(physical));
      b_.AddElement(kind.dim, nodes, phys, elementary >= 0 ? elementary : 0);
    }
    ExpectEnd("Elements");
  }

  std::int32_t Node(std::int64_t tag) {
    const std::int32_t i = index_.Find(tag);
    if (i < 0) val_.Fail("element node", "node tag " + std::to_string(tag) + " is not in $Nodes");
    return i;
  }

  // ---- MSH 4.1 -------------------------------------------------------------------------------

  void ReadEntities() {
    std::int64_t counts[4];
    for (int d = 0; d < 4; ++d) counts[d] = val_.Count("number of entities", 10, 36);
    for (int d = 0; d < 4; ++d) {
      for (std::int64_t e = 0; e < counts[d]; ++e) {
        const int tag = val_.Int("entity tag");
        const int ncoord = d == 0 ? 3 : 6;
        for (int k = 0; k < ncoord; ++k) val_.Real("entity bounding box");
        const std::int64_t np = val_.Count("number of physical tags", 2, 4);
        std::vector<int>& phys = entity_phys_[{d, tag}];
        phys.clear();
        for (std::int64_t k = 0; k < np; ++k) phys.push_back(val_.Int("physical tag"));
        if (d > 0) {
          const std::int64_t nb = val_.Count("number of bounding entities", 2, 4);
          for (std::int64_t k = 0; k < nb; ++k) val_.Int("bounding entity tag");
        }
      }
    }
    ExpectEnd("Entities");
  }

  // Reads section `name` with `read`; *seen records it, and a second one is an error.
  void ReadOnce(const std::string& name, bool* seen, void (MshReader::*read)()) {
    if (*seen) c_.Fail("$" + name, "a second $" + name + " section is not supported");
    (this->*read)();
    *seen = true;
  }

  // The head of an MSH 4 $Nodes or $Elements section (`item` "node" or "element"): the block
  // count, the total count (each item at least total_ascii_min / total_bin_min bytes), and the
  // smallest and largest tag (not needed). Returns {block count, total count}.
  std::pair<std::int64_t, std::int64_t> ReadSectionHead4(const std::string& item,
                                                         std::size_t total_ascii_min,
                                                         std::size_t total_bin_min) {
    const std::int64_t nblocks = val_.Count("number of " + item + " blocks", 8, 20);
    const std::int64_t total =
        val_.Count("number of " + item + "s", total_ascii_min, total_bin_min);
    val_.Size("min " + item + " tag");
    val_.Size("max " + item + " tag");
    return {nblocks, total};
  }

  void ReadNodes4() {
    const auto [nblocks, total] = ReadSectionHead4("node", 8, 32);
    std::vector<std::int64_t> tags;
    for (std::int64_t b = 0; b < nblocks; ++b) {
      const int dim = val_.IntIn("node block entity dimension", 0, 3);
      val_.Int("node block entity tag");
      const int parametric = val_.IntIn("node block parametric flag", 0, 1);
      const std::int64_t n = val_.Count("number of nodes in block", 8, 32);
      if (b_.num_nodes() + n > total) {
        val_.Fail("number of nodes in block",
                  "node blocks hold more nodes than the declared " + std::to_string(total));
      }
      tags.resize(static_cast<std::size_t>(n));
      for (std::int64_t i = 0; i < n; ++i)
        tags[static_cast<std::size_t>(i)] = val_.Size("node tag");
      const int extra = parametric ? dim : 0;
      for (std::int64_t i = 0; i < n; ++i) {
        const double x = val_.Finite("node x");
        const double y = val_.Finite("node y");
        const double z = val_.Finite("node z");
        for (int k = 0; k < extra; ++k) val_.Real("node parametric coordinate");
        b_.AddNode(tags[static_cast<std::size_t>(i)], x, y, z);
      }
    }
    if (b_.num_nodes() != total) {
      val_.Fail("number of nodes", "declared " + std::to_string(total) + " nodes but blocks hold " +
                                       std::to_string(b_.num_nodes()));
    }
    index_.Build(b_.node_tags(), c_, "node tag");
    ExpectEnd("Nodes");
  }

  void ReadElements4() {
    const auto [nblocks, total] = ReadSectionHead4("element", 4, 16);
    std::int64_t seen = 0;
    const std::vector<int> none;
    std::int32_t nodes[4];
    for (std::int64_t b = 0; b < nblocks; ++b) {
      const int dim = val_.IntIn("element block entity dimension", 0, 3);
      const int entity = val_.Int("element block entity tag");
      const int type = val_.Int("element type");
      const ElementKind kind = KindOf(type);
      if (kind.dim < 0) val_.Fail("element type", UnsupportedType(type));
      const std::int64_t n =
          val_.Count("number of elements in block", 2 * static_cast<std::size_t>(kind.nodes + 1),
                     8 * static_cast<std::size_t>(kind.nodes + 1));
      seen += n;
      if (seen > total) {
        val_.Fail("number of elements in block",
                  "element blocks hold more elements than the "
                  "declared " +
                      std::to_string(total));
      }
      const auto it = entity_phys_.find({dim, entity});
      const std::vector<int>& phys = it == entity_phys_.end() ? none : it->second;
      for (std::int64_t i = 0; i < n; ++i) {
        val_.Size("element tag");
        for (int k = 0; k < kind.nodes; ++k) nodes[k] = Node(val_.Size("element node"));
        if (kind.dim > 0) b_.AddElement(kind.dim, nodes, phys);
      }
    }
    if (seen != total) {
      val_.Fail("number of elements", "declared " + std::to_string(total) +
                                          " elements but blocks hold " + std::to_string(seen));
    }
    ExpectEnd("Elements");
  }

  Cursor& c_;
  Values val_{c_, false};
  bool v4_ = false;
  MeshBuilder b_;
  NodeIndex index_;
  std::map<std::pair<int, int>, std::string> names_;
  std::map<std::pair<int, int>, std::vector<int>> entity_phys_;
};

}  // namespace

MeshData ReadMsh(Cursor& cur) { return MshReader(cur).Read(); }

}  // namespace arthrosim::mesh::detail
