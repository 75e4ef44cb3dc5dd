// The structure of a region and its difference from another (region_structure.h).

#include "planning/nondirectional/region_structure.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "planning/nondirectional.h"
#include "planning/nondirectional/ring_geometry.h"

namespace visco::planning::internal {

std::vector<std::string> RingSequence(const RegionRing& ring, const char* tag) {
  const size_t n = ring.edges.size();
  std::vector<std::string> items;
  items.reserve(n);
  for (const auto& e : ring.edges) items.push_back(std::string(EdgeKindName(e.kind)) + ":" + e.ref);
  // The lexicographically least rotation names the cyclic sequence. Rotations are compared in place on the items'
  // ranks (the same order as the strings), without building them: a ring of a thousand edges costs about n
  // comparisons instead of n² string copies.
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return items[a] < items[b]; });
  std::vector<size_t> rank(n);
  for (size_t i = 0, r = 0; i < n; ++i) {
    if (i > 0 && items[order[i]] != items[order[i - 1]]) ++r;
    rank[order[i]] = r;
  }
  size_t best = 0;
  for (size_t r = 1; r < n; ++r) {
    for (size_t i = 0; i < n; ++i) {
      const size_t x = rank[(r + i) % n], y = rank[(best + i) % n];
      if (x != y) {
        if (x < y) best = r;
        break;
      }
    }
  }
  std::vector<std::string> out = {tag};
  out.reserve(n + 1);
  for (size_t i = 0; i < n; ++i) out.push_back(std::move(items[(best + i) % n]));
  return out;
}

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) {
    if (!s.empty()) s += ' ';
    s += x;
  }
  return s;
}

std::optional<RingEdit> SmallestEdit(const RegionRing& b, const RegionRing& a) {
  const size_t nb = b.edges.size(), na = a.edges.size();
  if (nb == 0 || na == 0) return std::nullopt;
  std::optional<RingEdit> best;
  for (const size_t i : {size_t{0}, nb / 3, 2 * nb / 3}) {
    for (size_t j = 0; j < na; ++j) {
      if (!SameEdge(b.edges[i], a.edges[j])) continue;
      const size_t most = std::min(nb, na);
      size_t p = 0, q = 0;
      while (p < most && SameEdge(b.edges[(i + p) % nb], a.edges[(j + p) % na])) ++p;
      while (q + p < most && SameEdge(b.edges[(i + nb - 1 - q) % nb], a.edges[(j + na - 1 - q) % na])) ++q;
      RingEdit e{&b, &a, (i + p) % nb, nb - p - q, (j + p) % na, na - p - q};
      if (!best || e.b_count + e.a_count < best->b_count + best->a_count) best = e;
    }
  }
  return best;
}

std::optional<RingEdit> OneRingChanged(const Region& before, const Region& after,
                                       const std::vector<std::string>& s_before,
                                       const std::vector<std::string>& s_after) {
  std::vector<std::string> only_b, only_a;
  std::set_difference(s_before.begin(), s_before.end(), s_after.begin(), s_after.end(), std::back_inserter(only_b));
  std::set_difference(s_after.begin(), s_after.end(), s_before.begin(), s_before.end(), std::back_inserter(only_a));
  if (only_b.size() != 1 || only_a.size() != 1) return std::nullopt;
  std::vector<std::pair<std::string, const RegionRing*>> rb, ra;
  auto rings = [](const Region& r, std::vector<std::pair<std::string, const RegionRing*>>& out) {
    ForEachRing(r, [&](const RegionRing& ring) { out.push_back({Join(RingSequence(ring, "ring")), &ring}); });
    std::sort(out.begin(), out.end());
  };
  rings(before, rb);
  rings(after, ra);
  std::vector<const RegionRing*> changed_b, changed_a;
  auto differ = [](const auto& x, const auto& y, std::vector<const RegionRing*>& out) {
    size_t j = 0;
    for (const auto& [key, ring] : x) {
      while (j < y.size() && y[j].first < key) ++j;
      if (j < y.size() && y[j].first == key) {
        ++j;
      } else {
        out.push_back(ring);
      }
    }
  };
  differ(rb, ra, changed_b);
  differ(ra, rb, changed_a);
  if (changed_b.size() != 1 || changed_a.size() != 1) return std::nullopt;
  return SmallestEdit(*changed_b[0], *changed_a[0]);
}

}  // namespace visco::planning::internal

namespace visco::planning {

using internal::Join;
using internal::RingSequence;

std::vector<std::string> RegionStructure(const Region& region) {
  std::vector<std::string> polys;
  for (const auto& poly : region.polygons) {
    std::string s = Join(RingSequence(poly.outer, "outer"));
    std::vector<std::string> holes;
    for (const auto& h : poly.holes) holes.push_back(Join(RingSequence(h, "hole")));
    std::sort(holes.begin(), holes.end());
    for (const auto& h : holes) s += " | " + h;
    polys.push_back(std::move(s));
  }
  std::sort(polys.begin(), polys.end());
  return polys;
}

}  // namespace visco::planning
