// The accuracy/size trade-off of strategy continuous: E (relative RMS nodal error, log axis)
// against the number of springs, one curve per result (its sparsity path), the returned
// model marked, and the closed-form baseline of an FEM reference as a dashed level with its
// spring count. Drawn by `springfit plot --tradeoff` (README.md, "Figures").
#pragma once
#include <optional>
#include <string>
#include <vector>

namespace springfit::figures {

struct TradeoffCurve {
  std::string label;
  std::vector<std::pair<int, double>> points;  // (springs, E); E not finite: not drawn
  std::optional<std::size_t> chosen;  // the point the returned model came from (none: the start)
  // The returned model itself (springs, E): after its refit it is off the path.
  std::optional<std::pair<int, double>> returned;
  std::optional<double> baseline_error;  // the baseline's E
  std::optional<int> baseline_springs;
};

struct TradeoffPlotOptions {
  double width = 760.0;
  double height = 480.0;
};

// Throws std::invalid_argument when no curve has a point with a positive finite E.
std::string RenderTradeoffPlot(const std::vector<TradeoffCurve>& curves, const std::string& title,
                               const TradeoffPlotOptions& options = {});

}  // namespace springfit::figures
