// Normalised error against wall time on log-log axes, one curve per run: the data of
// Bianchi et al.'s Figure 2 on a time axis, drawn by `springfit plot` (README.md, "Figures").
#pragma once
#include <string>
#include <vector>

namespace springfit::figures {

struct ErrorCurve {
  std::string label;
  // (x, best E so far: the relative RMS nodal error), in the order of the trace; x is wall seconds
  // by default (ErrorPlotOptions::x_label says what else). The best error never rises; an error of
  // 0 is exact recovery, drawn on the bottom axis with a marker.
  std::vector<std::pair<double, double>> points;
};

struct ErrorPlotOptions {
  double width = 760.0;
  double height = 480.0;
  // What the points' first coordinate is (plot --x): wall seconds, generations, evaluations.
  std::string x_label = "wall time (s)";
};

// Throws std::invalid_argument when no curve has a point.
std::string RenderErrorPlot(const std::vector<ErrorCurve>& curves, const std::string& title,
                            const ErrorPlotOptions& options = {});

}  // namespace springfit::figures
