#include "planning/svg.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>

#include "common/error.h"

namespace visco::planning {

SvgCanvas::SvgCanvas(const Point& min, const Point& max, double width_px) : min_(min) {
  const Point span = (max - min).cwiseMax(Point(1e-9, 1e-9));
  scale_ = width_px / span.x();
  width_ = width_px + 2 * margin_;
  height_ = span.y() * scale_ + 2 * margin_ + 60;  // room for a legend below
  max_y_ = max.y();
}

double SvgCanvas::x(const Point& p) const { return margin_ + (p.x() - min_.x()) * scale_; }
double SvgCanvas::y(const Point& p) const { return margin_ + (max_y_ - p.y()) * scale_; }

namespace {
std::string PathOf(const SvgCanvas& c, const Polygon& polygon) {
  std::string d;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    d += fmt::format("{}{:.2f},{:.2f} ", i == 0 ? "M" : "L", c.x(polygon[i]), c.y(polygon[i]));
  }
  return d + "Z ";
}
}  // namespace

void SvgCanvas::Polygon(const planning::Polygon& polygon, const std::string& style) {
  body_ += fmt::format("<path d=\"{}\" {}/>\n", PathOf(*this, polygon), style);
}

void SvgCanvas::PolygonWithHoles(const planning::PolygonWithHoles& region, const std::string& style) {
  std::string d = PathOf(*this, region.outer);
  for (const planning::Polygon& h : region.holes) d += PathOf(*this, h);
  body_ += fmt::format("<path fill-rule=\"evenodd\" d=\"{}\" {}/>\n", d, style);
}

void SvgCanvas::Line(const Point& a, const Point& b, const std::string& style) {
  body_ += fmt::format("<line x1=\"{:.2f}\" y1=\"{:.2f}\" x2=\"{:.2f}\" y2=\"{:.2f}\" {}/>\n", x(a), y(a), x(b), y(b),
                       style);
}

void SvgCanvas::Circle(const Point& center, double radius_px, const std::string& style) {
  body_ +=
      fmt::format("<circle cx=\"{:.2f}\" cy=\"{:.2f}\" r=\"{:.2f}\" {}/>\n", x(center), y(center), radius_px, style);
}

void SvgCanvas::Cross(const Point& center, double size_px, const std::string& style) {
  const double cx = x(center), cy = y(center), s = size_px / 2;
  body_ += fmt::format("<path d=\"M{:.2f},{:.2f} L{:.2f},{:.2f} M{:.2f},{:.2f} L{:.2f},{:.2f}\" {}/>\n", cx - s, cy - s,
                       cx + s, cy + s, cx - s, cy + s, cx + s, cy - s, style);
}

void SvgCanvas::Text(const Point& at, const std::string& text, double size_px, const std::string& style, double dx,
                     double dy) {
  TextPx(x(at) + dx, y(at) + dy, text, size_px, style);
}

void SvgCanvas::TextPx(double x_px, double y_px, const std::string& text, double size_px, const std::string& style) {
  body_ += fmt::format("<text x=\"{:.2f}\" y=\"{:.2f}\" font-family=\"sans-serif\" font-size=\"{:.1f}\" {}>{}</text>\n",
                       x_px, y_px, size_px, style, SvgEscape(text));
}

void SvgCanvas::Legend(const std::vector<std::vector<LegendItem>>& rows) {
  const double line = 17;
  // The canvas keeps 60 px below the drawing; more rows make the document taller.
  height_ += std::max(0.0, line * static_cast<double>(rows.size()) + 10 - 60);
  double y = height_ - 8 - line * static_cast<double>(rows.size() - 1);
  for (const auto& row : rows) {
    double x = 12;
    for (const LegendItem& item : row) {
      TextPx(x, y, item.glyph, 13, fmt::format("class=\"legend\" fill=\"{}\"", item.colour));
      x += 8.5 * static_cast<double>(item.glyph.size() / 3 + 1) + 4;  // the glyphs are 3-byte UTF-8 characters
      TextPx(x, y, item.text, 11, "class=\"legend\" fill=\"black\"");
      x += 6.0 * static_cast<double>(item.text.size()) + 16;
    }
    y += line;
  }
}

namespace {
std::string Document(double width, double height, const std::string& body) {
  return fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{:.0f}\" "
      "height=\"{:.0f}\" viewBox=\"0 0 {:.0f} {:.0f}\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n{}"
      "</svg>\n",
      width, height, width, height, body);
}
}  // namespace

std::string SvgCanvas::Finish() const { return Document(width_, height_, body_); }

std::string SideBySide(const std::vector<SvgPanel>& panels, double gap_px) {
  std::string body;
  double x = 0, height = 0;
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const SvgCanvas& c = *panels[i].canvas;
    if (i > 0) x += gap_px;
    body +=
        fmt::format("<g id=\"{}\" transform=\"translate({:.2f},0)\">\n{}</g>\n", SvgEscape(panels[i].id), x, c.body());
    x += c.width_px();
    height = std::max(height, c.height_px());
  }
  return Document(x, height, body);
}

void SvgCanvas::Write(const std::string& path) const {
  std::ofstream out(path);
  out << Finish();
  if (!out) throw InputError(path, "", "cannot write the SVG file");
}

std::string SvgEscape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace visco::planning
