#include "figures/tradeoff_plot.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>

#include "figures/plot_axes.h"
#include "figures/svg_document.h"

namespace springfit::figures {
namespace {

bool Drawable(double e) {
  return std::isfinite(e) && e > 0.0;
}

// A round step for a linear axis of `span` with about `ticks` ticks: 1, 2 or 5 times 10^k.
double NiceStep(double span, int ticks) {
  const double raw = span / ticks;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * power >= raw) return m * power;
  }
  return 10.0 * power;
}

// The springs and E that the curves span: their drawable points, returned models and baselines.
struct TradeoffSpan {
  double s_lo = std::numeric_limits<double>::infinity(), s_hi = 0.0;
  double e_lo = std::numeric_limits<double>::infinity(), e_hi = 0.0;

  void AddSprings(double springs) {
    s_lo = std::min(s_lo, springs);
    s_hi = std::max(s_hi, springs);
  }
  void AddError(double e) {
    e_lo = std::min(e_lo, e);
    e_hi = std::max(e_hi, e);
  }
  static TradeoffSpan Of(const std::vector<TradeoffCurve>& curves) {
    TradeoffSpan span;
    for (const TradeoffCurve& c : curves) {
      for (const auto& [springs, e] : c.points) {
        if (!Drawable(e)) continue;
        span.AddSprings(static_cast<double>(springs));
        span.AddError(e);
      }
      if (c.returned && Drawable(c.returned->second)) {
        span.AddSprings(static_cast<double>(c.returned->first));
        span.AddError(c.returned->second);
      }
      if (c.baseline_error && Drawable(*c.baseline_error)) {
        span.AddError(*c.baseline_error);
        if (c.baseline_springs) span.AddSprings(static_cast<double>(*c.baseline_springs));
      }
    }
    return span;
  }
};

// The plot's frame: its axes, and where a (springs, E) point is drawn.
struct TradeoffFrame {
  double step = 1.0, x_lo = 0.0, x_hi = 1.0;  // the springs axis, linear
  LogAxis y_axis;                             // E, log
  double plot_w = 0.0, plot_h = 0.0;

  TradeoffFrame(const TradeoffSpan& span, const TradeoffPlotOptions& options)
      : step(NiceStep(std::max(span.s_hi - span.s_lo, 1.0), 6)),
        x_lo(std::floor(span.s_lo / step) * step),
        x_hi(std::ceil(span.s_hi / step) * step + (span.s_hi == span.s_lo ? step : 0.0)),
        y_axis(LogAxis::Over(span.e_lo, span.e_hi)),
        plot_w(options.width - kPlotLeft - kPlotRight),
        plot_h(options.height - kPlotTop - kPlotBottom) {}
  double X(double springs) const { return kPlotLeft + plot_w * (springs - x_lo) / (x_hi - x_lo); }
  double Y(double e) const {
    return kPlotTop + plot_h * (1.0 - std::clamp(y_axis.Fraction(e), 0.0, 1.0));
  }
};

void DrawAxes(SvgDocument& svg, const TradeoffFrame& f, const std::string& title) {
  svg.Text({kPlotLeft, 26}, title, "title");
  for (double s = f.x_lo; s <= f.x_hi + 0.5 * f.step; s += f.step) {
    const double x = f.X(s);
    svg.Line({x, kPlotTop}, {x, kPlotTop + f.plot_h}, "grid");
    svg.Text({x, kPlotTop + f.plot_h + 18}, fmt::format("{:.0f}", s), "",
             SvgDocument::Anchor::kMiddle);
  }
  for (int d = f.y_axis.lo; d <= f.y_axis.hi; ++d) {
    const double y = f.Y(std::pow(10.0, d));
    svg.Line({kPlotLeft, y}, {kPlotLeft + f.plot_w, y}, "grid");
    svg.Text({kPlotLeft - 8, y + 4}, DecadeLabel(d), "", SvgDocument::Anchor::kEnd);
  }
  DrawPlotFrame(svg, f.plot_w, f.plot_h, "springs", "E (relative RMS nodal error)");
}

