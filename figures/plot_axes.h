// What the line plots share: the colours of their curves, decade labels, logarithmic axes and
// the plot area's frame.
#pragma once
#include <cstddef>
#include <string>

#include "figures/svg_document.h"

namespace springfit::figures {

// The plot area's margins inside the figure (room for tick labels, title and axis names) and
// the height of one legend row, in pixels: the same on every line plot.
inline constexpr double kPlotLeft = 78.0, kPlotRight = 24.0, kPlotTop = 48.0, kPlotBottom = 56.0;
inline constexpr double kLegendRow = 18.0;

// The CSS of a plot with `curves` curves: text, grid and frame, and per curve i the classes
// `curve<i>` (its line) and `exact<i>` (a filled marker in its colour).
std::string PlotCss(std::size_t curves);

// "1", "10", "1e-3": the label of 10^exponent.
std::string DecadeLabel(int exponent);

// Whole decades [10^lo, 10^hi] covering a range of positive values.
struct LogAxis {
  int lo = 0, hi = 1;
  double Fraction(double v) const;  // 0 at 10^lo, 1 at 10^hi
  static LogAxis Over(double lo, double hi);
};

// The plot area's frame (plot_w x plot_h at the margins) and the axes' names: `x_label` below
// it, `y_label` up its left side. After the grid, so that the frame is drawn over it.
void DrawPlotFrame(SvgDocument& svg, double plot_w, double plot_h, const std::string& x_label,
                   const std::string& y_label);

}  // namespace springfit::figures
