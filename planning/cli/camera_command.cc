// `visco camera`: evaluates candidate projection centres by planning with each, and ranks them (fewest steps, then
// the widest narrowest θ-interval, then the largest first preimage). Candidates: one per view of the viewing cells
// (default), a grid, or a file.

#include "planning/cli/camera_command.h"

#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/write_output.h"
#include "planning/camera_placement.h"
#include "planning/json_lines.h"
#include "planning/nondirectional.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/svg.h"
#include "planning/threads.h"

namespace visco::planning {
namespace {

using Json = nlohmann::ordered_json;

struct Args {
  std::string scene;
  double grid = 0;
  std::string candidates;
  double fov = 0;     // 0: the scene camera's width, else 100
  double height = 0;  // 0: the scene camera's height if it has one, else none (the planar model)
  std::vector<double> aim;
  int max_steps = 2;
  int max_candidates = 24;
  int max_backprojections = 12;
  int threads = MachineThreads();
  std::string out, svg;
};

enum class Mode { kCells, kGrid, kFile };

std::vector<Point> ReadCandidates(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw InputError(path, "", "cannot read the candidates file");
  std::stringstream text;
  text << file.rdbuf();
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text.str());
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path, "", fmt::format("invalid JSON: {}", e.what()));
  }
  const nlohmann::json* list = &j;
  std::string prefix;
  if (j.is_object()) {
    if (!j.contains("centers") || j.size() != 1) {
      throw InputError(path, "", "expected {\"centers\": [[x, y], ...]} or a list of [x, y]");
    }
    list = &j["centers"];
    prefix = "centers";
  }
  if (!list->is_array() || list->empty()) {
    throw InputError(path, prefix, "expected a non-empty list of candidate centres [x, y]");
  }
  std::vector<Point> out;
  for (std::size_t i = 0; i < list->size(); ++i) {
    const auto& p = (*list)[i];
    const std::string object = fmt::format("{}[{}]", prefix, i);
    if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number()) {
      throw InputError(path, object, "expected a point [x, y] of two numbers");
    }
    out.emplace_back(p[0].get<double>(), p[1].get<double>());
  }
  return out;
}

Json PointJson(const Point& p) { return Json::array({p.x(), p.y()}); }

Json EvaluationJson(const CameraEvaluation& e, bool camera) {
  Json j;
  if (camera) {
    j["center"] = PointJson(e.center);
    j["fov_deg"] = Json::array({e.fov_first_deg, e.fov_first_deg + e.fov_span_deg});
  }
  if (e.cell >= 0) j["cell"] = e.cell;
  j["feasible"] = e.feasible;
  j["steps"] = e.steps;
  j["min_interval_deg"] = e.min_interval_deg;
  j["preimage_area"] = e.preimage_area;
  j["coverage"] = e.coverage;
  j["seconds"] = std::round(e.seconds * 1000) / 1000;
  if (!e.feasible) j["reason"] = e.reason;
  return j;
}

std::string Describe(const CameraEvaluation& e) {
  if (!e.feasible) return fmt::format("no strategy (one step covers {:.0f} % of the start region)", 100 * e.coverage);
  return fmt::format("{} step{}, narrowest interval {:.2f} deg, first preimage {:.3g} m^2", e.steps,
                     e.steps == 1 ? "" : "s", e.min_interval_deg, e.preimage_area);
}

// Colour of a candidate: green for one step, yellow-orange for more, purple shades by coverage when infeasible (grey
// is the obstacles').
std::string Colour(const CameraEvaluation& e) {
  if (e.feasible) {
    static const char* by_steps[] = {"#1a9850", "#a6d96a", "#fee08b", "#fdae61", "#f46d43"};
    return by_steps[std::clamp(e.steps - 1, 0, 4)];
  }
  // From #efe3f6 (no coverage) to #6a3d9a (one step covers all of the start region).
  const double t = std::clamp(e.coverage, 0.0, 1.0);
  auto mix = [t](int a, int b) { return static_cast<int>(std::lround(a + t * (b - a))); };
  return fmt::format("#{:02x}{:02x}{:02x}", mix(0xef, 0x6a), mix(0xe3, 0x3d), mix(0xf6, 0x9a));
}

