// Wavefront OBJ reader: v, f (v, v/vt, v/vt/vn, v//vn; negative = relative), l polylines,
// g/o names as groups. Polygons are fan-triangulated (0, i, i+1). Other geometry statements
// (curves, surfaces) are rejected; material and smoothing statements are ignored.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mesh_builder.h"

namespace arthrosim::mesh::detail {
namespace {

std::vector<std::string_view> Split(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && Cursor::IsSpace(line[i])) ++i;
    const std::size_t s = i;
    while (i < line.size() && !Cursor::IsSpace(line[i])) ++i;
    if (i > s) out.push_back(line.substr(s, i - s));
  }
  return out;
}

bool Ignored(std::string_view k) {
  static const char* kIgnored[] = {
      "vt", "vn",         "vp",        "s",     "usemtl",   "mtllib",   "usemap", "maplib", "lod",
      "mg", "shadow_obj", "trace_obj", "bevel", "c_interp", "d_interp", "ctech",  "stech",  "p"};
  for (const char* i : kIgnored) {
    if (k == i) return true;
  }
  return false;
}

class ObjReader {
 public:
  explicit ObjReader(Cursor& c) : c_(c) {}

  MeshData Read() {
    while (!c_.AtEnd()) {
      std::string_view line = c_.RestOfLine();
      line_ = c_.line();
      const std::size_t hash = line.find('#');
      if (hash != std::string_view::npos) line = line.substr(0, hash);
      const std::vector<std::string_view> tok = Split(line);
      if (tok.empty()) continue;
      const std::string_view k = tok[0];
      if (k == "v") {
        if (tok.size() < 4 || tok.size() > 7) Fail("v", "expected 'v x y z' (optionally w or rgb)");
        double xyz[3];
        for (int i = 0; i < 3; ++i) {
          const std::string field = std::string("v ") + "xyz"[i];
          if (!Cursor::ParseReal(tok[static_cast<std::size_t>(i + 1)], &xyz[i])) {
            Fail(field, "expected a number but found '" +
                            Cursor::Shorten(tok[static_cast<std::size_t>(i + 1)]) + "'");
          }
          if (!(xyz[i] - xyz[i] == 0.0)) Fail(field, "non-finite coordinate");
        }
        b_.AddNode(b_.num_nodes() + 1, xyz[0], xyz[1], xyz[2]);
      } else if (k == "vt") {
        ++num_vt_;
      } else if (k == "vn") {
        ++num_vn_;
      } else if (k == "f") {
        if (tok.size() < 4) Fail("f", "a face needs at least 3 vertices");
        idx_.clear();
        for (std::size_t i = 1; i < tok.size(); ++i) idx_.push_back(Vertex(tok[i], "f"));
        for (std::size_t i = 1; i + 1 < idx_.size(); ++i) {
          const std::int32_t tri[3] = {idx_[0], idx_[i], idx_[i + 1]};
          b_.AddElement(2, tri, Group(2));
        }
      } else if (k == "l") {
        if (tok.size() < 3) Fail("l", "a line needs at least 2 vertices");
        idx_.clear();
        for (std::size_t i = 1; i < tok.size(); ++i) idx_.push_back(Vertex(tok[i], "l"));
        for (std::size_t i = 0; i + 1 < idx_.size(); ++i) {
          const std::int32_t seg[2] = {idx_[i], idx_[i + 1]};
          b_.AddElement(1, seg, Group(1));
        }
      } else if (k == "g" || k == "o") {
        std::string name;
        for (std::size_t i = 1; i < tok.size(); ++i) {
          if (i > 1) name += ' ';
          name += std::string(tok[i]);
        }
        if (name.empty()) {
          group_.reset();  // a bare g/o returns to the default (no) group
        } else {
          group_ = name;
        }
      } else if (!Ignored(k)) {
        Fail("statement", "unsupported OBJ statement '" + Cursor::Shorten(k) +
                              "' (expected v, vt, vn, f, l, g, o, s, usemtl, mtllib)");
      }
    }
    for (const auto& [key, name] : names_) b_.SetName(key.first, key.second, name);
    return b_.Finish("obj");
  }

 private:
  [[noreturn]] void Fail(const std::string& field, const std::string& msg) const {
    throw InputError(c_.file(), line_, field, msg);
  }

  /// Resolves one OBJ index (1-based, or negative = relative to the count so far).
  std::int64_t Resolve(std::string_view t, std::int64_t count, const std::string& field) {
    std::int64_t v = 0;
    if (!Cursor::ParseInt(t, &v)) {
      Fail(field, "expected an integer index but found '" + Cursor::Shorten(t) + "'");
    }
    const std::int64_t r = v < 0 ? count + v + 1 : v;
    if (v == 0 || r < 1 || r > count) {
      Fail(field, "index " + std::to_string(v) + " out of range (" + std::to_string(count) +
                      " defined so far; 1-based, negative = relative)");
    }
    return r;
  }

  std::int32_t Vertex(std::string_view t, const std::string& stmt) {
    const std::size_t s1 = t.find('/');
    const std::int64_t v = Resolve(t.substr(0, s1), b_.num_nodes(), stmt + " vertex index");
    if (s1 != std::string_view::npos) {
      const std::string_view rest = t.substr(s1 + 1);
      const std::size_t s2 = rest.find('/');
      const std::string_view vt = rest.substr(0, s2);
      if (!vt.empty()) Resolve(vt, num_vt_, stmt + " texture index");
      if (s2 != std::string_view::npos) {
        const std::string_view vn = rest.substr(s2 + 1);
        if (!vn.empty()) Resolve(vn, num_vn_, stmt + " normal index");
      }
    }
    return static_cast<std::int32_t>(v - 1);
  }

  /// The physical-tag list for the current g/o name (tags 1, 2, ... by first use per dim).
  const std::vector<int>& Group(int dim) {
    static const std::vector<int> kNone;
    if (!group_) return kNone;
    const auto key = std::make_pair(dim, *group_);
    auto it = tags_.find(key);
    if (it == tags_.end()) {
      const int tag = ++next_tag_[dim];
      it = tags_.emplace(key, std::vector<int>{tag}).first;
      names_[{dim, tag}] = *group_;
    }
    return it->second;
  }

  Cursor& c_;
  MeshBuilder b_;
  int line_ = 0;
  std::int64_t num_vt_ = 0, num_vn_ = 0;
  std::vector<std::int32_t> idx_;
  std::optional<std::string> group_;
  std::map<std::pair<int, std::string>, std::vector<int>> tags_;
  std::map<std::pair<int, int>, std::string> names_;
  std::map<int, int> next_tag_;
};

}  // namespace

MeshData ReadObj(Cursor& cur) { return ObjReader(cur).Read(); }

}  // namespace arthrosim::mesh::detail
