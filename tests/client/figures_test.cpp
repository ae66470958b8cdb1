// The SVG figures of `springfit render` and `springfit plot`, counted shape by shape.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "client/figures/error_plot.h"
#include "client/figures/topology_figure.h"
#include "engine/input_error.h"
#include "tests/test_scenes.h"

namespace springfit::cli {
namespace {

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
  return n;
}

Problem GridProblem(int dimension) { return Problem::Build(testing::GridScene(dimension, 3)); }

TEST(TopologyFigure, MarksEachWrongSpringInEachPanel) {
  const Problem problem = GridProblem(2);
  TopologyFigureInput input;
  input.springs = problem.scene().reference.springs;
  const NodePair dropped = input.springs.back();
  input.springs.pop_back();
  input.missing = std::vector<NodePair>{dropped};
  input.extra = std::vector<NodePair>{};
  const std::string svg = RenderTopologyFigure(problem, input);
  const int cases = static_cast<int>(problem.load_cases().size());
  EXPECT_EQ(Count(svg, "class=\"missing\""), cases + 1);  // one per identified panel, one in the legend
  EXPECT_EQ(Count(svg, "class=\"extra\""), 1);
  EXPECT_EQ(Count(svg, "class=\"panel\""), 2 * cases);
  EXPECT_EQ(Count(svg, "<clipPath"), 2 * cases);
  EXPECT_EQ(Count(svg, "</svg>"), 1);

  TopologyFigureOptions only;
  only.load_cases = {2, 0};
  EXPECT_EQ(Count(RenderTopologyFigure(problem, input, only), "class=\"missing\""), 3);
}

TEST(TopologyFigure, AMechanismIsDrawnAtRestAndSaidSo) {
  const Problem problem = GridProblem(3);
  TopologyFigureInput input;  // no springs at all
  input.missing = problem.scene().reference.springs;
  input.extra = std::vector<NodePair>{};
  const std::string svg = RenderTopologyFigure(problem, input);
  EXPECT_EQ(Count(svg, "no equilibrium, a mechanism"), static_cast<int>(problem.load_cases().size()));
  EXPECT_EQ(Count(svg, "class=\"missing\""),
            static_cast<int>(problem.load_cases().size() * input.missing->size()) + 1);
}

TEST(TopologyFigure, SmallDisplacementsAreMagnifiedAndTheFactorStated) {
  Scene scene = testing::GridScene(2, 3, 1.0, 1.0, 1e-4);  // tiny loads: tiny displacements
  const Problem problem = Problem::Build(std::move(scene));
  TopologyFigureInput input;
  input.springs = problem.scene().reference.springs;
  EXPECT_EQ(Count(RenderTopologyFigure(problem, input), "displacements x"), 1);
  TopologyFigureOptions fixed;
  fixed.magnify = 1.0;
  EXPECT_EQ(Count(RenderTopologyFigure(problem, input, fixed), "displacements true size"), 1);
}

TEST(TopologyFigure, RefusesSpringsThatAreNotCandidatesAndUnknownLoadCases) {
  const Problem problem = GridProblem(2);
  TopologyFigureInput input;
  input.springs = {{0, 1}, {0, 8}};  // 0 and 8 are opposite corners of the 3x3 grid
  try {
    RenderTopologyFigure(problem, input);
    FAIL() << "a non-candidate spring was drawn";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "springs[1]");
  }
  input.springs = {{0, 1}};
  TopologyFigureOptions options;
  options.load_cases = {0, 99};
  try {
    RenderTopologyFigure(problem, input, options);
    FAIL() << "load case 99 was drawn";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "load_cases[1]");
  }
}

TEST(ErrorPlot, StepsPerCurveAndAMarkerForExactRecovery) {
  ErrorCurve exact{"exact", {{0.001, 10.0}, {0.01, 0.5}, {0.1, 0.0}}};
  ErrorCurve stuck{"stuck", {{0.0, 3.0}, {2.0, 0.2}}};  // a time of 0 sits on the axis
  const std::string svg = RenderErrorPlot({exact, stuck}, "t < & >");
  EXPECT_EQ(Count(svg, "<polyline class=\"curve"), 2);
  EXPECT_EQ(Count(svg, "<circle class=\"exact0\""), 1);
  EXPECT_EQ(Count(svg, "<circle class=\"exact1\""), 0);
  EXPECT_EQ(Count(svg, "t &lt; &amp; &gt;"), 1);  // the title is escaped
  EXPECT_EQ(Count(svg, "(exact at 0.1 s)"), 1);
  EXPECT_EQ(Count(svg, "(error 0.2 at 2 s)"), 1);
  EXPECT_EQ(Count(svg, "nan"), 0);
  EXPECT_EQ(Count(svg, "inf"), 0);
  EXPECT_THROW(RenderErrorPlot({ErrorCurve{"empty", {}}}, "x"), std::invalid_argument);
}

}  // namespace
}  // namespace springfit::cli
