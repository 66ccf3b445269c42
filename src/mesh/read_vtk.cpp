// Legacy VTK reader: DATASET UNSTRUCTURED_GRID, ASCII, file versions 2.0 to 5.1 (5.1 uses the
// OFFSETS/CONNECTIVITY layout). Cell types: 1 vertex (skipped), 3 line, 5 triangle, 10 tetra.
// A cell scalar named "physical" or "gmsh:physical" becomes the per-element physical tag.
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "mesh_builder.h"

namespace arthrosim::mesh::detail {
namespace {

constexpr std::int64_t kMaxInt32 = std::numeric_limits<std::int32_t>::max();

struct Cell {
  int dim = 0;
  std::int32_t nodes[4] = {0, 0, 0, 0};
};

bool IsDataType(std::string_view t) {
  static const char* kTypes[] = {"bit",          "unsigned_char", "char",   "unsigned_short",
                                 "short",        "unsigned_int",  "int",    "unsigned_long",
                                 "long",         "float",         "double", "vtktypeint64",
                                 "vtktypeint32", "vtkIdType"};
  for (const char* k : kTypes) {
    if (t == k) return true;
  }
  return false;
}

class VtkReader {
 public:
  explicit VtkReader(Cursor& c) : c_(c) {}

  MeshData Read() {
    const std::string_view head = c_.RestOfLine();
    if (head.rfind("# vtk DataFile Version", 0) != 0) {
      c_.Fail("header", "expected '# vtk DataFile Version x.y' on line 1 but found '" +
                            Cursor::Shorten(head) + "'");
    }
    c_.RestOfLine();  // title
    const std::string_view enc = c_.Token("encoding");
    if (enc == "BINARY") c_.Fail("encoding", "binary legacy VTK is not supported; write ASCII");
    if (enc != "ASCII")
      c_.Fail("encoding", "expected ASCII but found '" + Cursor::Shorten(enc) + "'");
    c_.Expect("DATASET", "DATASET");
    const std::string_view ds = c_.Token("DATASET");
    if (ds != "UNSTRUCTURED_GRID") {
      c_.Fail("DATASET",
              "unsupported dataset '" + Cursor::Shorten(ds) + "' (only UNSTRUCTURED_GRID)");
    }
    bool have_points = false;
    for (;;) {
      const std::string_view kw = c_.TryToken();
      if (kw.empty()) break;
      if (kw == "POINTS") {
        ReadPoints();
        have_points = true;
      } else if (kw == "CELLS") {
        if (!have_points) c_.Fail("CELLS", "CELLS before POINTS");
        ReadCells();
      } else if (kw == "CELL_TYPES") {
        ReadCellTypes();
      } else if (kw == "CELL_DATA") {
        if (!ReadCellData()) break;
      } else if (kw == "POINT_DATA" || kw == "METADATA" || kw == "FIELD") {
        break;  // attributes we do not use: the geometry is complete
      } else {
        c_.Fail("keyword", "unexpected keyword '" + Cursor::Shorten(kw) + "'");
      }
    }
    if (!have_points) c_.Fail("POINTS", "file has no POINTS section");
    if (cells_read_ && !types_read_) c_.Fail("CELL_TYPES", "file has CELLS but no CELL_TYPES");
    for (std::size_t i = 0; i < cells_.size(); ++i) {
      const Cell& cell = cells_[i];
      if (cell.dim == 0) continue;
      std::vector<int> phys;
      if (!physical_.empty() && physical_[i] != 0) phys.push_back(physical_[i]);
      b_.AddElement(cell.dim, cell.nodes, phys);
    }
    return b_.Finish("vtk");
  }

 private:
  void ReadPoints() {
    const std::int64_t n = c_.Count("POINTS count", 6);
    const std::string_view type = c_.Token("POINTS data type");
    if (!IsDataType(type)) {
      c_.Fail("POINTS data type", "expected a VTK data type like float or double but found '" +
                                      Cursor::Shorten(type) + "'");
    }
    for (std::int64_t i = 0; i < n; ++i) {
      const double x = c_.Finite("point x");
      const double y = c_.Finite("point y");
      const double z = c_.Finite("point z");
      b_.AddNode(i, x, y, z);
    }
  }

  std::int32_t Index(const std::string& field) {
    const std::int64_t v = c_.Int(field);
    if (v < 0 || v >= b_.num_nodes()) {
      c_.Fail(field, "point index " + std::to_string(v) + " out of range [0, " +
                         std::to_string(b_.num_nodes()) + ")");
    }
    return static_cast<std::int32_t>(v);
  }