void DrawCameraMarker(SvgCanvas& c, const CameraEvaluation& e, double reach, const std::string& colour,
                      const std::string& label) {
  const double a0 = e.fov_first_deg * M_PI / 180, a1 = (e.fov_first_deg + e.fov_span_deg) * M_PI / 180;
  for (double a : {a0, a1}) {
    c.Line(e.center, e.center + reach * Vector(std::cos(a), std::sin(a)),
           fmt::format("stroke=\"{}\" stroke-width=\"1.5\" stroke-dasharray=\"5,3\"", colour));
  }
  c.Circle(e.center, 6, fmt::format("fill=\"{}\" stroke=\"black\" stroke-width=\"1\"", colour));
  c.Text(e.center, label, 13, fmt::format("fill=\"{}\" font-weight=\"bold\"", colour), 8, -8);
}

std::string HeatMapSvg(const Scene& scene, const Point& min, const Point& max, Mode mode, const ViewingCells& cells,
                       const std::vector<CameraEvaluation>& evaluated, const std::map<int, std::size_t>& by_view,
                       double grid, const std::optional<CameraEvaluation>& scene_camera, const CameraEvaluation* best) {
  // The drawing covers the bounds and the obstacles (a floor often lies below the bounds).
  Point lo = min, hi = max;
  for (const Obstacle& o : scene.obstacles) {
    for (const Point& v : o.shape.polygon.vertices) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
  SvgCanvas c(lo, hi);
  c.Polygon(Polygon{{min, {max.x(), min.y()}, max, {min.x(), max.y()}}}, "fill=\"white\" stroke=\"#999\"");
  if (mode == Mode::kCells) {
    for (const ViewingCell& cell : cells.cells) {
      const auto it = by_view.find(cell.view);
      const std::string fill = it == by_view.end() ? "#ffffff" : Colour(evaluated[it->second]);
      c.Polygon(cell.polygon,
                fmt::format("class=\"cell view{}\" fill=\"{}\" stroke=\"#ccc\" stroke-width=\"0.3\"", cell.view, fill));
    }
  } else {
    const double half = grid > 0 ? grid / 2 : 0.1;
    for (const CameraEvaluation& e : evaluated) {
      const Point a = e.center - Vector(half, half), b = e.center + Vector(half, half);
      c.Polygon(Polygon{{a, {b.x(), a.y()}, b, {a.x(), b.y()}}},
                fmt::format("class=\"candidate\" fill=\"{}\" stroke=\"#ccc\" stroke-width=\"0.3\"", Colour(e)));
    }
  }
  for (const Obstacle& o : scene.obstacles) c.Polygon(o.shape.polygon, "fill=\"#888\" stroke=\"#444\"");
  c.Polygon(scene.goal.polygon, "fill=\"black\" stroke=\"black\"");
  if (scene.start) c.Polygon(scene.start->polygon, "fill=\"none\" stroke=\"#060\" stroke-width=\"2.5\"");
  const double reach = (max - min).norm() / 4;
  if (scene_camera) DrawCameraMarker(c, *scene_camera, reach, "#1f78b4", "scene camera");
  if (best != nullptr) DrawCameraMarker(c, *best, reach, "#d7191c", "best");
  // Legend (in the room the canvas keeps below the drawing).
  const double y0 = c.height_px() - 36;
  // Two rows: what a camera placed there gives, then what the other marks are.
  const std::vector<std::pair<std::string, std::string>> legend = {
      {"#1a9850", "1 step"},
      {"#a6d96a", "2 steps"},
      {"#fee08b", "3 steps"},
      {"#ab8cc8", "no strategy (darker: one step covers more of the start)"},
      {"#ffffff", "view not evaluated"}};
  const std::vector<std::pair<std::string, std::string>> marks = {{"#888888", "obstacle"},
                                                                  {"#000000", "goal"},
                                                                  {"none\" stroke=\"#060", "start region"},
                                                                  {"#1f78b4", "the scene's camera"},
                                                                  {"#d7191c", "the best candidate"}};
  std::string items;
  double x = 30;
  for (const auto& [colour, text] : legend) {
    items += fmt::format(
        "<rect class=\"legend\" x=\"{:.1f}\" y=\"{:.1f}\" width=\"16\" height=\"12\" fill=\"{}\" "
        "stroke=\"#666\"/>\n",
        x, y0 - 22, colour);
    c.TextPx(x + 22, y0 - 12, text, 11, "class=\"legend\" fill=\"black\"");
    x += 40 + 6.2 * static_cast<double>(text.size());
  }
  x = 30;
  for (const auto& [colour, text] : marks) {
    items += fmt::format(
        "<rect class=\"legend\" x=\"{:.1f}\" y=\"{:.1f}\" width=\"16\" height=\"12\" fill=\"{}\" "
        "stroke-width=\"2\"/>\n",
        x, y0 - 2, colour);
    c.TextPx(x + 22, y0 + 8, text, 11, "class=\"legend\" fill=\"black\"");
    x += 40 + 6.2 * static_cast<double>(text.size());
  }
  std::string svg = c.Finish();
  // The legend sits below the drawing: grow the document and add the swatches.
  const auto close = svg.rfind("</svg>");
  if (close != std::string::npos) svg.insert(close, items);
  return svg;
}

void Run(const Args& a) {
  if (a.threads < 1) throw InputError("command line", "--threads", "must be at least 1");
  if (a.max_candidates < 1) throw InputError("command line", "--max-candidates", "must be at least 1");
  if (a.max_backprojections < 1) throw InputError("command line", "--max-backprojections", "must be at least 1");
  if (a.max_steps < 1) throw InputError("command line", "--max-steps", "must be at least 1");
  if (a.grid < 0 || !std::isfinite(a.grid)) throw InputError("command line", "--grid", "the spacing must be positive");
  const Scene scene = LoadScene(a.scene);
  if (!scene.start) throw InputError(a.scene, "start", "placing a camera needs a start region");
  double fov = a.fov;
  if (fov == 0) {
    // The scene camera's width, rounded off its trip through radians (100.00000000000001 is 100).
    fov = scene.camera
              ? std::round((scene.camera->fov_second_rad - scene.camera->fov_first_rad) * 180 / M_PI * 1e9) / 1e9
              : 100.0;
  }
  if (!(fov > 0 && fov < 180)) throw InputError("command line", "--fov", "must be strictly between 0 and 180 degrees");
  if (a.height < 0 || !std::isfinite(a.height)) throw InputError("command line", "--height", "must be positive");
  // 2.5D: candidates this high see over the prisms lower than them (docs/planning_cspace.md "Heights").
  const std::optional<double> height = a.height > 0   ? std::optional<double>(a.height)
                                       : scene.camera ? scene.camera->height
                                                      : std::nullopt;
  const Point aim = a.aim.empty() ? DefaultAim(scene) : Point(a.aim[0], a.aim[1]);
  if (!std::isfinite(aim.x()) || !std::isfinite(aim.y())) throw InputError("command line", "--aim", "must be finite");
  const Point min = scene.bounds.min, max = scene.bounds.max;
  const Mode mode = a.grid > 0 ? Mode::kGrid : !a.candidates.empty() ? Mode::kFile : Mode::kCells;
  const bool tty = isatty(fileno(stderr)) != 0;
  const auto t0 = std::chrono::steady_clock::now();

  ViewingCells cells;
  std::vector<Point> centers;
  std::vector<int> cell_of;  // per candidate: its cell (cells mode), else -1
  std::map<int, std::size_t> by_view;
  if (mode == Mode::kCells) {
    if (tty) {
      std::fprintf(stderr, "viewing cells ...\r");
      std::fflush(stderr);
    }
    cells = ComputeViewingCells(scene, min, max, height);
    std::fprintf(stderr,
                 "viewing cells: %d event lines, %d faces, %zu cells outside the obstacles, %d views "
                 "(n = %d obstacle vertices, m = %d robot hull vertices, (mn)^2 = %lld)\n",
                 cells.event_lines, cells.faces, cells.cells.size(), cells.views, cells.obstacle_vertices,
                 cells.robot_vertices,
                 static_cast<long long>(cells.obstacle_vertices) * cells.robot_vertices * cells.obstacle_vertices *
                     cells.robot_vertices);
    // One candidate per view, at its largest cell (cells are sorted largest first), the largest views first.
    for (std::size_t i = 0; i < cells.cells.size() && static_cast<int>(centers.size()) < a.max_candidates; ++i) {
      if (by_view.count(cells.cells[i].view) != 0) continue;
      by_view[cells.cells[i].view] = centers.size();
      centers.push_back(cells.cells[i].sample);
      cell_of.push_back(static_cast<int>(i));
    }
  } else {
    // (JSON has no non-finite numbers, and grid points are finite: no check needed.)
    centers = mode == Mode::kGrid ? GridCandidates(scene, min, max, a.grid) : ReadCandidates(a.candidates);
    cell_of.assign(centers.size(), -1);
  }
  if (centers.empty()) throw JobFailed(a.scene + ": no candidate centre lies outside the obstacles");

  CameraSearchOptions options;
  options.max_steps = a.max_steps;
  options.max_backprojections = a.max_backprojections;
  options.threads = a.threads;
  std::string stage;
  options.progress = [&](int done, int total) {
    if (!tty) return;
    std::fprintf(stderr, "\rplanning %s: camera %d of %d", stage.c_str(), done, total);
    std::fflush(stderr);
  };
  // The baselines: without a camera, and the scene's own camera (as the file gives it), with every step allowed.
  std::vector<std::optional<Camera>> baselines = {std::nullopt};
  if (scene.camera) baselines.push_back(scene.camera);
  stage = "the baselines";
  const std::vector<CameraEvaluation> base = EvaluateCameras(scene, baselines, options);
  const CameraEvaluation no_camera = base[0];
  std::optional<CameraEvaluation> scene_camera;
  if (scene.camera) scene_camera = base[1];
  // The candidates with one step allowed, then two, ...: a strategy with fewer steps ranks first whatever the rest,
  // so the search stops at the first step count that some candidate reaches (the best is the one planning each
  // with every step allowed would give; the others are reported as planned at that count).
  std::vector<std::optional<Camera>> cameras;
  for (const Point& p : centers) cameras.push_back(AimedCamera(p, aim, fov, height));
  std::vector<CameraEvaluation> evaluated;
  int searched = 0;
  for (int k = 1; k <= a.max_steps; ++k) {
    options.max_steps = searched = k;
    stage = fmt::format("with up to {} step{}", k, k == 1 ? "" : "s");
    evaluated = EvaluateCameras(scene, cameras, options);
    if (std::any_of(evaluated.begin(), evaluated.end(), [](const CameraEvaluation& e) { return e.feasible; })) break;
  }
  if (tty) std::fprintf(stderr, "\r%60s\r", "");
  for (std::size_t i = 0; i < evaluated.size(); ++i) evaluated[i].cell = cell_of[i];
  std::vector<std::size_t> order(evaluated.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t x, std::size_t y) { return RanksBefore(evaluated[x], evaluated[y]); });
  const CameraEvaluation* best = evaluated[order.front()].feasible ? &evaluated[order.front()] : nullptr;
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  Json j;
  j["scene"] = scene.name;
  j["mode"] = mode == Mode::kCells ? "cells" : mode == Mode::kGrid ? "grid" : "candidates";
  j["region"] = {{"min", PointJson(min)}, {"max", PointJson(max)}};
  j["fov_deg"] = fov;
  j["height"] = height ? Json(*height) : Json(nullptr);
  j["aim"] = PointJson(aim);
  j["max_steps"] = a.max_steps;
  j["steps_searched"] = searched;
  if (mode == Mode::kCells) {
    j["cells"] = {{"event_lines", cells.event_lines},
                  {"faces", cells.faces},
                  {"cells", cells.cells.size()},
                  {"views", cells.views},
                  {"n", cells.obstacle_vertices},
                  {"m", cells.robot_vertices},
                  {"mn_squared", static_cast<long long>(cells.obstacle_vertices) * cells.robot_vertices *
                                     cells.obstacle_vertices * cells.robot_vertices}};
  }
  if (mode == Mode::kGrid) j["grid"] = a.grid;
  j["no_camera"] = EvaluationJson(no_camera, false);
  j["scene_camera"] = scene_camera ? EvaluationJson(*scene_camera, true) : Json(nullptr);
  Json ranked = Json::array();
  for (std::size_t r = 0; r < order.size(); ++r) {
    Json e = {{"rank", r + 1}};
    e.update(EvaluationJson(evaluated[order[r]], true));
    ranked.push_back(std::move(e));
  }
  j["best"] = best != nullptr ? EvaluationJson(*best, true) : Json(nullptr);
  j["candidates"] = std::move(ranked);
  j["seconds"] = std::round(seconds * 100) / 100;
  WriteTextOutput(JsonLines(j, 2, 4, true), a.out);  // a candidate per line
  if (!a.svg.empty()) {
    WriteTextOutput(HeatMapSvg(scene, min, max, mode, cells, evaluated, by_view, a.grid, scene_camera, best), a.svg);
  }

  std::fprintf(stderr, "%zu candidates in %.1f s; without a camera: %s\n", evaluated.size(), seconds,
               Describe(no_camera).c_str());
  if (scene_camera) std::fprintf(stderr, "the scene's camera: %s\n", Describe(*scene_camera).c_str());
  if (best == nullptr) {
    throw JobFailed(
        fmt::format("{}: none of the {} candidate cameras gives a strategy within {} step{} (try "
                    "--max-steps, --fov, --aim or more --max-candidates)",
                    a.scene, evaluated.size(), a.max_steps, a.max_steps == 1 ? "" : "s"));
  }
  std::fprintf(stderr, "best: centre (%.3f, %.3f), field of view [%.1f, %.1f] deg: %s\n", best->center.x(),
               best->center.y(), best->fov_first_deg, best->fov_first_deg + best->fov_span_deg,
               Describe(*best).c_str());
}

}  // namespace

void RegisterCameraCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "camera",
      "Where to put the camera (Fox & Hutchinson section VIII-B, Conjecture 2): plans with each candidate projection "
      "centre as the scene's camera and ranks them: a strategy first, then fewest steps, then the widest narrowest "
      "theta-interval (how far the commanded direction may err), then the largest first preimage. Candidates: by "
      "default one per view of the viewing cells (the faces of the arrangement of the lines across which the "
      "unoccluded vertices or CM vertices change; one evaluation stands for the cell), or a grid (--grid), or a "
      "file (--candidates). Each candidate looks at --aim with a field of view --fov wide. Prints JSON {\"best\", "
      "\"candidates\": [...ranked], \"no_camera\", \"scene_camera\", \"cells\"}; --svg draws a heat map over the "
      "workspace. Exit 1 when no candidate gives a strategy.");
  cmd->add_option("SCENE", args->scene, "scene file (JSON); needs a start region")->required();
  auto* grid = cmd->add_option("--grid", args->grid, "evaluate the grid of this spacing (metres) over the bounds");
  cmd->add_option("--candidates", args->candidates,
                  "evaluate the centres in FILE (JSON: [[x, y], ...] or {\"centers\": [[x, y], ...]})")
      ->excludes(grid);
  cmd->add_option("--fov", args->fov,
                  "width of each candidate's field of view in degrees (default: the scene camera's, else 100)");
  cmd->add_option("--height", args->height,
                  "candidates stand this high above the plane (metres) and see over the obstacles' prisms lower than "
                  "them (2.5D; obstacles need a `height`); default: the scene camera's height, else the planar model");
  cmd->add_option("--aim", args->aim, "where candidates look (default: midway between the start region and the goal)")
      ->expected(2);
  cmd->add_option("--max-steps", args->max_steps, "the most steps a strategy may have")->capture_default_str();
  cmd->add_option("--max-candidates", args->max_candidates,
                  "cells mode: evaluate at most this many views (the largest cells first)")
      ->capture_default_str();
  cmd->add_option("--max-backprojections", args->max_backprojections,
                  "per candidate: stop its search after this many nondirectional backprojections")
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "candidates planned side by side (default: the machine's cores)")
      ->capture_default_str();
  cmd->add_option("--out", args->out, "write the JSON to FILE instead of stdout");
  cmd->add_option("--svg", args->svg, "draw the heat map of the candidates over the workspace into FILE (SVG)");
  cmd->callback([args] { Run(*args); });
}

}  // namespace visco::planning
