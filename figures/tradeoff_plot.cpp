#include "figures/tradeoff_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

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

}  // namespace

std::string RenderTradeoffPlot(const std::vector<TradeoffCurve>& curves, const std::string& title,
                               const TradeoffPlotOptions& options) {
  double s_lo = std::numeric_limits<double>::infinity(), s_hi = 0.0;
  double e_lo = std::numeric_limits<double>::infinity(), e_hi = 0.0;
  for (const TradeoffCurve& c : curves) {
    for (const auto& [springs, e] : c.points) {
      if (!Drawable(e)) continue;
      s_lo = std::min(s_lo, static_cast<double>(springs));
      s_hi = std::max(s_hi, static_cast<double>(springs));
      e_lo = std::min(e_lo, e);
      e_hi = std::max(e_hi, e);
    }
    if (c.returned && Drawable(c.returned->second)) {
      s_lo = std::min(s_lo, static_cast<double>(c.returned->first));
      s_hi = std::max(s_hi, static_cast<double>(c.returned->first));
      e_lo = std::min(e_lo, c.returned->second);
      e_hi = std::max(e_hi, c.returned->second);
    }
    if (c.baseline_error && Drawable(*c.baseline_error)) {
      e_lo = std::min(e_lo, *c.baseline_error);
      e_hi = std::max(e_hi, *c.baseline_error);
      if (c.baseline_springs) {
        s_lo = std::min(s_lo, static_cast<double>(*c.baseline_springs));
        s_hi = std::max(s_hi, static_cast<double>(*c.baseline_springs));
      }
    }
  }
  if (!(e_hi > 0.0)) {
    throw std::invalid_argument(
        "nothing to plot: no sparsity path (strategy continuous writes one, proto/RUN.md)");
  }
  const double step = NiceStep(std::max(s_hi - s_lo, 1.0), 6);
  const double x_lo = std::floor(s_lo / step) * step,
               x_hi = std::ceil(s_hi / step) * step + (s_hi == s_lo ? step : 0.0);
  const LogAxis y_axis = LogAxis::Over(e_lo, e_hi);

  // Two legend rows per curve (its name; the returned model), one for the baseline.
  const double legend_height = kLegendRow * static_cast<double>(2 * curves.size() + 1) + 10;
  const double plot_w = options.width - kPlotLeft - kPlotRight;
  const double plot_h = options.height - kPlotTop - kPlotBottom;
  auto px = [&](double springs) { return kPlotLeft + plot_w * (springs - x_lo) / (x_hi - x_lo); };
  auto py = [&](double e) {
    return kPlotTop + plot_h * (1.0 - std::clamp(y_axis.Fraction(e), 0.0, 1.0));
  };

  SvgDocument svg(options.width, options.height + legend_height);
  svg.Style(PlotCss(curves.size()));
  svg.Text({kPlotLeft, 26}, title, "title");
  for (double s = x_lo; s <= x_hi + 0.5 * step; s += step) {
    const double x = px(s);
    svg.Line({x, kPlotTop}, {x, kPlotTop + plot_h}, "grid");
    char label[32];
    std::snprintf(label, sizeof label, "%.0f", s);
    svg.Text({x, kPlotTop + plot_h + 18}, label, "", SvgDocument::Anchor::kMiddle);
  }
  for (int d = y_axis.lo; d <= y_axis.hi; ++d) {
    const double y = py(std::pow(10.0, d));
    svg.Line({kPlotLeft, y}, {kPlotLeft + plot_w, y}, "grid");
    svg.Text({kPlotLeft - 8, y + 4}, DecadeLabel(d), "", SvgDocument::Anchor::kEnd);
  }
  svg.Rect({kPlotLeft, kPlotTop}, plot_w, plot_h, "frame");
  svg.Text({kPlotLeft + plot_w / 2, kPlotTop + plot_h + 40}, "springs", "",
           SvgDocument::Anchor::kMiddle);
  svg.VerticalText({22, kPlotTop + plot_h / 2}, "E (relative RMS nodal error)", "");

  for (std::size_t i = 0; i < curves.size(); ++i) {
    const TradeoffCurve& c = curves[i];
    const std::string cls = std::to_string(i);
    std::vector<Point2> line;
    for (const auto& [springs, e] : c.points) {
      if (Drawable(e)) line.push_back({px(springs), py(e)});
    }
    if (!line.empty()) svg.Polyline(line, "curve" + cls);
    for (const Point2& p : line) svg.Circle(p, 2.5, "exact" + cls);
    if (c.chosen && *c.chosen < c.points.size() && Drawable(c.points[*c.chosen].second)) {
      const auto& [springs, e] = c.points[*c.chosen];
      svg.Circle({px(springs), py(e)}, 6.0, "exact" + cls);
    }
    if (c.returned && Drawable(c.returned->second)) {
      // A square: the model the result returns, where the user reads its springs and E.
      const Point2 p{px(c.returned->first), py(c.returned->second)};
      svg.Rect({p.x - 5.0, p.y - 5.0}, 10.0, 10.0, "curve" + cls);
    }
    if (c.baseline_error && Drawable(*c.baseline_error)) {
      const double y = py(*c.baseline_error);
      svg.Line({kPlotLeft, y}, {kPlotLeft + plot_w, y}, "reference");
      if (c.baseline_springs) svg.Circle({px(*c.baseline_springs), y}, 4.0, "exact" + cls);
    }
  }

  const double legend_top = options.height;
  for (std::size_t i = 0; i < curves.size(); ++i) {
    const TradeoffCurve& c = curves[i];
    const double y = legend_top + kLegendRow * static_cast<double>(2 * i);
    svg.Line({kPlotLeft, y - 4}, {kPlotLeft + 26, y - 4}, "curve" + std::to_string(i));
    svg.Text({kPlotLeft + 32, y}, c.label, "");
    std::string text;
    char part[128];
    if (c.returned) {
      std::snprintf(part, sizeof part, "returned model (square): %d springs, E %.3g",
                    c.returned->first, c.returned->second);
      text = part;
    }
    if (c.chosen && *c.chosen < c.points.size()) {
      std::snprintf(part, sizeof part,
                    "%srefitted from path point %zu of %zu (%d springs, E %.3g: large dot)",
                    text.empty() ? "" : "; ", *c.chosen + 1, c.points.size(),
                    c.points[*c.chosen].first, c.points[*c.chosen].second);
      text += part;
    }
    if (!text.empty()) svg.Text({kPlotLeft + 32, y + kLegendRow}, text, "");
  }
  const bool any_baseline = std::any_of(curves.begin(), curves.end(), [](const TradeoffCurve& c) {
    return c.baseline_error && Drawable(*c.baseline_error);
  });
  if (any_baseline) {
    const double y = legend_top + kLegendRow * static_cast<double>(2 * curves.size());
    svg.Line({kPlotLeft, y - 4}, {kPlotLeft + 26, y - 4}, "reference");
    svg.Text({kPlotLeft + 32, y}, "closed-form baseline (van Gelder 1998) on the mesh edges", "");
  }
  return svg.str();
}

}  // namespace springfit::figures
