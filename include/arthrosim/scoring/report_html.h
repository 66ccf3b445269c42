#pragma once
// The instructor's report: one self-contained HTML file (inline SVG plots, PNG thumbnails as
// data URIs, no network resource): verdict and domain scores, a per-step table, a timeline of
// steps and events, instrument force over time with the protected-structure limits, instrument
// and camera paths in top and side views, the arthroscope view at each step's completion, the
// metrics, and a link to the run's video when one sits beside the run file.
#include <string>

#include "arthrosim/scoring/plan.h"
#include "arthrosim/scoring/run_data.h"
#include "arthrosim/scoring/score.h"

namespace arthrosim::scoring {

struct HtmlOptions {
  bool thumbnails = true;  ///< render the scope view at each completed step (OSMesa)
  int thumb_width = 240;
  int thumb_height = 180;
};

/// The report page. Thumbnails that cannot be rendered (no GL context or font) are replaced by
/// a note saying why; everything else never needs rendering.
std::string ReportHtml(const Plan& plan, const RunData& run, const ScoreReport& report,
                       const HtmlOptions& options = {});

/// `bytes` as base64 (RFC 4648, with padding).
std::string Base64(const std::string& bytes);

}  // namespace arthrosim::scoring
