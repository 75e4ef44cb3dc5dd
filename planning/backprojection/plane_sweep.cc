// The plane sweep's event loop (Donald–Canny): static events (the overlay's vertices, overlay.cc) and dynamic ones
// (where a free edge meets another curve) in (y, x) order, each processed by the local rule (local_rule.cc); and the
// entry points that run one sweep.

#include "planning/backprojection/plane_sweep.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace visco::planning::internal {

int Sweep::AddName(std::string name) {
  names_.push_back(std::move(name));
  return static_cast<int>(names_.size()) - 1;
}

int Sweep::VertexName(const P2& p, const std::vector<Curve*>& through) {
  auto it = vertex_names_.find(p);
  if (it != vertex_names_.end()) return it->second;
  std::vector<std::string> parts;
  for (const Curve* c : through) parts.push_back(names_[c->name]);
  // Every static segment through p, whatever the sweep holds there: where segments coincide (a goal strip and the
  // forbidden strip abutting it share an edge) the curves through p depend on θ, and so did the name, a change of
  // structure where nothing changed (found by
  // NondirectionalProperty.StructureIsConstantWithStripGoalsAndForbiddenStrips).
  for (const Source& src : sources_) {
    if (src.name >= 0 && src.kind != EdgeKind::kFree && Seg(src.a, src.b).has_on(p)) parts.push_back(names_[src.name]);
  }
  std::sort(parts.begin(), parts.end());
  parts.erase(std::unique(parts.begin(), parts.end()), parts.end());
  std::string s = "x(";
  for (size_t i = 0; i < parts.size(); ++i) s += (i ? "," : "") + parts[i];
  s += ")";
  const int id = AddName(s);
  vertex_names_.emplace(p, id);
  return id;
}

void Sweep::Run() {
  size_t si = 0;
  const std::vector<StaticCurve> none;
  while (si < static_events_.size() || !dynamic_.empty()) {
    bool from_static;
    if (si >= static_events_.size()) {
      from_static = false;
    } else if (dynamic_.empty()) {
      from_static = true;
    } else {
      from_static = CompareYX(static_events_[si].first, dynamic_.top()) != CGAL::LARGER;
    }
    const P2 p = from_static ? static_events_[si].first : dynamic_.top();
    while (!dynamic_.empty() && Same(dynamic_.top(), p)) dynamic_.pop();
    if (from_static) {
      Process(p, static_events_[si].second);
      ++si;
    } else {
      Process(p, none);
    }
  }
}

void Sweep::CheckIntersection(const Curve* a, const Curve* b, const P2& p) {
  if (!a || !b) return;
  if (a->kind != EdgeKind::kFree && b->kind != EdgeKind::kFree) return;
  const auto res = CGAL::intersection(Seg(a->lo, a->hi), Seg(b->lo, b->hi));
  if (!res) return;
  if (const P2* q = boost::get<P2>(&*res)) {
    if (CGAL::compare_yx(*q, p) == CGAL::LARGER) dynamic_.push(*q);
  } else if (const Seg* s = boost::get<Seg>(&*res)) {
    const P2 low = CGAL::compare_yx(s->source(), s->target()) == CGAL::SMALLER ? s->source() : s->target();
    if (CGAL::compare_yx(low, p) == CGAL::LARGER) dynamic_.push(low);
  }
}

std::vector<RegionEdge> Sweep::StaticEdges() const {
  std::vector<RegionEdge> out;
  for (const Source& src : sources_) {
    if (src.kind == EdgeKind::kVc) continue;
    // As ToRegion labels them.
    out.push_back({src.kind, names_[src.name], Vector2d::Zero(), WorldLine(src), 0});
  }
  return out;
}
SweepResult RunSweep(const BackprojectionProblem& problem, const std::vector<int>& active, SweepFrame& frame) {
  Sweep sweep(problem, active, frame);
  sweep.Run();
  SweepResult r;
  r.rings = sweep.Assemble();
  r.region = sweep.ToRegion(r.rings);
  r.bad_track_rays = sweep.bad_track_rays();
  return r;
}

}  // namespace visco::planning::internal

namespace visco::planning {

using internal::RunSweep;
using internal::Sweep;
using internal::SweepFrame;

Region ClassicBackprojection(const BackprojectionProblem& problem) {
  SweepFrame frame(problem.theta);
  return RunSweep(problem, {}, frame).region;
}

Region BackprojectionWithActiveRays(const BackprojectionProblem& problem, const std::vector<std::string>& active) {
  std::vector<int> idx;
  for (const auto& id : active) {
    auto it = std::find_if(problem.rays.begin(), problem.rays.end(), [&](const CvcRayInput& r) { return r.id == id; });
    if (it == problem.rays.end()) throw std::invalid_argument("backprojection: unknown CVC ray '" + id + "'");
    idx.push_back(static_cast<int>(it - problem.rays.begin()));
  }
  SweepFrame frame(problem.theta);
  return RunSweep(problem, idx, frame).region;
}

std::vector<RegionEdge> StaticRegionEdges(const BackprojectionProblem& problem) {
  SweepFrame frame(problem.theta);
  return Sweep(problem, {}, frame).StaticEdges();
}

}  // namespace visco::planning
