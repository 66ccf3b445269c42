#include "arthrosim/scoring/report_html.h"

#include <fmt/core.h>
#include <stb_image_write.h>

#include <algorithm>
#include <cmath>
#include <exception>

#include "arthrosim/io/run_reader.h"
#include "arthrosim/render/renderer.h"
#include "arthrosim/render/scene.h"

namespace arthrosim::scoring {
namespace {

constexpr int kPlotW = 760, kPlotH = 220;
const char* const kColors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e",
                               "#8c564b", "#e377c2", "#17becf", "#bcbd22", "#7f7f7f"};

std::string Esc(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else if (c == '"')
      out += "&quot;";
    else
      out += c;
  }
  return out;
}

std::string Fmt(double v) { return std::isfinite(v) ? fmt::format("{:.3g}", v) : "-"; }

// Maps a data interval onto pixels.
struct Axis {
  double lo = 0, hi = 1;
  double px0 = 0, px1 = 1;
  double operator()(double v) const {
    return hi > lo ? px0 + (v - lo) / (hi - lo) * (px1 - px0) : px0;
  }
};

std::string SvgOpen(const char* cls) {
  return fmt::format(
      "<svg class='{}' width='{}' height='{}' viewBox='0 0 {} {}' "
      "xmlns='http://www.w3.org/2000/svg'><rect width='100%' height='100%' fill='#fff' "
      "stroke='#ccc'/>",
      cls, kPlotW, kPlotH, kPlotW, kPlotH);
}

std::string Timeline(const RunData& run, const ScoreReport& report) {
  const double t_end = std::max(run.time_s.back(), 1e-9);
  const int rows = static_cast<int>(report.steps.size());
  const int h = 40 + 18 * rows + 30;
  Axis x{0, t_end, 150, kPlotW - 10.0};
  std::string svg = fmt::format(
      "<svg class='timeline' width='{}' height='{}' xmlns='http://www.w3.org/2000/svg'>"
      "<rect width='100%' height='100%' fill='#fff' stroke='#ccc'/>",
      kPlotW, h);
  for (int i = 0; i < rows; ++i) {
    const StepResult& s = report.steps[i];
    const double y = 20 + 18 * i;
    svg += fmt::format("<text x='4' y='{}' font-size='11'>{}</text>", y + 11, Esc(s.id));
    if (std::isfinite(s.start_s)) {
      const double end = std::isfinite(s.end_s) ? s.end_s : t_end;
      svg += fmt::format(
          "<rect x='{:.1f}' y='{}' width='{:.1f}' height='13' fill='{}'><title>{}</title></rect>",
          x(s.start_s), y, std::max(2.0, x(end) - x(s.start_s)), s.passed ? "#4caf50" : "#e53935",
          Esc(s.title));
    }
  }
  const double ey = 24 + 18 * rows;
  for (const Event& e : run.events) {
    const bool contact = e.kind == "contact_start" || e.kind == "contact_end";
    svg += fmt::format(
        "<line x1='{0:.1f}' x2='{0:.1f}' y1='{1}' y2='{2}' stroke='{3}'><title>{4} {5:.2f} s "
        "{6} {7}</title></line>",
        x(e.time_s), ey, ey + 12, contact ? "#90a4ae" : "#d81b60", Esc(e.kind), e.time_s,
        Esc(e.tool), Esc(e.body));
  }
  svg += fmt::format("<text x='4' y='{}' font-size='11'>events</text>", ey + 11);
  svg += fmt::format(
      "<text x='150' y='{}' font-size='10'>0 s</text><text x='{}' y='{}' "
      "font-size='10' text-anchor='end'>{:.1f} s</text></svg>",
      h - 4, kPlotW - 10, h - 4, t_end);
  return svg;
}

std::string ForcePlot(const Plan& plan, const RunData& run) {
  double fmax = 0.5;
  for (const InstrumentSeries& s : run.instruments)
    for (double f : s.force_n) fmax = std::max(fmax, f);
  for (const ProtectedStructure& p : plan.protected_structures)
    fmax = std::max(fmax, 1.1 * p.max_force_n);
  Axis x{0, std::max(run.time_s.back(), 1e-9), 40, kPlotW - 10.0};
  Axis y{0, fmax * 1.05, kPlotH - 20.0, 10};
  std::string svg = SvgOpen("force");
  int color = 0;
  std::string legend;
  for (const InstrumentSeries& s : run.instruments) {
    if (std::find(s.active.begin(), s.active.end(), 1) == s.active.end()) continue;
    std::string points;
    for (std::int64_t k = 0; k < run.frames(); ++k)
      points += fmt::format("{:.1f},{:.1f} ", x(run.time_s[k]), y(s.force_n[k]));
    const char* c = kColors[color++ % 10];
    svg += fmt::format("<polyline fill='none' stroke='{}' stroke-width='1.2' points='{}'/>", c,
                       points);
    legend += fmt::format("<span style='color:{}'>&#9632; {}</span> ", c, Esc(s.name));
  }
  for (const ProtectedStructure& p : plan.protected_structures)
    svg += fmt::format(
        "<line x1='40' x2='{0}' y1='{1:.1f}' y2='{1:.1f}' stroke='#e53935' stroke-dasharray='5,3'/>"
        "<text x='{0}' y='{2:.1f}' font-size='10' text-anchor='end' fill='#e53935'>{3} "
        "{4:g} N</text>",
        kPlotW - 10, y(p.max_force_n), y(p.max_force_n) - 2, Esc(p.name), p.max_force_n);
  svg += fmt::format(
      "<text x='2' y='14' font-size='10'>{:.2g} N</text><text x='2' y='{}' "
      "font-size='10'>0</text></svg>",
      fmax, kPlotH - 20);
  return svg + "<div class='legend'>" + legend + "</div>";
}

