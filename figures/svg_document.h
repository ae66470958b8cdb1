// A minimal SVG 1.1 writer for springfit's figures: shapes carry a class, and the figure's
// look is one CSS block, so a figure's colours live in one place and a test can count the
// shapes of a kind (e.g. every `class="missing"` line).
#pragma once

#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "io/xml_text.h"

namespace springfit::figures {

struct Point2 {
  double x = 0.0;
  double y = 0.0;
};

class SvgDocument {
 public:
  SvgDocument(double width, double height);

  void Style(std::string_view css);
  void Line(Point2 a, Point2 b, std::string_view cls);
  void Polyline(const std::vector<Point2>& points, std::string_view cls);
  void Polygon(const std::vector<Point2>& points, std::string_view cls);
  void Circle(Point2 center, double radius, std::string_view cls);
  void Rect(Point2 corner, double width, double height, std::string_view cls);
  enum class Anchor { kStart, kMiddle, kEnd };
  void Text(Point2 at, std::string_view text, std::string_view cls, Anchor anchor = Anchor::kStart);
  // Text turned 90 degrees counter-clockwise about its anchor (a y-axis label).
  void VerticalText(Point2 at, std::string_view text, std::string_view cls);
  // A group of shapes; `tooltip` (may be empty) becomes its <title>.
  void BeginGroup(std::string_view cls, std::string_view tooltip = {});
  // A group whose shapes are clipped to a rectangle (a panel that a wildly deformed model
  // must not spill out of).
  void BeginClippedGroup(Point2 corner, double width, double height);
  void EndGroup();

  std::string str() const;

 private:
  void Open(std::string_view tag, std::string_view cls);
  std::ostringstream body_;
  std::string style_;
  int clip_count_ = 0;
  double width_;
  double height_;
};

using io::XmlEscape;  // (io/xml_text.h)

}  // namespace springfit::figures
