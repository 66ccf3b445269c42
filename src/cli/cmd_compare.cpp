// arthrosim compare RUN.h5 GOLDEN.h5 [--tolerances F] [--exact] [--update [--sparse K]]
// Compares a run with a golden file (or another run) series by series (golden/README.md).
// Exit 0 equal, 1 regression, 2 bad input. --update rewrites GOLDEN from RUN (tools/update-golden)
// and prints what changed.
#include <fmt/core.h>

#include <filesystem>
#include <memory>

#include "arthrosim/core/error.h"
#include "arthrosim/scoring/compare.h"
#include "commands.h"

namespace arthrosim::cli {
namespace {

struct CompareArgs {
  std::string run, golden, tolerances;
  bool exact = false, update = false;
  std::int64_t sparse = 50;
};

void CheckFile(const std::string& path, const char* field) {
  if (!std::filesystem::exists(path)) throw InputError(path, 0, field, "file not found");
}

int Update(const CompareArgs& a) {
  CheckFile(a.run, "RUN");
  const scoring::Digest digest = scoring::DigestOfRun(a.run, a.sparse);
  if (std::filesystem::exists(a.golden) && scoring::IsGoldenFile(a.golden)) {
    const scoring::Digest old = scoring::ReadGolden(a.golden);
    const scoring::CompareResult r =
        scoring::CompareDigests(digest, old, scoring::CompareOptions::Defaults());
    fmt::print("{}: {}", a.golden, r.equal ? "unchanged (within tolerances)\n" : r.Report());
  } else {
    fmt::print("{}: new golden file\n", a.golden);
  }
  scoring::WriteGolden(a.golden, digest);
  fmt::print("wrote {} ({} bytes)\n", a.golden, std::filesystem::file_size(a.golden));
  return kExitOk;
}

int RunCompare(const CompareArgs& a) {
  if (a.update) return Update(a);
  CheckFile(a.run, "RUN");
  CheckFile(a.golden, "GOLDEN");
  const scoring::CompareOptions options = [&] {
    scoring::CompareOptions o = a.tolerances.empty() ? scoring::CompareOptions::Defaults()
                                                     : scoring::LoadTolerances(a.tolerances);
    o.exact = a.exact;
    return o;
  }();
  // A golden file fixes the sparse frames; two run files compare every frame.
  const scoring::Digest golden = scoring::LoadDigest(a.golden, 0);
  const scoring::Digest run = scoring::DigestOfRun(a.run, golden.sparse_every);
  const scoring::CompareResult r = scoring::CompareDigests(run, golden, options);
  fmt::print("{}", r.Report());
  return r.equal ? kExitOk : kExitCheckFailed;
}

}  // namespace

void AddCompareCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand("compare", "Compare a run with a golden file (regression)");
  auto a = std::make_shared<CompareArgs>();
  cmd->add_option("run", a->run, "Run file (.h5)")->required();
  cmd->add_option("golden", a->golden, "Golden file (or another run file)")->required();
  cmd->add_option("--tolerances", a->tolerances, "Tolerances YAML (golden/README.md)");
  cmd->add_flag("--exact", a->exact, "Every value and state hash bit for bit");
  cmd->add_flag("--update", a->update, "Rewrite GOLDEN from RUN and print what changed");
  cmd->add_option("--sparse", a->sparse, "With --update: body positions every K frames")
      ->check(CLI::PositiveNumber);
  cmd->callback([a, exit_code] { *exit_code = RunCompare(*a); });
}

}  // namespace arthrosim::cli
