#include "figures/svg_document.h"

#include <fmt/format.h>

namespace springfit::figures {
namespace {

// Two decimals: a hundredth of a pixel is below any viewer's resolution, and it keeps files
// of a few thousand springs small.
std::string Num(double v) {
  return fmt::format("{:.2f}", v);
}

std::string Points(const std::vector<Point2>& points) {
  std::string out;
  for (const Point2& p : points) {
    if (!out.empty()) out += ' ';
    out += Num(p.x) + ',' + Num(p.y);
  }
  return out;
}

}  // namespace

SvgDocument::SvgDocument(double width, double height) : width_(width), height_(height) {}

void SvgDocument::Style(std::string_view css) {
  style_ += css;
}

void SvgDocument::Open(std::string_view tag, std::string_view cls) {
  body_ << '<' << tag;
  if (!cls.empty()) body_ << " class=\"" << XmlEscape(cls) << '"';
}

void SvgDocument::Line(Point2 a, Point2 b, std::string_view cls) {
  Open("line", cls);
  body_ << " x1=\"" << Num(a.x) << "\" y1=\"" << Num(a.y) << "\" x2=\"" << Num(b.x) << "\" y2=\""
        << Num(b.y) << "\"/>\n";
}

void SvgDocument::Polyline(const std::vector<Point2>& points, std::string_view cls) {
  Open("polyline", cls);
  body_ << " points=\"" << Points(points) << "\"/>\n";
}

void SvgDocument::Polygon(const std::vector<Point2>& points, std::string_view cls) {
  Open("polygon", cls);
  body_ << " points=\"" << Points(points) << "\"/>\n";
}

void SvgDocument::Circle(Point2 center, double radius, std::string_view cls) {
  Open("circle", cls);
  body_ << " cx=\"" << Num(center.x) << "\" cy=\"" << Num(center.y) << "\" r=\"" << Num(radius)
        << "\"/>\n";
}

void SvgDocument::Rect(Point2 corner, double width, double height, std::string_view cls) {
  Open("rect", cls);
  body_ << " x=\"" << Num(corner.x) << "\" y=\"" << Num(corner.y) << "\" width=\"" << Num(width)
        << "\" height=\"" << Num(height) << "\"/>\n";
}

void SvgDocument::Text(Point2 at, std::string_view text, std::string_view cls, Anchor anchor) {
  Open("text", cls);
  body_ << " x=\"" << Num(at.x) << "\" y=\"" << Num(at.y) << '"';
  if (anchor == Anchor::kMiddle) body_ << " text-anchor=\"middle\"";
  if (anchor == Anchor::kEnd) body_ << " text-anchor=\"end\"";
  body_ << '>' << XmlEscape(text) << "</text>\n";
}

void SvgDocument::VerticalText(Point2 at, std::string_view text, std::string_view cls) {
  Open("text", cls);
  body_ << " x=\"" << Num(at.x) << "\" y=\"" << Num(at.y)
        << "\" text-anchor=\"middle\" transform=\"rotate(-90 " << Num(at.x) << ' ' << Num(at.y)
        << ")\">" << XmlEscape(text) << "</text>\n";
}

void SvgDocument::BeginGroup(std::string_view cls, std::string_view tooltip) {
  Open("g", cls);
  body_ << ">\n";
  if (!tooltip.empty()) body_ << "<title>" << XmlEscape(tooltip) << "</title>\n";
}

void SvgDocument::BeginClippedGroup(Point2 corner, double width, double height) {
  const std::string id = "clip" + std::to_string(++clip_count_);
  body_ << "<clipPath id=\"" << id << "\"><rect x=\"" << Num(corner.x) << "\" y=\"" << Num(corner.y)
        << "\" width=\"" << Num(width) << "\" height=\"" << Num(height) << "\"/></clipPath>\n"
        << "<g clip-path=\"url(#" << id << ")\">\n";
}

void SvgDocument::EndGroup() {
  body_ << "</g>\n";
}

std::string SvgDocument::str() const {
  std::ostringstream out;
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      << "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"" << Num(width_)
      << "\" height=\"" << Num(height_) << "\" viewBox=\"0 0 " << Num(width_) << ' ' << Num(height_)
      << "\">\n";
  if (!style_.empty()) out << "<style>\n" << style_ << "</style>\n";
  out << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n" << body_.str() << "</svg>\n";
  return out.str();
}

}  // namespace springfit::figures