  void ReadCells() {
    const std::int64_t a = c_.Count("CELLS count", 2);
    const std::int64_t size = c_.Count("CELLS size", 2);
    const Cursor::Mark save_pos = c_.Save();
    const std::string_view next = c_.TryToken();
    if (next == "OFFSETS") {
      // VTK 5.1: a = offsets (cells + 1), size = connectivity length.
      c_.Token("OFFSETS data type");
      if (a < 1) c_.Fail("CELLS count", "expected at least 1 offset");
      std::vector<std::int64_t> off(static_cast<std::size_t>(a));
      for (std::int64_t i = 0; i < a; ++i) {
        off[static_cast<std::size_t>(i)] = c_.IntIn("offset", 0, size);
        if (i > 0 && off[static_cast<std::size_t>(i)] < off[static_cast<std::size_t>(i - 1)]) {
          c_.Fail("offset", "offsets must not decrease");
        }
      }
      if (off.front() != 0 || off.back() != size) {
        c_.Fail("offset",
                "offsets must start at 0 and end at the connectivity size " + std::to_string(size));
      }
      c_.Expect("CONNECTIVITY", "CONNECTIVITY");
      c_.Token("CONNECTIVITY data type");
      cells_.resize(static_cast<std::size_t>(a - 1));
      counts_.resize(cells_.size());
      for (std::size_t i = 0; i + 1 < off.size(); ++i) {
        const std::int64_t k = off[i + 1] - off[i];
        counts_[i] = static_cast<int>(std::min<std::int64_t>(k, 64));
        for (std::int64_t j = 0; j < k; ++j) {
          const std::int32_t v = Index("cell point index");
          if (j < 4) cells_[i].nodes[j] = v;
        }
      }
    } else {
      c_.Restore(save_pos);
      if (a > size) c_.Fail("CELLS size", "CELLS size smaller than the number of cells");
      cells_.resize(static_cast<std::size_t>(a));
      counts_.resize(cells_.size());
      std::int64_t used = 0;
      for (std::int64_t i = 0; i < a; ++i) {
        const std::int64_t k = c_.IntIn("cell point count", 0, size);
        used += k + 1;
        if (used > size)
          c_.Fail("cell point count",
                  "cells use more values than CELLS size " + std::to_string(size));
        counts_[static_cast<std::size_t>(i)] = static_cast<int>(std::min<std::int64_t>(k, 64));
        for (std::int64_t j = 0; j < k; ++j) {
          const std::int32_t v = Index("cell point index");
          if (j < 4) cells_[static_cast<std::size_t>(i)].nodes[j] = v;
        }
      }
      if (used != size) {
        c_.Fail("CELLS size", "CELLS size " + std::to_string(size) + " but cells use " +
                                  std::to_string(used) + " values");
      }
    }
    cells_read_ = true;
  }

  void ReadCellTypes() {
    if (!cells_read_) c_.Fail("CELL_TYPES", "CELL_TYPES before CELLS");
    const std::int64_t n = c_.Count("CELL_TYPES count", 2);
    if (n != static_cast<std::int64_t>(cells_.size())) {
      c_.Fail("CELL_TYPES count", "expected " + std::to_string(cells_.size()) +
                                      " cell types (one per cell) but found " + std::to_string(n));
    }
    for (std::size_t i = 0; i < cells_.size(); ++i) {
      const std::int64_t type = c_.Int("cell type");
      int dim = -1, need = 0;
      switch (type) {
        case 1:
          dim = 0;
          need = 1;
          break;
        case 3:
          dim = 1;
          need = 2;
          break;
        case 5:
          dim = 2;
          need = 3;
          break;
        case 10:
          dim = 3;
          need = 4;
          break;
        default:
          c_.Fail("cell type", "unsupported VTK cell type " + std::to_string(type) +
                                   " (supported: 1 vertex, 3 line, 5 triangle, 10 tetra)");
      }
      if (counts_[i] != need) {
        c_.Fail("cell type", "cell " + std::to_string(i) + " of type " + std::to_string(type) +
                                 " needs " + std::to_string(need) + " points but has " +
                                 std::to_string(counts_[i]));
      }
      cells_[i].dim = dim;
    }
    types_read_ = true;
  }

  /// Returns false when it meets attributes it does not parse (the rest is ignored).
  bool ReadCellData() {
    const std::int64_t n = c_.Count("CELL_DATA count", 2);
    if (n != static_cast<std::int64_t>(cells_.size())) {
      c_.Fail("CELL_DATA count", "expected " + std::to_string(cells_.size()) +
                                     " (one per cell) but found " + std::to_string(n));
    }
    for (;;) {
      const Cursor::Mark save = c_.Save();
      const std::string_view kw = c_.TryToken();
      if (kw != "SCALARS") {
        c_.Restore(save);
        return kw == "POINT_DATA" || kw == "CELL_DATA" ? true : kw.empty();
      }
      const std::string name(c_.Token("SCALARS name"));
      c_.Token("SCALARS data type");
      // Optional component count, then LOOKUP_TABLE name.
      std::string_view t = c_.Token("LOOKUP_TABLE");
      std::int64_t comps = 1;
      if (t != "LOOKUP_TABLE") {
        if (!Cursor::ParseInt(t, &comps) || comps < 1 || comps > 4) {
          c_.Fail("SCALARS components", "expected 1..4 components or LOOKUP_TABLE");
        }
        c_.Expect("LOOKUP_TABLE", "LOOKUP_TABLE");
      }
      c_.Token("LOOKUP_TABLE name");
      const bool phys = (name == "physical" || name == "gmsh:physical") && comps == 1;
      if (phys) physical_.assign(static_cast<std::size_t>(n), 0);
      for (std::int64_t i = 0; i < n * comps; ++i) {
        if (phys) {
          physical_[static_cast<std::size_t>(i)] =
              static_cast<int>(c_.IntIn("physical tag", -kMaxInt32, kMaxInt32));
        } else {
          c_.Real("cell scalar");
        }
      }
    }
  }

  Cursor& c_;
  MeshBuilder b_;
  std::vector<Cell> cells_;
  std::vector<int> counts_;
  std::vector<int> physical_;
  bool cells_read_ = false, types_read_ = false;
};

}  // namespace

MeshData ReadVtk(Cursor& cur) { return VtkReader(cur).Read(); }

}  // namespace arthrosim::mesh::detail
