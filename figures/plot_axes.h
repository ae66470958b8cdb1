// What the line plots share: the colours of their curves, decade labels and logarithmic axes.
#pragma once
#include <cstddef>
#include <string>

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

}  // namespace springfit::figures
