// The SVG figures of `springfit render` and `springfit plot`, counted shape by shape.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "engine/runtime/input_error.h"
#include "figures/error_plot.h"
#include "figures/svg_document.h"
#include "figures/topology_figure.h"
#include "tests/test_scenes.h"

namespace springfit::figures {
namespace {

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos;
       at = text.find(what, at + what.size()))
    ++n;
  return n;
}

Problem GridProblem(int dimension) {
  return Problem::Build(testing::GridScene(dimension, 3));
}

TEST(TopologyFigure, MarksEachWrongSpringInEachPanel) {
  const Problem problem = GridProblem(2);
  TopologyFigureInput input;
  input.springs = problem.scene().reference.springs;
  input.springs.pop_back();  // one missing spring, found by the figure itself
  const std::string svg = RenderTopologyFigure(problem, input);
  const int cases = static_cast<int>(problem.load_cases().size());
  EXPECT_EQ(Count(svg, "class=\"missing\""),
            cases + 1);  // one per identified panel, one in the legend
  EXPECT_EQ(Count(svg, "class=\"extra\""), 1);
  EXPECT_EQ(Count(svg, "class=\"panel\""), 2 * cases);
  EXPECT_EQ(Count(svg, "<clipPath"), 2 * cases);
  EXPECT_EQ(Count(svg, "</svg>"), 1);
  EXPECT_EQ(Count(svg, "not exact: 1 missing, 0 extra"), 1);
  EXPECT_EQ(Count(svg, "nan"), 0);
  EXPECT_EQ(Count(svg, "inf"), 0);

  TopologyFigureOptions only;
  only.load_cases = {2, 0};
  EXPECT_EQ(Count(RenderTopologyFigure(problem, input, only), "class=\"missing\""), 3);
}

TEST(TopologyFigure, AMechanismIsDrawnAtRestAndSaidSo) {
  const Problem problem = GridProblem(3);
  TopologyFigureInput input;  // no springs at all
  const std::string svg = RenderTopologyFigure(problem, input);
  EXPECT_EQ(Count(svg, "identified: a mechanism"), static_cast<int>(problem.load_cases().size()));
  // Every reference spring the genome can hold is missing, in every identified panel.
  const int missing = problem.CompareWithReference(Genome(problem.gene_count(), 0))->hamming();
  EXPECT_GT(missing, 0);
  EXPECT_EQ(Count(svg, "class=\"missing\""),
            static_cast<int>(problem.load_cases().size()) * missing + 1);
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
  input.springs = {{0, 1}, {0, 1}};
  try {
    RenderTopologyFigure(problem, input);
    FAIL() << "a spring given twice was drawn";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "springs[1]");
  }
  input.springs = {{0, 1}};
  input.stiffness = {1.0, 2.0};
  EXPECT_THROW(RenderTopologyFigure(problem, input), InputError);
  input.stiffness = {-1.0};
  EXPECT_THROW(RenderTopologyFigure(problem, input), InputError);
  input.stiffness.clear();
  TopologyFigureOptions options;
  options.load_cases = {0, 99};
  try {
    RenderTopologyFigure(problem, input, options);
    FAIL() << "load case 99 was drawn";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "load_cases[1]");
  }
}

TEST(TopologyFigure, ThreeDimensionalViewIsFromAboveAndRightHanded) {
  // Straight on (azimuth 0): x to the right, z up, and y (away) higher as seen from above.
  EXPECT_GT(ProjectView(1, 0, 0, 0, 25).x, 0.9);
  EXPECT_NEAR(ProjectView(1, 0, 0, 0, 25).y, 0.0, 1e-12);
  EXPECT_GT(ProjectView(0, 0, 1, 0, 25).y, 0.9);
  EXPECT_GT(ProjectView(0, 1, 0, 0, 25).y, 0.4);
  // Turned by -35 degrees: the y axis comes a little to the right, still receding upwards.
  const ViewPoint y_axis = ProjectView(0, 1, 0, -35, 25);
  EXPECT_GT(y_axis.x, 0.5);
  EXPECT_GT(y_axis.y, 0.3);
}

TEST(SvgText, EscapesMarkupAndReplacesWhatXmlForbids) {
  EXPECT_EQ(XmlEscape("a<b>&\"c\""), "a&lt;b&gt;&amp;&quot;c&quot;");
  EXPECT_EQ(XmlEscape("tab\tok"), "tab\tok");
  EXPECT_EQ(XmlEscape(std::string("x\x01y")), "x\xEF\xBF\xBDy");
  EXPECT_EQ(XmlEscape("caf\xC3\xA9"), "caf\xC3\xA9");            // valid UTF-8 kept
  EXPECT_EQ(XmlEscape("bad\xC3"), "bad\xEF\xBF\xBD");            // truncated sequence
  EXPECT_EQ(XmlEscape("\xC0\xAF"), "\xEF\xBF\xBD\xEF\xBF\xBD");  // overlong form
  EXPECT_EQ(XmlEscape("\xED\xA0\x80"), "\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBD");  // a surrogate
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
}  // namespace springfit::figures