// Curve i: its path, the point refitted from (a large dot), the returned model (a square) and
// its baseline (a line across, and a dot at its springs).
void DrawCurve(SvgDocument& svg, const TradeoffFrame& f, const TradeoffCurve& c, std::size_t i) {
  const std::string cls = std::to_string(i);
  std::vector<Point2> line;
  for (const auto& [springs, e] : c.points) {
    if (Drawable(e)) line.push_back({f.X(springs), f.Y(e)});
  }
  if (!line.empty()) svg.Polyline(line, "curve" + cls);
  for (const Point2& p : line) svg.Circle(p, 2.5, "exact" + cls);
  if (c.chosen && *c.chosen < c.points.size() && Drawable(c.points[*c.chosen].second)) {
    const auto& [springs, e] = c.points[*c.chosen];
    svg.Circle({f.X(springs), f.Y(e)}, 6.0, "exact" + cls);
  }
  if (c.returned && Drawable(c.returned->second)) {
    // A square: the model the result returns, where the user reads its springs and E.
    const Point2 p{f.X(c.returned->first), f.Y(c.returned->second)};
    svg.Rect({p.x - 5.0, p.y - 5.0}, 10.0, 10.0, "curve" + cls);
  }
  if (c.baseline_error && Drawable(*c.baseline_error)) {
    const double y = f.Y(*c.baseline_error);
    svg.Line({kPlotLeft, y}, {kPlotLeft + f.plot_w, y}, "reference");
    if (c.baseline_springs) svg.Circle({f.X(*c.baseline_springs), y}, 4.0, "exact" + cls);
  }
}

// Two rows per curve (its name; the returned model and the point it was refitted from), then
// one for the baseline when some curve has one, from `top` down.
void DrawLegend(SvgDocument& svg, const std::vector<TradeoffCurve>& curves, double top) {
  for (std::size_t i = 0; i < curves.size(); ++i) {
    const TradeoffCurve& c = curves[i];
    const double y = top + kLegendRow * static_cast<double>(2 * i);
    svg.Line({kPlotLeft, y - 4}, {kPlotLeft + 26, y - 4}, "curve" + std::to_string(i));
    svg.Text({kPlotLeft + 32, y}, c.label, "");
    std::string text;
    if (c.returned)
      text = fmt::format("returned model (square): {} springs, E {:.3g}", c.returned->first,
                         c.returned->second);
    if (c.chosen && *c.chosen < c.points.size())
      text += fmt::format("{}refitted from path point {} of {} ({} springs, E {:.3g}: large dot)",
                          text.empty() ? "" : "; ", *c.chosen + 1, c.points.size(),
                          c.points[*c.chosen].first, c.points[*c.chosen].second);
    if (!text.empty()) svg.Text({kPlotLeft + 32, y + kLegendRow}, text, "");
  }
  const bool any_baseline = std::any_of(curves.begin(), curves.end(), [](const TradeoffCurve& c) {
    return c.baseline_error && Drawable(*c.baseline_error);
  });
  if (any_baseline) {
    const double y = top + kLegendRow * static_cast<double>(2 * curves.size());
    svg.Line({kPlotLeft, y - 4}, {kPlotLeft + 26, y - 4}, "reference");
    svg.Text({kPlotLeft + 32, y}, "closed-form baseline (van Gelder 1998) on the mesh edges", "");
  }
}

}  // namespace

std::string RenderTradeoffPlot(const std::vector<TradeoffCurve>& curves, const std::string& title,
                               const TradeoffPlotOptions& options) {
  const TradeoffSpan span = TradeoffSpan::Of(curves);
  if (!(span.e_hi > 0.0)) {
    throw std::invalid_argument(
        "nothing to plot: no sparsity path (strategy continuous writes one, proto/RUN.md)");
  }
  const TradeoffFrame frame(span, options);
  // Two legend rows per curve (its name; the returned model), one for the baseline.
  const double legend_height = kLegendRow * static_cast<double>(2 * curves.size() + 1) + 10;
  SvgDocument svg(options.width, options.height + legend_height);
  svg.Style(PlotCss(curves.size()));
  DrawAxes(svg, frame, title);
  for (std::size_t i = 0; i < curves.size(); ++i) DrawCurve(svg, frame, curves[i], i);
  DrawLegend(svg, curves, options.height);
  return svg.str();
}

}  // namespace springfit::figures
