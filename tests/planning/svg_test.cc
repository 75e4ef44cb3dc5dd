#include "planning/svg.h"

#include <gtest/gtest.h>

#include <string>

namespace visco::planning {
namespace {

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(SvgCanvas, SideBySidePlacesEachCanvasInItsOwnGroup) {
  SvgCanvas left({0, 0}, {10, 5}, 200);  // 200 px + 2 * 30 px margin wide
  SvgCanvas right({0, 0}, {10, 10}, 100);
  left.Line({0, 0}, {10, 5}, "stroke=\"black\"");
  right.Circle({5, 5}, 3, "fill=\"red\"");
  right.TextPx(0, 10, "a < b & c", 12, "");
  // The same world point maps to each canvas's own pixel frame.
  EXPECT_DOUBLE_EQ(left.x({10, 0}), 230);
  EXPECT_DOUBLE_EQ(right.x({10, 0}), 130);
  const std::string doc = SideBySide({{"classic", &left}, {"vc", &right}}, 20);
  EXPECT_EQ(Count(doc, "<svg "), 1);
  EXPECT_EQ(Count(doc, "</svg>"), 1);
  EXPECT_NE(doc.find("<g id=\"classic\" transform=\"translate(0.00,0)\">"), std::string::npos);
  EXPECT_NE(doc.find("<g id=\"vc\" transform=\"translate(280.00,0)\">"), std::string::npos);  // 260 + 20
  EXPECT_EQ(Count(doc, "</g>"), 2);
  // Width: both canvases and the gap; height: the higher one (100 px of world, 2 margins, the legend room).
  EXPECT_NE(doc.find("width=\"440\" height=\"220\""), std::string::npos) << doc.substr(0, 200);
  EXPECT_LT(doc.find("<line"), doc.find("<g id=\"vc\""));
  EXPECT_GT(doc.find("<circle"), doc.find("<g id=\"vc\""));
  EXPECT_NE(doc.find("a &lt; b &amp; c"), std::string::npos);
  // A single canvas's document is unchanged by the composition code.
  EXPECT_EQ(Count(left.Finish(), "<g "), 0);
  EXPECT_NE(left.Finish().find(left.body()), std::string::npos);
}

}  // namespace
}  // namespace visco::planning
