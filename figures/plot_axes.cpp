#include "figures/plot_axes.h"

#include <cmath>
#include <iterator>

namespace springfit::figures {
namespace {

// Eight colours that stay apart for colour-blind readers (Okabe and Ito).
constexpr const char* kColours[] = {"#0072b2", "#d55e00", "#009e73", "#cc79a7",
                                    "#e69f00", "#56b4e9", "#000000", "#f0e442"};

}  // namespace

std::string PlotCss(std::size_t curves) {
  std::string css =
      "text{font-family:sans-serif;font-size:12px;fill:#222}\n"
      ".title{font-size:15px;font-weight:bold}\n"
      ".grid{stroke:#e6e6e6;stroke-width:1}\n"
      ".frame{fill:none;stroke:#222;stroke-width:1}\n"
      ".reference{stroke:#555;stroke-width:1.2;stroke-dasharray:6 4}\n";
  for (std::size_t i = 0; i < curves; ++i) {
    const char* c = kColours[i % std::size(kColours)];
    css += ".curve" + std::to_string(i) + "{fill:none;stroke:" + c + ";stroke-width:1.8}\n";
    css += ".exact" + std::to_string(i) + "{fill:" + c + "}\n";
  }
  return css;
}

std::string DecadeLabel(int exponent) {
  if (exponent == 0) return "1";
  if (exponent == 1) return "10";
  return "1e" + std::to_string(exponent);
}

double LogAxis::Fraction(double v) const {
  return (std::log10(v) - lo) / (hi - lo);
}

LogAxis LogAxis::Over(double lo, double hi) {
  LogAxis axis;
  axis.lo = static_cast<int>(std::floor(std::log10(lo)));
  axis.hi = static_cast<int>(std::ceil(std::log10(hi)));
  if (axis.hi <= axis.lo) axis.hi = axis.lo + 1;
  return axis;
}

void DrawPlotFrame(SvgDocument& svg, double plot_w, double plot_h, const std::string& x_label,
                   const std::string& y_label) {
  svg.Rect({kPlotLeft, kPlotTop}, plot_w, plot_h, "frame");
  svg.Text({kPlotLeft + plot_w / 2, kPlotTop + plot_h + 40}, x_label, "",
           SvgDocument::Anchor::kMiddle);
  svg.VerticalText({22, kPlotTop + plot_h / 2}, y_label, "");
}

}  // namespace springfit::figures
