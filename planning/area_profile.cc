#include "planning/area_profile.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "planning/geometry.h"
#include "planning/svg.h"

namespace visco::planning {
namespace {

double Deg(double rad) { return rad * 180.0 / M_PI; }

const char* KindColour(CriticalKind kind) {
  switch (kind) {
    case CriticalKind::kVgraph:
      return "#1f77b4";
    case CriticalKind::kSliding:
      return "#ff7f0e";
    case CriticalKind::kVertex:
      return "#2ca02c";
    case CriticalKind::kR:
      return "#bbbbbb";
    case CriticalKind::kFreeEdge:
      return "#9467bd";
    case CriticalKind::kVc:
      return "#d62728";
    case CriticalKind::kSelection:
      return "#8c564b";
  }
  return "black";
}

}  // namespace

std::vector<AreaSample> SampleAreas(const NondirectionalBackprojection& nd, int samples) {
  std::vector<AreaSample> out;
  auto add = [&](double theta) {
    out.push_back({WrapAngle(theta), RegionAt(nd, theta, false).area, RegionAt(nd, theta, true).area});
  };
  for (int i = 0; i < samples; ++i) add(-M_PI + (i + 0.5) * 2 * M_PI / samples);
  // Each critical slice's own areas, and each open interval's just inside its ends, so that the curves jump where
  // the structure changes rather than between two samples.
  for (const Slice& s : nd.slices) {
    if (s.critical) {
      out.push_back({s.theta, s.vc.classic.area, s.vc.region.area});
    } else if (nd.slices.size() > 1) {
      const double inside = 1e-6 * (s.hi - s.lo);
      add(s.lo + inside);
      add(s.hi - inside);
    }
  }
  std::sort(out.begin(), out.end(), [](const AreaSample& a, const AreaSample& b) { return a.theta < b.theta; });
  return out;
}

std::string AreaProfileSvg(const std::string& title, const std::vector<AreaSample>& samples,
                           const std::vector<CriticalOrientation>& orientations) {
  const double w = 900, h = 360, left = 70, right = 20, top = 40, bottom = 50;
  double max_area = 0;
  for (const auto& s : samples) max_area = std::max({max_area, s.classic, s.vc});
  if (max_area <= 0) max_area = 1;
  auto X = [&](double theta) { return left + (Deg(theta) + 180.0) / 360.0 * (w - left - right); };
  auto Y = [&](double area) { return h - bottom - area / (1.05 * max_area) * (h - top - bottom); };
  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" viewBox=\"0 0 {} {}\">\n"
      "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
      w, h + 30, w, h + 30);
  svg += fmt::format("<text x=\"{}\" y=\"22\" font-size=\"15\" font-family=\"sans-serif\">{}</text>\n", left,
                     SvgEscape(title));
  // Axes and ticks every 45°.
  svg += fmt::format("<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/>\n", left, h - bottom, w - right,
                     h - bottom);
  svg += fmt::format("<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/>\n", left, top, left, h - bottom);
  for (int d = -180; d <= 180; d += 45) {
    const double x = X(d * M_PI / 180.0);
    svg += fmt::format(
        "<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"black\"/><text x=\"{0}\" y=\"{3}\" "
        "font-size=\"12\" text-anchor=\"middle\" font-family=\"sans-serif\">{4}°</text>\n",
        x, h - bottom, h - bottom + 5, h - bottom + 20, d);
  }
  for (int k = 0; k <= 4; ++k) {
    const double a = max_area * k / 4;
    svg += fmt::format(
        "<text x=\"{}\" y=\"{}\" font-size=\"12\" text-anchor=\"end\" font-family=\"sans-serif\">{:.3g}</text>\n",
        left - 6, Y(a) + 4, a);
  }
  svg += fmt::format(
      "<text x=\"{}\" y=\"{}\" font-size=\"12\" text-anchor=\"middle\" font-family=\"sans-serif\">commanded "
      "direction θ (degrees)</text>\n",
      (left + w - right) / 2, h - 10);
  // Critical orientations, coloured by kind.
  for (const auto& o : orientations) {
    svg += fmt::format(
        "<line class=\"critical {}\" x1=\"{:.2f}\" y1=\"{}\" x2=\"{:.2f}\" y2=\"{}\" stroke=\"{}\" "
        "stroke-width=\"1\" opacity=\"0.7\"><title>{:.4f}° {}</title></line>\n",
        CriticalKindName(o.kind), X(o.theta), top, X(o.theta), h - bottom, KindColour(o.kind), Deg(o.theta),
        CriticalKindName(o.kind));
  }
  auto polyline = [&](bool vc, const char* colour, const char* cls) {
    std::string pts;
    for (const auto& s : samples) pts += fmt::format("{:.2f},{:.2f} ", X(s.theta), Y(vc ? s.vc : s.classic));
    return fmt::format("<polyline class=\"{}\" points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"2\"/>\n", cls,
                       pts, colour);
  };
  svg += polyline(true, "#c00", "area-vc");
  svg += polyline(false, "#036", "area-classic");
  // Legend.
  double lx = left;
  const double ly = h + 12;
  svg += fmt::format(
      "<line x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\" stroke=\"#036\" stroke-width=\"2\"/><text x=\"{3}\" y=\"{4}\" "
      "font-size=\"12\" font-family=\"sans-serif\">area of B_θ(G)</text>\n",
      lx, ly, lx + 20, lx + 24, ly + 4);
  lx += 120;
  svg += fmt::format(
      "<line x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\" stroke=\"#c00\" stroke-width=\"2\"/><text x=\"{3}\" y=\"{4}\" "
      "font-size=\"12\" font-family=\"sans-serif\">area of B_vcθ(G)</text>\n",
      lx, ly, lx + 20, lx + 24, ly + 4);
  lx += 130;
  for (int k = 0; k < 7; ++k) {
    const auto kind = static_cast<CriticalKind>(k);
    svg += fmt::format(
        "<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"{3}\" stroke-width=\"2\"/><text x=\"{4}\" "
        "y=\"{5}\" font-size=\"12\" font-family=\"sans-serif\">{6}</text>\n",
        lx, ly - 6, ly + 6, KindColour(kind), lx + 4, ly + 4, CriticalKindName(kind));
    lx += 72;
  }
  svg += "</svg>\n";
  return svg;
}

}  // namespace visco::planning
