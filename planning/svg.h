#pragma once
// A small SVG canvas in world coordinates (metres, y up), for the planner's pictures (`visco vcrays --svg`, and
// whoever draws regions next). World y is flipped to SVG's y down; sizes given in pixels stay pixels.

#include <string>
#include <vector>

#include "planning/geometry.h"

namespace visco::planning {

class SvgCanvas {
 public:
  /// A canvas showing the world rectangle [min, max] about `width_px` pixels wide (plus a margin).
  SvgCanvas(const Point& min, const Point& max, double width_px = 900);

  /// Style strings are SVG presentation attributes, e.g. `fill="#ccc" stroke="black" stroke-width="1"`.
  void Polygon(const planning::Polygon& polygon, const std::string& style);
  void PolygonWithHoles(const planning::PolygonWithHoles& region, const std::string& style);
  void Line(const Point& a, const Point& b, const std::string& style);
  void Circle(const Point& center, double radius_px, const std::string& style);
  void Cross(const Point& center, double size_px, const std::string& style);
  /// Text at a world point, offset by (dx, dy) pixels (dy down).
  void Text(const Point& at, const std::string& text, double size_px, const std::string& style, double dx = 0,
            double dy = 0);
  /// Text at a fixed pixel position (for legends).
  void TextPx(double x_px, double y_px, const std::string& text, double size_px, const std::string& style);

  /// The document.
  std::string Finish() const;
  /// Writes the document. @throws visco::InputError(path, "", ...) if the file cannot be written.
  void Write(const std::string& path) const;

  double x(const Point& p) const;
  double y(const Point& p) const;
  double height_px() const { return height_; }

 private:
  Point min_;
  double scale_;
  double margin_ = 30;
  double width_;
  double height_;
  double max_y_;
  std::string body_;
};

/// Escapes &, <, > and quotes for SVG text.
std::string SvgEscape(const std::string& text);

}  // namespace visco::planning