// Paths projected on two world axes (a, b) = (0, 1) top view, (0, 2) side view.
std::string PathPlot(const RunData& run, int a, int b, const char* title) {
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  auto extend = [&](const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  };
  for (const InstrumentSeries& s : run.instruments)
    for (std::int64_t k = 0; k < run.frames(); ++k)
      if (s.active[k]) extend(s.pose[k].position_mm);
  for (const CameraState& c : run.camera) extend(c.pose.position_mm);
  const double span = std::max({hi[a] - lo[a], hi[b] - lo[b], 1.0});
  const int w = kPlotW / 2 - 10, h = 300;
  Axis x{lo[a], lo[a] + span, 10, w - 10.0};
  Axis y{lo[b], lo[b] + span, h - 10.0, h - 10.0 - (w - 20.0)};
  std::string svg = fmt::format(
      "<svg class='paths' width='{0}' height='{1}' xmlns='http://www.w3.org/2000/svg'>"
      "<rect width='100%' height='100%' fill='#fff' stroke='#ccc'/>"
      "<text x='6' y='14' font-size='11'>{2}</text>",
      w, h, title);
  auto polyline = [&](const std::vector<Vec3>& pts, const char* color) {
    std::string p;
    for (const Vec3& v : pts) p += fmt::format("{:.1f},{:.1f} ", x(v[a]), y(v[b]));
    svg +=
        fmt::format("<polyline fill='none' stroke='{}' stroke-width='1.2' points='{}'/>", color, p);
  };
  int color = 0;
  for (const InstrumentSeries& s : run.instruments) {
    std::vector<Vec3> pts;
    bool any = false;
    for (std::int64_t k = 0; k <= run.frames(); ++k) {
      if (k < run.frames() && s.active[k]) {
        pts.push_back(s.pose[k].position_mm);
        any = true;
      } else if (!pts.empty()) {
        polyline(pts, kColors[color % 10]);
        pts.clear();
      }
    }
    if (any) ++color;
  }
  std::vector<Vec3> cam;
  for (const CameraState& c : run.camera) cam.push_back(c.pose.position_mm);
  polyline(cam, "#000");
  return svg + "</svg>";
}

void AppendPng(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data), size);
}

// Data URIs of the scope view at each completed step ("" where not rendered), or the reason.
std::vector<std::string> Thumbnails(const RunData& run, const ScoreReport& report,
                                    const HtmlOptions& o, std::string* why) {
  std::vector<std::string> out(report.steps.size());
  if (!o.thumbnails) return out;
  try {
    render::Renderer renderer;
    io::RunReader reader(run.path);
    render::ViewSpec spec;
    spec.width = o.thumb_width;
    spec.height = o.thumb_height;
    spec.overlay = false;
    State state;
    render::Image image;
    for (std::size_t i = 0; i < report.steps.size(); ++i) {
      const std::int64_t k = report.steps[i].completion_frame;
      if (k < 0 || k >= reader.frame_count()) continue;
      reader.ReadFrame(k, state);
      renderer.Render(render::BuildScene(run.model, state), spec, &image);
      std::string png;
      stbi_write_png_to_func(AppendPng, &png, image.width, image.height, 3, image.rgb.data(),
                             image.width * 3);
      out[i] = "data:image/png;base64," + Base64(png);
    }
  } catch (const std::exception& e) {
    *why = e.what();
  }
  return out;
}

std::string StepTable(const ScoreReport& report, const std::vector<std::string>& thumbs) {
  std::string t =
      "<table><tr><th>step</th><th>verdict</th><th>start</th><th>done</th><th>duration</th>"
      "<th>reason</th><th>scope view at completion</th></tr>";
  for (std::size_t i = 0; i < report.steps.size(); ++i) {
    const StepResult& s = report.steps[i];
    t += fmt::format(
        "<tr class='{}'><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>",
        s.passed ? "pass" : "fail", Esc(s.title), s.passed ? "PASS" : "FAIL", Fmt(s.start_s),
        Fmt(s.end_s), Fmt(s.duration_s), Esc(s.reason));
    if (!thumbs[i].empty())
      t +=
          fmt::format("<img class='thumb' alt='scope view at {}' src='{}'/>", Esc(s.id), thumbs[i]);
    t += "</td></tr>";
  }
  return t + "</table>";
}

