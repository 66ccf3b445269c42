// arthrosim score RUN.h5 --plan PLAN [--reference EXPERT.h5]... [--json F] [--html F] [--xapi F]
//                 [--scenario FILE]
// Scores a recorded run against a procedure plan from the run file alone (no simulation).
// Exit 0 pass, 1 fail, 2 bad input.
#include <fmt/core.h>

#include <fstream>
#include <memory>

#include "arthrosim/core/error.h"
#include "arthrosim/scoring/plan.h"
#include "arthrosim/scoring/report_html.h"
#include "arthrosim/scoring/score.h"
#include "commands.h"

namespace arthrosim::cli {
namespace {

struct ScoreArgs {
  std::string run, plan, scenario, json, html, xapi;
  std::vector<std::string> references;
};

void WriteText(const std::string& path, const std::string& text, const char* option) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw InputError(path, 0, option, "cannot write the file");
}

int RunScore(const ScoreArgs& a) {
  const Model model = scoring::LoadRunModel(a.run, a.scenario);
  const scoring::Plan plan = scoring::LoadPlan(a.plan, &model);
  const scoring::RunData run = scoring::ReadRunData(a.run, model);
  std::vector<scoring::RunData> refs;
  for (const std::string& r : a.references) {
    refs.push_back(scoring::ReadRunData(r, scoring::LoadRunModel(r, a.scenario)));
    if (refs.back().model.name != model.name)
      throw InputError(
          r, 0, "--reference",
          "reference is of scenario '" + refs.back().model.name + "', not '" + model.name + "'");
  }
  std::vector<const scoring::RunData*> ref_ptrs;
  for (const scoring::RunData& r : refs) ref_ptrs.push_back(&r);
  const scoring::ScoreReport report = scoring::Evaluate(plan, run, ref_ptrs);
  fmt::print("{}", scoring::ConsoleSummary(report));
  if (!a.json.empty()) WriteText(a.json, scoring::ToJson(report), "--json");
  if (!a.xapi.empty()) WriteText(a.xapi, scoring::ToXapi(report), "--xapi");
  if (!a.html.empty()) {
    WriteText(a.html, scoring::ReportHtml(plan, run, report), "--html");
    fmt::print("report: {}\n", a.html);
  }
  return report.passed ? kExitOk : kExitCheckFailed;
}

}  // namespace

void AddScoreCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand("score", "Score a run file against a procedure plan");
  auto a = std::make_shared<ScoreArgs>();
  cmd->add_option("run", a->run, "Run file (.h5)")->required();
  cmd->add_option("--plan", a->plan, "Procedure plan (YAML, docs/plan-format.md)")->required();
  cmd->add_option("--reference", a->references, "Expert run(s) for z-scores and economy");
  cmd->add_option("--json", a->json, "Write the score as JSON (docs/score-format.md)");
  cmd->add_option("--html", a->html, "Write a self-contained HTML report");
  cmd->add_option("--xapi", a->xapi, "Write the result as an xAPI statement (JSON)");
  cmd->add_option("--scenario", a->scenario,
                  "Scenario file if the run's is not at its stored path");
  cmd->callback([a, exit_code] { *exit_code = RunScore(*a); });
}

}  // namespace arthrosim::cli
