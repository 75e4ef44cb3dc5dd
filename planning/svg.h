#pragma once
// A small SVG canvas in world coordinates (metres, y up), for the planner's pictures (`visco vcrays --svg`,
// `visco backproject --svg`). World y is flipped to SVG's y down; sizes given in pixels stay pixels. Several canvases
// can be composed side by side into one document (SideBySide), each keeping its own world-to-pixel map.

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

  /// One entry of a legend: a glyph drawn in `colour` (e.g. "■" for a fill, "━" for a line, "╍" for a dashed one),
  /// then what it means in words.
  struct LegendItem {
    std::string glyph;
    std::string colour;
    std::string text;
  };
  /// A legend below the drawing: rows of items, left to right (class "legend"); the document grows for more than
  /// three rows. Call it last.
  void Legend(const std::vector<std::vector<LegendItem>>& rows);

  /// The document.
  std::string Finish() const;
  /// The drawing without the document around it (SVG elements in this canvas's pixel frame).
  const std::string& body() const { return body_; }
  /// Writes the document. @throws visco::InputError(path, "", ...) if the file cannot be written.
  void Write(const std::string& path) const;

  double x(const Point& p) const;
  double y(const Point& p) const;
  double width_px() const { return width_; }
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

/// A canvas placed in a composed document: its drawing goes into `<g id="ID" transform="translate(X,0)">`.
struct SvgPanel {
  std::string id;  ///< an XML id (letters, digits, '-', '_')
  const SvgCanvas* canvas = nullptr;
};

/// One document with the panels' canvases left to right, `gap_px` apart, top-aligned; the document is as wide as
/// all of them and the gaps, and as high as the highest.
std::string SideBySide(const std::vector<SvgPanel>& panels, double gap_px = 20);

/// Escapes &, <, > and quotes for SVG text.
std::string SvgEscape(const std::string& text);

}  // namespace visco::planning
