#pragma once
// Golden regression (docs/golden.md in golden/README.md): a run is reduced to a digest — per
// frame state hashes, tool and camera poses, forces, bone removed volumes, topology counts,
// constraint and contact fingerprints, every event, and body/thread positions at sparse frames —
// and two digests are compared series by series with per-series absolute AND relative
// tolerances and an explicit NaN policy. A golden file is a digest saved as HDF5 (format
// `arthrosim-golden`), small enough for the repository.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace arthrosim::scoring {

/// How a series is compared.
enum class SeriesClass : std::uint8_t {
  kExact,     ///< integers, counts, topology: equal values
  kHash,      ///< 64-bit fingerprints: equal
  kText,      ///< event rows: equal strings
  kPosition,  ///< mm and quaternions
  kForce,     ///< N
  kMetric,    ///< derived quantities (removed volume, times): relative
};
/// "exact", "hash", "text", "position", "force", "metric" ("?" for no class).
const char* SeriesClassName(SeriesClass c);
/// The class SeriesClassName names `name`; nullopt for no class.
std::optional<SeriesClass> ParseSeriesClass(std::string_view name);

struct DigestSeries {
  std::string name;  ///< e.g. "tools/burr/pose"
  SeriesClass cls = SeriesClass::kExact;
  int width = 1;                      ///< values per row
  std::vector<std::int64_t> steps;    ///< simulation step of each row
  std::vector<double> values;         ///< rows x width (numeric classes)
  std::vector<std::uint64_t> hashes;  ///< kHash rows
  std::vector<std::string> text;      ///< kText rows
  std::int64_t rows() const { return static_cast<std::int64_t>(steps.size()); }
};

struct Digest {
  std::int64_t sparse_every = 0;  ///< positions every K frames (and the last); 0 = every frame
  std::string scenario;
  std::vector<DigestSeries> series;  ///< fixed order
};

/// The digest of a run file. `sparse_every` = K > 0 keeps body and thread positions of every
/// K-th frame and the last only; 0 keeps them for every frame.
/// @throws InputError if the file is not a readable run.
Digest DigestOfRun(const std::string& run_path, std::int64_t sparse_every);
/// Writes / reads a golden file. @throws InputError naming the file on failure.
void WriteGolden(const std::string& path, const Digest& digest);
Digest ReadGolden(const std::string& path);
/// A golden file or, for a run file, its digest with positions every `sparse_every` frames.
Digest LoadDigest(const std::string& path, std::int64_t sparse_every);
/// Whether `path` is an arthrosim golden file (else a run file is assumed).
bool IsGoldenFile(const std::string& path);

/// Tolerance of one series: |run - golden| <= atol + rtol * |golden|.
struct Tolerance {
  double atol = 0;
  double rtol = 0;
};
enum class NanPolicy : std::uint8_t {
  kSamePlace,  ///< NaN equals NaN at the same index; NaN vs a number differs (default)
  kDiffer,     ///< every NaN is a difference
};

struct CompareOptions {
  bool exact = false;  ///< hashes and every value bit for bit
  std::map<SeriesClass, Tolerance> by_class;
  std::map<std::string, Tolerance> by_series;  ///< overrides by series name
  NanPolicy nan = NanPolicy::kSamePlace;
  /// The defaults of docs (positions 1e-6 mm + 1e-9 rel, forces 1e-6 N + 1e-6 rel, metrics
  /// 1e-9 + 1e-6 rel, exact classes 0).
  static CompareOptions Defaults();
};

/// Loads a tolerances YAML file over the defaults (golden/README.md shows the format).
/// @throws InputError (file, line, field).
CompareOptions LoadTolerances(const std::string& path);

struct Divergence {
  std::string series;
  std::int64_t step = -1;
  std::int64_t row = -1, column = -1;
  std::string run_value, golden_value;
  std::string text() const;
};

struct CompareResult {
  bool equal = true;
  std::optional<Divergence> first;     ///< the earliest divergence by step, then series order
  std::vector<Divergence> per_series;  ///< first divergence of each series that differs
  std::int64_t series_compared = 0;
  std::int64_t values_compared = 0;
  std::string Report() const;
};

/// Compares `run` with `golden` (the reference side of the relative tolerance).
CompareResult CompareDigests(const Digest& run, const Digest& golden,
                             const CompareOptions& options);

}  // namespace arthrosim::scoring
