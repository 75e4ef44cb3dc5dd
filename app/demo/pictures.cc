#include "app/demo/pictures.h"

#include <fmt/format.h>

#include <algorithm>

#include "app/demo/monte_carlo.h"
#include "planning/svg.h"

namespace visco::app::demo {
namespace {

// A histogram panel: `values` in `bins` bins over [min, max] of the values; bars, axis, ticks, the median.
planning::SvgCanvas HistogramPanel(const std::vector<double>& values, const std::string& title, const std::string& unit,
                                   int bins = 20) {
  // World frame of the panel: x in [0, 1] along the values, y in [0, 0.75] along the counts.
  planning::SvgCanvas c({-0.08, -0.12}, {1.04, 0.85}, 380);
  c.TextPx(10, 18, title, 13, "fill=\"black\"");
  if (values.empty()) {
    c.Text({0.5, 0.4}, "no values", 12, "fill=\"#666\" text-anchor=\"middle\"");
    return c;
  }
  const double lo = *std::min_element(values.begin(), values.end());
  double hi = *std::max_element(values.begin(), values.end());
  if (hi - lo < 1e-9) hi = lo + 1;
  std::vector<int> count(static_cast<size_t>(bins), 0);
  for (double v : values) {
    const int b = std::clamp(static_cast<int>((v - lo) / (hi - lo) * bins), 0, bins - 1);
    ++count[static_cast<size_t>(b)];
  }
  const int top = *std::max_element(count.begin(), count.end());
  for (int b = 0; b < bins; ++b) {
    if (count[static_cast<size_t>(b)] == 0) continue;
    const double x0 = static_cast<double>(b) / bins, x1 = static_cast<double>(b + 1) / bins;
    const double h = 0.75 * count[static_cast<size_t>(b)] / top;
    planning::Polygon bar;
    bar.vertices = {{x0, 0}, {x1, 0}, {x1, h}, {x0, h}};
    c.Polygon(bar, "class=\"bar\" fill=\"#4a7\" stroke=\"white\" stroke-width=\"1\"");
  }
  c.Line({0, 0}, {1, 0}, "stroke=\"black\" stroke-width=\"1\"");
  c.Line({0, 0}, {0, 0.75}, "stroke=\"black\" stroke-width=\"1\"");
  for (int k = 0; k <= 4; ++k) {
    const double x = k / 4.0;
    c.Line({x, 0}, {x, -0.015}, "stroke=\"black\" stroke-width=\"1\"");
    c.Text({x, -0.015}, fmt::format("{:.3g}", lo + x * (hi - lo)), 11, "fill=\"black\" text-anchor=\"middle\"", 0, 13);
  }
  c.Text({1.0, -0.015}, unit, 11, "fill=\"black\" text-anchor=\"end\"", 0, 27);
  c.Text({0, 0.75}, std::to_string(top), 11, "fill=\"black\" text-anchor=\"end\"", -4, 4);
  const double median = Quantile(values, 0.5);
  const double mx = (median - lo) / (hi - lo);
  c.Line({mx, 0}, {mx, 0.78}, "class=\"median\" stroke=\"#c00\" stroke-width=\"1.5\" stroke-dasharray=\"4 3\"");
  c.Text({mx, 0.78}, fmt::format("median {:.3g}", median), 11, "fill=\"#c00\" text-anchor=\"middle\"", 0, -4);
  return c;
}

}  // namespace

std::string RunSvg(const planning::Scene& scene, const planning::CSpace& cspace, const planning::Strategy& strategy,
                   const Trace& trace) {
  planning::SvgCanvas c(scene.bounds.min, scene.bounds.max, 700);
  planning::DrawStrategy(c, scene, cspace, strategy);
  for (size_t i = 1; i < trace.path.size(); ++i) {
    c.Line(trace.path[i - 1], trace.path[i], "class=\"trajectory\" stroke=\"#c00\" stroke-width=\"2.5\"");
  }
  for (const auto& p : trace.crossings)
    c.Circle(p, 6, "class=\"vc-event\" fill=\"none\" stroke=\"#90c\" stroke-width=\"3\"");
  for (const auto& p : trace.contacts) c.Circle(p, 4, "class=\"contact\" fill=\"#f80\" stroke=\"none\"");
  if (!trace.path.empty()) c.Circle(trace.path.back(), 5, "class=\"end\" fill=\"#c00\" stroke=\"black\"");
  c.TextPx(10, 18,
           fmt::format("{}: the executed trajectory over the plan (steps numbered from 0, as in the logs)", scene.name),
           13, "fill=\"black\"");
  auto legend = planning::StrategyLegend(strategy);
  legend.push_back({{"━", "#c00", "executed trajectory (vision's estimates)"},
                    {"○", "#90c", "visual event"},
                    {"●", "#f80", "contact"},
                    {"●", "#c00", "where it ended"}});
  c.Legend(legend);
  return c.Finish();
}

std::string MonteCarloSvg(const Setup& su, const std::vector<RunOutcome>& outcomes) {
  planning::SvgCanvas plan(su.scene->bounds.min, su.scene->bounds.max, 520);
  planning::DrawStrategy(plan, *su.scene, *su.cspace, *su.strategy);
  std::vector<double> times, commands;
  int ok = 0;
  for (const auto& o : outcomes) {
    const std::string colour = o.ok ? "#2a2" : "#d00";
    for (size_t i = 1; i < o.trace.path.size(); ++i) {
      plan.Line(o.trace.path[i - 1], o.trace.path[i],
                "class=\"trajectory\" stroke=\"" + colour + "\" stroke-width=\"1\" stroke-opacity=\"0.5\"");
    }
    const Eigen::Vector2d s(o.item["start"][0].get<double>(), o.item["start"][1].get<double>());
    plan.Circle(s, 2.5, "class=\"start\" fill=\"" + colour + "\" stroke=\"none\"");
    ok += o.ok;
    if (o.ok && o.item["motion_s"].is_number()) times.push_back(o.item["motion_s"].get<double>());
    if (o.ok) commands.push_back(o.item["commands_sent"].get<double>());
  }
  plan.TextPx(10, 18,
              fmt::format("{}: {} of {} runs reached the goal ({:.1f} %)", su.scene->name, ok, outcomes.size(),
                          100.0 * ok / static_cast<double>(outcomes.size())),
              13, "fill=\"black\"");
  // The legend: the runs', then the plan's underneath (preimages and commanded directions, three to a row so that
  // the legend stays inside this panel), then the scene's.
  std::vector<std::vector<planning::SvgCanvas::LegendItem>> legend = {{{"━", "#2a2", "a run that reached the goal"},
                                                                       {"━", "#d00", "a run that did not"},
                                                                       {"●", "#2a2", "its start, same colour"}}};
  const auto plan_rows = planning::StrategyLegend(*su.strategy);
  if (plan_rows.size() > 1) {
    for (std::size_t i = 0; i < plan_rows[1].size(); i += 3) {
      legend.emplace_back(plan_rows[1].begin() + static_cast<std::ptrdiff_t>(i),
                          plan_rows[1].begin() + static_cast<std::ptrdiff_t>(std::min(i + 3, plan_rows[1].size())));
    }
  }
  legend.push_back(
      {{"■", "#7c7", "start region"}, {"■", "black", "goal"}, {"■", "#bbb", "obstacle"}, {"✕", "black", "camera"}});
  plan.Legend(legend);
  const planning::SvgCanvas time_panel = HistogramPanel(times, "time in motion (successful runs)", "s");
  const planning::SvgCanvas command_panel = HistogramPanel(commands, "velocity commands sent", "commands");
  return planning::SideBySide({{"runs", &plan}, {"motion-time", &time_panel}, {"commands", &command_panel}});
}

}  // namespace visco::app::demo