std::string MetricTable(const ScoreReport& report) {
  std::string t =
      "<table class='metrics'><tr><th>metric</th><th>domain</th><th>value</th><th>unit</th>"
      "<th>band</th><th>pass</th><th>z</th></tr>";
  for (const Metric& m : report.metrics) {
    std::string band = m.min && m.max ? fmt::format("{:g} to {:g}", *m.min, *m.max)
                       : m.min        ? fmt::format("&ge; {:g}", *m.min)
                       : m.max        ? fmt::format("&le; {:g}", *m.max)
                                      : "";
    t += fmt::format(
        "<tr class='{}'><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>"
        "<td>{}</td><td>{}</td></tr>",
        m.pass ? "pass" : "fail", Esc(m.label), m.domain, Fmt(m.value), m.unit, band,
        m.pass ? "yes" : "NO", m.z ? Fmt(*m.z) : "");
  }
  return t + "</table>";
}

const char* kStyle =
    "body{font-family:sans-serif;margin:16px;color:#222}table{border-collapse:collapse;"
    "margin:8px 0}td,th{border:1px solid #ccc;padding:3px 6px;font-size:13px;text-align:left}"
    "tr.fail td:nth-child(2){color:#c62828;font-weight:bold}tr.pass td:nth-child(2)"
    "{color:#2e7d32}.verdict{font-size:22px;font-weight:bold}.PASS{color:#2e7d32}"
    ".FAIL{color:#c62828}.legend{font-size:12px}.thumb{display:block;border:1px solid #999}"
    "svg{margin:4px 4px 4px 0}";

}  // namespace

std::string Base64(const std::string& bytes) {
  static const char* const kAlphabet =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::size_t n = std::min<std::size_t>(3, bytes.size() - i);
    std::uint32_t v = 0;
    for (std::size_t j = 0; j < 3; ++j)
      v = (v << 8) | (j < n ? static_cast<unsigned char>(bytes[i + j]) : 0u);
    for (std::size_t j = 0; j < 4; ++j) out += j <= n ? kAlphabet[(v >> (18 - 6 * j)) & 63] : '=';
  }
  return out;
}

std::string ReportHtml(const Plan& plan, const RunData& run, const ScoreReport& report,
                       const HtmlOptions& options) {
  std::string why;
  const std::vector<std::string> thumbs = Thumbnails(run, report, options, &why);
  const char* verdict = report.passed ? "PASS" : "FAIL";
  std::string h = fmt::format(
      "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>arthrosim score: {}"
      "</title><style>{}</style></head><body><h1>{} &mdash; {}</h1>"
      "<p class='verdict {}'>{} &nbsp; {:.1f} / 100</p><p>run {} ({:.1f} s), plan {}{}</p>",
      Esc(report.run_file), kStyle, Esc(report.scenario), Esc(plan.name), verdict, verdict,
      report.total, Esc(report.run_file), report.duration_s, Esc(plan.name),
      report.references ? fmt::format(", {} reference run(s)", report.references) : "");
  if (run.video_beside)
    h += fmt::format("<p>Video: <a href='{0}'>{0}</a></p>", Esc(run.video_path));
  h += "<table><tr>";
  for (const auto& [domain, score] : report.domains) h += fmt::format("<th>{}</th>", Esc(domain));
  h += "</tr><tr>";
  for (const auto& [domain, score] : report.domains) h += fmt::format("<td>{:.1f}</td>", score);
  h += "</tr></table>";
  if (!report.critical_errors.empty()) {
    h += "<h2>Critical errors</h2><ul>";
    for (const std::string& e : report.critical_errors) h += "<li>" + Esc(e) + "</li>";
    h += "</ul>";
  }
  h += "<h2>Steps</h2>" + StepTable(report, thumbs);
  if (!why.empty()) h += "<p>Thumbnails not rendered: " + Esc(why) + "</p>";
  if (!report.violations.empty()) {
    h += "<h2>Violations</h2><ul>";
    for (const Violation& v : report.violations) h += "<li>" + Esc(v.text) + "</li>";
    h += "</ul>";
  }
  h += "<h2>Timeline</h2>" + Timeline(run, report);
  h += "<h2>Instrument force</h2>" + ForcePlot(plan, run);
  h += "<h2>Paths (instruments in colour, camera black)</h2>" +
       PathPlot(run, 0, 1, "top view (x-y)") + PathPlot(run, 0, 2, "side view (x-z)");
  h += "<h2>Metrics</h2>" + MetricTable(report);
  return h + "</body></html>\n";
}

}  // namespace arthrosim::scoring
