// The score report as JSON (docs/score-format.md), as an xAPI statement, and as console text.
#include <fmt/core.h>

#include <cmath>
#include <optional>
#include <string>

#include "arthrosim/scoring/score.h"

namespace arthrosim::scoring {
namespace {

std::string Quote(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          out += fmt::format("\\u{:04x}", static_cast<int>(c));
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

// Shortest decimal that reads back to the same double; null for NaN and infinities.
std::string Num(double v) { return std::isfinite(v) ? fmt::format("{}", v) : "null"; }
std::string Num(const std::optional<double>& v) { return v ? Num(*v) : "null"; }
const char* Bool(bool b) { return b ? "true" : "false"; }

void Steps(const ScoreReport& r, std::string* out) {
  *out += "  \"steps\": [";
  for (std::size_t i = 0; i < r.steps.size(); ++i) {
    const StepResult& s = r.steps[i];
    *out += fmt::format(
        "{}\n    {{\"id\": {}, \"title\": {}, \"completed\": {}, \"passed\": {}, \"start_s\": {}, "
        "\"end_s\": {}, \"duration_s\": {}, \"completion_frame\": {}, \"reason\": {}}}",
        i ? "," : "", Quote(s.id), Quote(s.title), Bool(s.completed), Bool(s.passed),
        Num(s.start_s), Num(s.end_s), Num(s.duration_s), s.completion_frame, Quote(s.reason));
  }
  *out += "\n  ],\n";
}

void Violations(const ScoreReport& r, std::string* out) {
  *out += "  \"violations\": [";
  for (std::size_t i = 0; i < r.violations.size(); ++i) {
    const Violation& v = r.violations[i];
    *out += fmt::format("{}\n    {{\"kind\": {}, \"time_s\": {}, \"step\": {}, \"text\": {}}}",
                        i ? "," : "", Quote(v.kind), Num(v.time_s), Quote(v.step), Quote(v.text));
  }
  *out += "\n  ],\n";
}

void Metrics(const ScoreReport& r, std::string* out) {
  *out += "  \"metrics\": [";
  for (std::size_t i = 0; i < r.metrics.size(); ++i) {
    const Metric& m = r.metrics[i];
    *out += fmt::format(
        "{}\n    {{\"id\": {}, \"domain\": {}, \"label\": {}, \"unit\": {}, \"value\": {}, "
        "\"min\": {}, \"max\": {}, \"pass\": {}, \"critical\": {}, \"z\": {}, "
        "\"reference_mean\": {}}}",
        i ? "," : "", Quote(m.id), Quote(m.domain), Quote(m.label), Quote(m.unit), Num(m.value),
        Num(m.min), Num(m.max), Bool(m.pass), Bool(m.critical), Num(m.z), Num(m.reference_mean));
  }
  *out += "\n  ]\n";
}

}  // namespace

std::string IsoDuration(double seconds) {
  if (!(seconds >= 0) || !std::isfinite(seconds)) seconds = 0;
  const long long centis = std::llround(seconds * 100.0);
  const long long hours = centis / 360000, minutes = (centis / 6000) % 60;
  const long long rest = centis % 6000;
  std::string out = "PT";
  if (hours) out += fmt::format("{}H", hours);
  if (minutes) out += fmt::format("{}M", minutes);
  out += fmt::format("{}.{:02d}S", rest / 100, rest % 100);
  return out;
}

std::string ToJson(const ScoreReport& r) {
  std::string out = "{\n";
  out += fmt::format("  \"schema\": \"arthrosim-score\",\n  \"schema_version\": {},\n",
                     kScoreSchemaVersion);
  out += fmt::format(
      "  \"run_file\": {},\n  \"plan\": {},\n  \"scenario\": {},\n  \"duration_s\": {},\n"
      "  \"references\": {},\n  \"passed\": {},\n  \"total\": {},\n",
      Quote(r.run_file), Quote(r.plan_name), Quote(r.scenario), Num(r.duration_s), r.references,
      Bool(r.passed), Num(r.total));
  out += "  \"domains\": {";
  bool first = true;
  for (const auto& [domain, score] : r.domains) {
    out += fmt::format("{}{}: {}", first ? "" : ", ", Quote(domain), Num(score));
    first = false;
  }
  out += "},\n  \"critical_errors\": [";
  for (std::size_t i = 0; i < r.critical_errors.size(); ++i)
    out += (i ? ", " : "") + Quote(r.critical_errors[i]);
  out += "],\n";
  Steps(r, &out);
  Violations(r, &out);
  Metrics(r, &out);
  out += "}\n";
  return out;
}

std::string ToXapi(const ScoreReport& r) {
  const char* verb = r.passed ? "passed" : "failed";
  const double scaled = std::clamp(r.total / 100.0, -1.0, 1.0);
  return fmt::format(
      "{{\n  \"actor\": {{\"objectType\": \"Agent\", \"account\": {{\"homePage\": "
      "\"urn:arthrosim\", \"name\": {}}}}},\n"
      "  \"verb\": {{\"id\": \"http://adlnet.gov/expapi/verbs/{}\", \"display\": {{\"en-US\": "
      "\"{}\"}}}},\n"
      "  \"object\": {{\"objectType\": \"Activity\", \"id\": \"urn:arthrosim:plan:{}\", "
      "\"definition\": {{\"type\": \"http://adlnet.gov/expapi/activities/simulation\", "
      "\"name\": {{\"en-US\": {}}}}}}},\n"
      "  \"result\": {{\"score\": {{\"scaled\": {}, \"raw\": {}, \"min\": 0, \"max\": 100}}, "
      "\"success\": {}, \"completion\": true, \"duration\": \"{}\"}}\n}}\n",
      Quote(r.run_file), verb, verb, r.plan_name, Quote(r.plan_name), Num(scaled), Num(r.total),
      Bool(r.passed), IsoDuration(r.duration_s));
}

std::string ConsoleSummary(const ScoreReport& r) {
  std::string out = fmt::format("{}: {} against plan {}: {:.1f}/100, {}\n", r.run_file, r.scenario,
                                r.plan_name, r.total, r.passed ? "PASS" : "FAIL");
  for (const auto& [domain, score] : r.domains)
    out += fmt::format("  {:<15} {:5.1f}\n", domain, score);
  for (const StepResult& s : r.steps) {
    out += fmt::format("  [{}] {}", s.passed ? "pass" : "FAIL", s.title);
    if (s.completed) out += fmt::format(" ({:.1f} s)", s.duration_s);
    if (!s.reason.empty()) out += ": " + s.reason;
    out += "\n";
  }
  for (const std::string& e : r.critical_errors) out += "  critical: " + e + "\n";
  for (const Violation& v : r.violations)
    if (v.kind == "order" || v.kind == "wrong_instrument") out += "  " + v.text + "\n";
  return out;
}

}  // namespace arthrosim::scoring
