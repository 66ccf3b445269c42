// Series-by-series comparison of two digests with absolute + relative tolerances.
#include "arthrosim/scoring/compare.h"

#include <fmt/core.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstring>

#include "arthrosim/core/enum_names.h"
#include "arthrosim/core/error.h"

namespace arthrosim::scoring {
namespace {

constexpr EnumName<SeriesClass> kClassNames[] = {
    {SeriesClass::kExact, "exact"}, {SeriesClass::kHash, "hash"},
    {SeriesClass::kText, "text"},   {SeriesClass::kPosition, "position"},
    {SeriesClass::kForce, "force"}, {SeriesClass::kMetric, "metric"}};

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

bool ValuesMatch(double run, double golden, const Tolerance& t, NanPolicy nan, bool exact) {
  if (exact) return SameBits(run, golden);
  const bool rn = std::isnan(run), gn = std::isnan(golden);
  if (rn || gn) return nan == NanPolicy::kSamePlace && rn && gn;
  if (run == golden) return true;  // equal infinities too
  return std::abs(run - golden) <= t.atol + t.rtol * std::abs(golden);
}

std::string Show(double v) { return fmt::format("{}", v); }

Tolerance ToleranceOf(const DigestSeries& s, const CompareOptions& o) {
  const auto it = o.by_series.find(s.name);
  if (it != o.by_series.end()) return it->second;
  const auto c = o.by_class.find(s.cls);
  return c != o.by_class.end() ? c->second : Tolerance{};
}

// First difference of a series pair, or nullopt.
std::optional<Divergence> CompareSeries(const DigestSeries& run, const DigestSeries& golden,
                                        const CompareOptions& o, std::int64_t* values) {
  const Tolerance tol = ToleranceOf(golden, o);
  const bool exact_class = golden.cls == SeriesClass::kExact;
  const std::int64_t rows = std::min(run.rows(), golden.rows());
  for (std::int64_t r = 0; r < rows; ++r) {
    Divergence d;
    d.series = golden.name;
    d.row = r;
    d.step = golden.steps[r];
    if (run.steps[r] != golden.steps[r]) {
      d.column = -1;
      d.run_value = fmt::format("step {}", run.steps[r]);
      d.golden_value = fmt::format("step {}", golden.steps[r]);
      d.step = std::min(run.steps[r], golden.steps[r]);
      return d;
    }
    if (golden.cls == SeriesClass::kHash) {
      ++*values;
      if (run.hashes[r] == golden.hashes[r]) continue;
      d.run_value = fmt::format("{:016x}", run.hashes[r]);
      d.golden_value = fmt::format("{:016x}", golden.hashes[r]);
      return d;
    }
    if (golden.cls == SeriesClass::kText) {
      ++*values;
      if (run.text[r] == golden.text[r]) continue;
      d.run_value = run.text[r];
      d.golden_value = golden.text[r];
      return d;
    }
    if (run.width != golden.width) {
      d.run_value = fmt::format("{} values per row", run.width);
      d.golden_value = fmt::format("{} values per row", golden.width);
      return d;
    }
    for (int c = 0; c < golden.width; ++c) {
      ++*values;
      const double a = run.values[r * run.width + c], b = golden.values[r * golden.width + c];
      if (ValuesMatch(a, b, tol, o.nan, o.exact || exact_class)) continue;
      d.column = c;
      d.run_value = Show(a);
      d.golden_value = Show(b);
      return d;
    }
  }
  if (run.rows() == golden.rows()) return std::nullopt;
  Divergence d;
  d.series = golden.name;
  d.row = rows;
  const bool run_longer = run.rows() > golden.rows();
  d.step = run_longer ? run.steps[rows] : golden.steps[rows];
  d.run_value = run_longer ? fmt::format("{} rows", run.rows()) : "missing";
  d.golden_value = run_longer ? "missing" : fmt::format("{} rows", golden.rows());
  return d;
}

const DigestSeries* Find(const Digest& d, const std::string& name) {
  for (const DigestSeries& s : d.series)
    if (s.name == name) return &s;
  return nullptr;
}

Tolerance ReadTolerance(const std::string& path, const YAML::Node& n, const std::string& field) {
  if (!n.IsMap()) throw InputError(path, n.Mark().line + 1, field, "expected {atol: A, rtol: R}");
  Tolerance t;
  for (auto it = n.begin(); it != n.end(); ++it) {
    const std::string key = it->first.as<std::string>();
    double v = 0;
    try {
      v = it->second.as<double>();
    } catch (const YAML::Exception&) {
      throw InputError(path, it->second.Mark().line + 1, field + "." + key, "expected a number");
    }
    if (!(v >= 0) || !std::isfinite(v))
      throw InputError(path, it->second.Mark().line + 1, field + "." + key,
                       "expected a finite number >= 0");
    if (key == "atol")
      t.atol = v;
    else if (key == "rtol")
      t.rtol = v;
    else
      throw InputError(path, it->first.Mark().line + 1, field + "." + key,
                       "unknown key (expected one of: atol, rtol)");
  }
  return t;
}

}  // namespace

const char* SeriesClassName(SeriesClass c) { return NameIn(kClassNames, c, "?"); }

std::optional<SeriesClass> ParseSeriesClass(std::string_view name) {
  return ValueIn(kClassNames, name);
}

CompareOptions CompareOptions::Defaults() {
  CompareOptions o;
  o.by_class[SeriesClass::kPosition] = {1e-6, 1e-9};
  o.by_class[SeriesClass::kForce] = {1e-6, 1e-6};
  o.by_class[SeriesClass::kMetric] = {1e-9, 1e-6};
  return o;
}

CompareOptions LoadTolerances(const std::string& path) {
  CompareOptions o = CompareOptions::Defaults();
  YAML::Node doc;
  try {
    doc = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw InputError(path, 0, "", "cannot open the tolerances file");
  } catch (const YAML::Exception& e) {
    throw InputError(path, e.mark.line + 1, "", "invalid YAML: " + e.msg);
  }
  if (!doc.IsMap()) throw InputError(path, 1, "", "expected a mapping");
  for (auto it = doc.begin(); it != doc.end(); ++it) {
    const std::string key = it->first.as<std::string>();
    const int line = it->first.Mark().line + 1;
    if (const std::optional<SeriesClass> c = ParseSeriesClass(key)) {
      if (c == SeriesClass::kExact || c == SeriesClass::kHash || c == SeriesClass::kText)
        throw InputError(path, line, key, "exact classes take no tolerance");
      o.by_class[*c] = ReadTolerance(path, it->second, key);
      continue;
    }
    if (key == "nan") {
      const std::string v = it->second.IsScalar() ? it->second.Scalar() : "";
      if (v == "same_place")
        o.nan = NanPolicy::kSamePlace;
      else if (v == "differ")
        o.nan = NanPolicy::kDiffer;
      else
        throw InputError(path, line, "nan", "expected same_place or differ");
    } else if (key == "series") {
      if (!it->second.IsMap()) throw InputError(path, line, "series", "expected a mapping");
      for (auto s = it->second.begin(); s != it->second.end(); ++s) {
        const std::string name = s->first.as<std::string>();
        o.by_series[name] = ReadTolerance(path, s->second, "series." + name);
      }
    } else {
      throw InputError(path, line, key,
                       "unknown key (expected one of: position, force, metric, nan, series)");
    }
  }
  return o;
}

std::string Divergence::text() const {
  std::string where = column >= 0 ? fmt::format("[{}, {}]", row, column) : fmt::format("[{}]", row);
  return fmt::format("step {}: {}{}: run {} vs golden {}", step, series, where, run_value,
                     golden_value);
}

CompareResult CompareDigests(const Digest& run, const Digest& golden,
                             const CompareOptions& options) {
  CompareResult r;
  for (const DigestSeries& g : golden.series) {
    ++r.series_compared;
    const DigestSeries* s = Find(run, g.name);
    std::optional<Divergence> d;
    if (!s) {
      d = Divergence{g.name, g.rows() ? g.steps[0] : 0, 0, -1, "missing", "present"};
    } else {
      d = CompareSeries(*s, g, options, &r.values_compared);
    }
    if (d) r.per_series.push_back(*d);
  }
  for (const DigestSeries& s : run.series)
    if (!Find(golden, s.name))
      r.per_series.push_back({s.name, s.rows() ? s.steps[0] : 0, 0, -1, "present", "missing"});
  // Hashes decide only in exact mode; otherwise tolerances do and hashes are informative.
  std::vector<Divergence> deciding;
  for (const Divergence& d : r.per_series) {
    const DigestSeries* g = Find(golden, d.series);
    if (options.exact || !g || g->cls != SeriesClass::kHash) deciding.push_back(d);
  }
  r.equal = deciding.empty();
  for (const Divergence& d : deciding)
    if (!r.first || d.step < r.first->step) r.first = d;
  return r;
}

std::string CompareResult::Report() const {
  if (equal)
    return fmt::format("equal: {} series, {} values compared\n", series_compared, values_compared);
  std::string out = fmt::format("REGRESSION: first divergence at {}\n", first->text());
  for (const Divergence& d : per_series) out += "  " + d.text() + "\n";
  return out;
}

}  // namespace arthrosim::scoring
