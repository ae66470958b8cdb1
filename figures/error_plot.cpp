#include "figures/error_plot.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>

#include "figures/plot_axes.h"
#include "figures/svg_document.h"

namespace springfit::figures {

namespace {

// Curve i as steps (the best error holds until the next improvement), a dot where it ends
// exact.
template <typename X, typename Y>
void DrawErrorCurve(SvgDocument& svg, const ErrorCurve& c, std::size_t i, X px, Y py) {
  if (c.points.empty()) return;
  std::vector<Point2> line;
  for (const auto& [t, e] : c.points) {
    const Point2 p{px(t), py(e)};
    if (!line.empty()) line.push_back({p.x, line.back().y});
    line.push_back(p);
  }
  const std::string cls = std::to_string(i);
  svg.Polyline(line, "curve" + cls);
  if (c.points.back().second <= 0.0) svg.Circle(line.back(), 4.5, "exact" + cls);
}

// One row per curve, from `top` down: its name and where it ended.
void DrawErrorLegend(SvgDocument& svg, const std::vector<ErrorCurve>& curves, double top) {
  for (std::size_t i = 0; i < curves.size(); ++i) {
    const double y = top + kLegendRow * static_cast<double>(i);
    svg.Line({kPlotLeft, y - 4}, {kPlotLeft + 26, y - 4}, "curve" + std::to_string(i));
    std::string label = curves[i].label;
    if (!curves[i].points.empty()) {
      const auto& [t, e] = curves[i].points.back();
      label += e <= 0.0 ? fmt::format("  (exact at {:.3g} s)", t)
                        : fmt::format("  (error {:.3g} at {:.3g} s)", e, t);
    }
    svg.Text({kPlotLeft + 32, y}, label, "");
  }
}

}  // namespace

std::string RenderErrorPlot(const std::vector<ErrorCurve>& curves, const std::string& title,
                            const ErrorPlotOptions& options) {
  // The axes' ranges: every positive time and error. A time of 0 (a trace's very first row
  // can be stamped before the clock moved) and an error of 0 (exact) sit on the axes' floors.
  double t_lo = std::numeric_limits<double>::infinity(), t_hi = 0.0;
  double e_lo = std::numeric_limits<double>::infinity(), e_hi = 0.0;
  bool any = false;
  for (const ErrorCurve& c : curves) {
    for (const auto& [t, e] : c.points) {
      any = true;
      if (t > 0.0) t_lo = std::min(t_lo, t), t_hi = std::max(t_hi, t);
      if (e > 0.0) e_lo = std::min(e_lo, e), e_hi = std::max(e_hi, e);
    }
  }
  if (!any) throw std::invalid_argument("nothing to plot: no trace rows");
  if (!(t_hi > 0.0)) t_lo = 1e-3, t_hi = 1.0;
  if (!(e_hi > 0.0)) e_lo = 1e-12, e_hi = 1.0;
  const LogAxis x_axis = LogAxis::Over(t_lo, t_hi);
  // One decade of room below the smallest error for exact recoveries.
  LogAxis y_axis = LogAxis::Over(e_lo, e_hi);
  y_axis.lo -= 1;

  const double legend_height = kLegendRow * static_cast<double>(curves.size()) + 10;
  const double plot_w = options.width - kPlotLeft - kPlotRight;
  const double plot_h = options.height - kPlotTop - kPlotBottom;
  auto px = [&](double t) {
    return kPlotLeft +
           plot_w * std::clamp(x_axis.Fraction(std::max(t, std::pow(10.0, x_axis.lo))), 0.0, 1.0);
  };
  auto py = [&](double e) {
    const double floor = std::pow(10.0, y_axis.lo);
    return kPlotTop + plot_h * (1.0 - std::clamp(y_axis.Fraction(std::max(e, floor)), 0.0, 1.0));
  };

  SvgDocument svg(options.width, options.height + legend_height);
  svg.Style(PlotCss(curves.size()));
  svg.Text({kPlotLeft, 26}, title, "title");

  for (int d = x_axis.lo; d <= x_axis.hi; ++d) {
    const double x = px(std::pow(10.0, d));
    svg.Line({x, kPlotTop}, {x, kPlotTop + plot_h}, "grid");
    svg.Text({x, kPlotTop + plot_h + 18}, DecadeLabel(d), "", SvgDocument::Anchor::kMiddle);
  }
  for (int d = y_axis.lo; d <= y_axis.hi; ++d) {
    const double y = py(std::pow(10.0, d));
    svg.Line({kPlotLeft, y}, {kPlotLeft + plot_w, y}, "grid");
    svg.Text({kPlotLeft - 8, y + 4}, d == y_axis.lo ? "exact" : DecadeLabel(d), "",
             SvgDocument::Anchor::kEnd);
  }
  DrawPlotFrame(svg, plot_w, plot_h, options.x_label, "best E (relative RMS nodal error)");
  for (std::size_t i = 0; i < curves.size(); ++i) DrawErrorCurve(svg, curves[i], i, px, py);
  DrawErrorLegend(svg, curves, options.height);
  return svg.str();
}

}  // namespace springfit::figures
