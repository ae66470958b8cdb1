#include "figures/topology_figure.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include "engine/api/input_error.h"
#include "engine/api/problem.h"
#include "figures/svg_document.h"

namespace springfit::figures {
namespace {

constexpr double kMargin = 20.0;
constexpr double kHeading = 78.0;        // title, subtitle, legend
constexpr double kCaption = 34.0;        // under each row of panels
constexpr double kGap = 24.0;            // between the two columns
constexpr double kPanelPad = 14.0;       // inside a panel, around the drawing
constexpr double kArrowFraction = 0.08;  // the largest force arrow, of a panel's size

constexpr std::string_view kCss =
    "text{font-family:sans-serif;font-size:12px;fill:#222}\n"
    ".title{font-size:15px;font-weight:bold}\n"
    ".warn{fill:#c62828}\n"
    ".panel{fill:none;stroke:#ddd}\n"
    ".rest{stroke:#c8c8c8;stroke-width:0.8}\n"
    ".spring{stroke:#37474f;stroke-width:1.1}\n"
    ".missing{stroke:#d32f2f;stroke-width:2;stroke-dasharray:5 3}\n"
    ".extra{stroke:#1e88e5;stroke-width:2.2}\n"
    ".node{fill:#37474f}\n"
    ".rest-node{fill:none;stroke:#b0b0b0}\n"
    ".fixed{fill:#222}\n"
    ".prescribed{fill:#8e24aa}\n"
    ".force{stroke:#2e7d32;stroke-width:1.4}\n"
    ".force-head{fill:#2e7d32}\n"
    ".number{font-size:9px;fill:#555}\n"
    // Line widths by stiffness (kStiffnessWidths classes, thinnest = softest).
    ".k0{stroke-width:0.5}.k1{stroke-width:1}.k2{stroke-width:1.6}.k3{stroke-width:2.4}"
    ".k4{stroke-width:3.4}\n";

// Projects the scene's points onto the page: 2D as they are; 3D in an orthographic view.
// Page coordinates grow downwards, so y is flipped at the very end (in Frame).
class Projection {
 public:
  Projection(int dimension, double azimuth_deg, double elevation_deg)
      : d_(dimension), azimuth_(azimuth_deg), elevation_(elevation_deg) {}
  // Node `node` of flat d*n coordinates (positions, or forces: the map is linear).
  Point2 operator()(const Vector& flat, int node) const {
    const Eigen::Index at = static_cast<Eigen::Index>(d_) * node;
    if (d_ == 2) return {flat(at), flat(at + 1)};
    const ViewPoint p = ProjectView(flat(at), flat(at + 1), flat(at + 2), azimuth_, elevation_);
    return {p.x, p.y};
  }

 private:
  int d_;
  double azimuth_, elevation_;
};

// Maps projected scene coordinates into one panel, the same scale for every panel so that
// deformations compare across load cases.
struct Frame {
  double scale = 1.0;
  Point2 center;  // of the scene's drawing, in projected coordinates
  Point2 origin;  // the panel's centre on the page
  Point2 operator()(Point2 p) const {
    return {origin.x + scale * (p.x - center.x), origin.y - scale * (p.y - center.y)};
  }
};

struct Extent {
  double lo_x = std::numeric_limits<double>::infinity(), lo_y = lo_x;
  double hi_x = -std::numeric_limits<double>::infinity(), hi_y = hi_x;
  void Add(Point2 p) {
    lo_x = std::min(lo_x, p.x);
    lo_y = std::min(lo_y, p.y);
    hi_x = std::max(hi_x, p.x);
    hi_y = std::max(hi_y, p.y);
  }
};

double MaxNodeNorm(const Vector& flat, int d) {
  double m = 0.0;
  for (Eigen::Index i = 0; i + d <= flat.size(); i += d) m = std::max(m, flat.segment(i, d).norm());
  return m;
}

struct PanelContent {
  const Vector* positions = nullptr;  // deformed (or rest, when there is no equilibrium)
  const std::vector<NodePair>* springs = nullptr;  // drawn at rest and deformed; null = nodes only
  const std::vector<NodePair>* missing = nullptr;
  const std::vector<NodePair>* extra = nullptr;
  const std::vector<double>* stiffness = nullptr;  // per spring of `springs`; null = uniform
};

class FigureWriter {
 public:
  FigureWriter(const Problem& problem, const TopologyFigureOptions& options)
      : problem_(problem),
        options_(options),
        d_(problem.dimension()),
        projection_(d_, options.azimuth, options.elevation) {}

  std::string Write(const TopologyFigureInput& input) {
    Evaluate(input);
    StiffnessRange(input);
    if (options_.rest_topology) return WriteRest(input);
    const std::vector<int> cases = SelectedCases();
    const double magnify = Magnification();
    for (const int k : cases) {
      reference_positions_.push_back(problem_.scene().rest +
                                     magnify * problem_.load_cases()[k].reference);
      identified_positions_.push_back(
          identified_u_[k].size() > 0 ? Vector(problem_.scene().rest + magnify * identified_u_[k])
                                      : problem_.scene().rest);
    }
    FitFrames();

    const double p = options_.panel_size;
    const double width = 2 * kMargin + 2 * p + kGap;
    const double height =
        kMargin + kHeading + static_cast<double>(cases.size()) * (p + kCaption) + kMargin;
    SvgDocument svg(width, height);
    svg.Style(kCss);
    Heading(svg, input, magnify, width);

    const Scene& scene = problem_.scene();
    const bool mss = scene.reference.kind == Reference::Kind::kMss;
    const std::vector<double>* reference_stiffness = ReferenceStiffness();
    const std::vector<double>* identified_stiffness =
        input.stiffness.empty() ? nullptr : &input.stiffness;
    for (std::size_t row = 0; row < cases.size(); ++row) {
      const int k = cases[row];
      const double top = kMargin + kHeading + static_cast<double>(row) * (p + kCaption);
      const Point2 left{kMargin, top};
      const Point2 right{kMargin + p + kGap, top};
      const std::string name =
          scene.load_cases[k].name.empty()
              ? "load case " + std::to_string(k)
              : "load case " + std::to_string(k) + " '" + scene.load_cases[k].name + "'";
      PanelContent reference{&reference_positions_[row], mss ? &scene.reference.springs : nullptr,
                             nullptr, nullptr, reference_stiffness};
      Panel(svg, left, k, reference, "reference, " + name);

      PanelContent identified{&identified_positions_[row], &input.springs,
                              difference_ ? &difference_->missing : nullptr,
                              difference_ ? &difference_->extra : nullptr, identified_stiffness};
      const LoadCaseEvaluation& eval = evaluation_.load_cases[k];
      std::string caption =
          "identified: E " + fmt::format("{:.3g}", std::sqrt(eval.normalized_error));
      bool warn = false;
      if (eval.solve.termination == Termination::kMechanism) {
        caption = "identified: a mechanism (" + std::to_string(eval.solve.mechanism_modes) +
                  " modes), at rest";
        warn = true;
      } else if (!eval.solve.converged()) {
        caption = "identified: no convergence, at rest";
        warn = true;
      }
      Panel(svg, right, k, identified, caption, warn);
    }
    return svg.str();
  }

 private:
  // The rest-topology figure: one pair of panels, both at rest.
  std::string WriteRest(const TopologyFigureInput& input) {
    reference_positions_ = {problem_.scene().rest};
    FitFrames(/*room_for_forces=*/false);
    const double p = options_.panel_size;
    const double width = 2 * kMargin + 2 * p + kGap;
    const double height = kMargin + kHeading + p + kCaption + kMargin;
    SvgDocument svg(width, height);
    svg.Style(kCss);
    Heading(svg, input, 1.0, width);
    const Scene& scene = problem_.scene();
    const double top = kMargin + kHeading;
    const Vector& rest = scene.rest;
    PanelContent reference{
        &rest, scene.reference.kind == Reference::Kind::kMss ? &scene.reference.springs : nullptr,
        nullptr, nullptr, ReferenceStiffness()};
    Panel(svg, {kMargin, top}, -1, reference,
          reference.springs ? "reference topology, at rest" : "reference: positions, no springs");
    PanelContent identified{&rest, &input.springs, difference_ ? &difference_->missing : nullptr,
                            difference_ ? &difference_->extra : nullptr,
                            input.stiffness.empty() ? nullptr : &input.stiffness};
    Panel(svg, {kMargin + p + kGap, top}, -1, identified,
          "identified topology, at rest: E " +
              fmt::format("{:.3g}", std::sqrt(evaluation_.normalized_error)));
    return svg.str();
  }

  // The reference's per-spring stiffness, when it has one per spring.
  const std::vector<double>* ReferenceStiffness() const {
    const Reference& ref = problem_.scene().reference;
    return ref.kind == Reference::Kind::kMss && ref.stiffness.size() == ref.springs.size() &&
                   ref.springs.size() > 1
               ? &ref.stiffness
               : nullptr;
  }

  // The stiffness range of the figure's springs; line widths follow it when it is not one value.
  void StiffnessRange(const TopologyFigureInput& input) {
    k_lo_ = std::numeric_limits<double>::infinity();
    k_hi_ = 0.0;
    for (const std::vector<double>* ks : {ReferenceStiffness(), &input.stiffness}) {
      if (!ks) continue;
      for (const double k : *ks) {
        if (!(k > 0.0) || !std::isfinite(k)) continue;
        k_lo_ = std::min(k_lo_, k);
        k_hi_ = std::max(k_hi_, k);
      }
    }
    widths_ = k_hi_ > k_lo_ * (1.0 + 1e-9);
  }

  // The CSS class of a spring of stiffness k: "" when widths are uniform.
  std::string WidthClass(const std::vector<double>* stiffness, std::size_t s) const {
    if (!widths_ || !stiffness) return "";
    const double k = (*stiffness)[s];
    const double t = std::log(k / k_lo_) / std::log(k_hi_ / k_lo_);
    const int bin = std::clamp(static_cast<int>(t * kStiffnessWidths), 0, kStiffnessWidths - 1);
    return "k" + std::to_string(bin);
  }

  std::vector<int> SelectedCases() const {
    const int count = static_cast<int>(problem_.load_cases().size());
    if (options_.load_cases.empty()) {
      std::vector<int> all(count);
      for (int k = 0; k < count; ++k) all[k] = k;
      return all;
    }
    for (std::size_t i = 0; i < options_.load_cases.size(); ++i) {
      const int k = options_.load_cases[i];
      if (k < 0 || k >= count) {
        throw InputError("load_cases[" + std::to_string(i) + "]",
                         "load case " + std::to_string(k) + " out of range: the scene has " +
                             std::to_string(count));
      }
    }
    return options_.load_cases;
  }

  void Evaluate(const TopologyFigureInput& input) {
    const std::vector<NodePair>& springs = input.springs;
    if (!input.stiffness.empty() && input.stiffness.size() != springs.size()) {
      throw InputError("stiffness", std::to_string(input.stiffness.size()) + " values for " +
                                        std::to_string(springs.size()) + " springs");
    }
    std::vector<std::uint8_t> mask(problem_.candidates().size(), 0);
    ActiveSprings model;
    for (std::size_t s = 0; s < springs.size(); ++s) {
      const std::string path = "springs[" + std::to_string(s) + "]";
      const int c = problem_.CandidateIndex(springs[s]);
      if (c < 0) {
        throw InputError(path, "[" + std::to_string(springs[s].first) + ", " +
                                   std::to_string(springs[s].second) +
                                   "] is not a candidate spring of the scene");
      }
      if (mask[c]) throw InputError(path, "given twice");
      mask[c] = 1;
      const double k = input.stiffness.empty() ? problem_.training_stiffness() : input.stiffness[s];
      if (!(k > 0.0) || !std::isfinite(k)) {
        throw InputError("stiffness[" + std::to_string(s) + "]", "must be a finite number > 0");
      }
      model.index.push_back(c);
      model.stiffness.push_back(k);
    }
    difference_ = problem_.CompareWithReference(problem_.GenomeFromMask(mask));
    CostOptions every_case;
    every_case.solve_cases_of_mechanisms = true;  // each panel shows its own case's equilibrium
    CostFunction cost(problem_, every_case);
    evaluation_ = cost.Evaluate(model, &identified_u_);
  }

  std::string Subtitle(const TopologyFigureInput& input) const {
    std::string s = input.note.empty() ? "" : input.note + "; ";
    if (difference_) {
      s += difference_->hamming() == 0
               ? "exact recovery"
               : "not exact: " + std::to_string(difference_->missing.size()) + " missing, " +
                     std::to_string(difference_->extra.size()) + " extra";
    } else {
      s += "reference topology unknown";
    }
    // E, the one error measure shown (proto/RUN.md); the springs as the result counts them.
    return s + "; " + std::to_string(input.springs.size()) + " springs; E " +
           fmt::format("{:.3g}", std::sqrt(evaluation_.normalized_error));
  }

  double Magnification() const {
    if (options_.magnify > 0.0) return options_.magnify;
    double largest = 0.0;
    for (const PreparedLoadCase& lc : problem_.load_cases())
      largest = std::max(largest, MaxNodeNorm(lc.reference, d_));
    const double diagonal = problem_.scene().Bounds().Diagonal();
    if (largest <= 0.0 || largest >= 0.05 * diagonal) return 1.0;
    return 0.1 * diagonal / largest;
  }

  // One scale for all panels, from the rest shape and the reference's deformed shapes. The
  // identified model's shapes are not included: a nearly-unstable topology may move a node
  // far away, and is clipped to its panel instead of shrinking every drawing.
  void FitFrames(bool room_for_forces = true) {
    Extent e;
    const int n = problem_.scene().node_count();
    for (int i = 0; i < n; ++i) e.Add(projection_(problem_.scene().rest, i));
    for (const Vector& x : reference_positions_) {
      for (int i = 0; i < n; ++i) e.Add(projection_(x, i));
    }
    // Force arrows: the largest is 8% of a panel, and the drawing leaves room for it.
    double largest_force = 0.0;
    if (room_for_forces) {
      for (const PreparedLoadCase& lc : problem_.load_cases())
        largest_force = std::max(largest_force, MaxNodeNorm(lc.force, d_));
    }
    const double arrow = largest_force > 0.0 ? kArrowFraction * options_.panel_size : 0.0;
    force_scale_ = largest_force > 0.0 ? arrow / largest_force : 0.0;
    const double inner = options_.panel_size - 2 * (kPanelPad + arrow);
    const double span = std::max({e.hi_x - e.lo_x, e.hi_y - e.lo_y, 1e-300});
    frame_.scale = inner / span;
    frame_.center = {0.5 * (e.lo_x + e.hi_x), 0.5 * (e.lo_y + e.hi_y)};
  }

  void Heading(SvgDocument& svg, const TopologyFigureInput& input, double magnify, double width) {
    svg.Text({kMargin, kMargin + 14}, input.title, "title");
    svg.Text({kMargin, kMargin + 32}, Subtitle(input), "");
    const double y = kMargin + 56;
    double x = kMargin;
    auto sample = [&](std::string_view cls, const std::string& label) {
      svg.Line({x, y - 4}, {x + 22, y - 4}, cls);
      svg.Text({x + 27, y}, label, "");
      x += 27 + 7.0 * static_cast<double>(label.size()) + 16;
    };
    if (!options_.rest_topology) {
      sample("rest", "rest");
      sample("spring", "deformed");
    } else {
      sample("spring", "spring");
    }
    if (difference_) {
      sample("missing", "missing: " + std::to_string(difference_->missing.size()));
      sample("extra", "extra: " + std::to_string(difference_->extra.size()));
    }
    if (widths_) {
      // On the subtitle's line, at the right: the thinnest and the thickest width, and the range.
      const std::string label = "width: stiffness " + fmt::format("{:.3g}", k_lo_) + " to " +
                                fmt::format("{:.3g}", k_hi_) + " (log)";
      const double right = width - kMargin, line_y = kMargin + 28;
      const double start = right - 6.5 * static_cast<double>(label.size()) - 34;
      svg.Line({start, line_y}, {start + 12, line_y}, "spring k0");
      svg.Line({start + 16, line_y}, {start + 28, line_y}, "spring k4");
      svg.Text({right, kMargin + 32}, label, "", SvgDocument::Anchor::kEnd);
    }
    if (options_.rest_topology) return;
    svg.Rect({x, y - 8}, 7, 7, "fixed");
    svg.Text({x + 11, y}, "fixed", "");
    x += 56;
    svg.Polygon({{x, y}, {x + 8, y}, {x + 4, y - 8}}, "prescribed");
    svg.Text({x + 12, y}, "prescribed", "");
    x += 90;
    svg.Line({x, y - 4}, {x + 18, y - 4}, "force");
    svg.Polygon({{x + 22, y - 4}, {x + 15, y - 7.5}, {x + 15, y - 0.5}}, "force-head");
    svg.Text({x + 27, y}, "force", "");
    const std::string scale = magnify == 1.0 ? "displacements true size"
                                             : "displacements x" + fmt::format("{:.3g}", magnify);
    svg.Text({width - kMargin, kMargin + 14}, scale, "", SvgDocument::Anchor::kEnd);
  }

  void Panel(SvgDocument& svg, Point2 corner, int k, const PanelContent& content,
             const std::string& caption, bool warn = false) {
    const double p = options_.panel_size;
    Frame frame = frame_;
    frame.origin = {corner.x + p / 2, corner.y + p / 2};
    const Vector& rest = problem_.scene().rest;
    const Vector& x = *content.positions;
    auto at = [&](const Vector& flat, int node) { return frame(projection_(flat, node)); };

    svg.Rect(corner, p, p, "panel");
    svg.BeginClippedGroup(corner, p, p);
    const int n = problem_.scene().node_count();
    if (content.springs) {
      if (!options_.rest_topology) {
        svg.BeginGroup("rest");
        for (const NodePair& s : *content.springs)
          svg.Line(at(rest, s.first), at(rest, s.second), "");
        svg.EndGroup();
      }
      svg.BeginGroup("spring");
      for (std::size_t s = 0; s < content.springs->size(); ++s) {
        const NodePair& spring = (*content.springs)[s];
        svg.Line(at(x, spring.first), at(x, spring.second), WidthClass(content.stiffness, s));
      }
      svg.EndGroup();
    } else {
      // A positions reference: no springs, so show where each node went.
      for (int i = 0; i < n; ++i) {
        svg.Circle(at(rest, i), 2.0, "rest-node");
        svg.Line(at(rest, i), at(x, i), "rest");
      }
    }
    // Wrong springs last, over the others; one shape each so they can be counted.
    if (content.missing) {
      for (const NodePair& s : *content.missing)
        svg.Line(at(x, s.first), at(x, s.second), "missing");
    }
    if (content.extra) {
      for (const NodePair& s : *content.extra) svg.Line(at(x, s.first), at(x, s.second), "extra");
    }
    for (int i = 0; i < n; ++i) svg.Circle(at(x, i), n > 400 ? 0.8 : 1.6, "node");
    if (options_.node_numbers) {
      for (int i = 0; i < n; ++i) {
        const Point2 c = at(x, i);
        svg.Text({c.x + 3, c.y - 3}, std::to_string(i), "number");
      }
    }
    if (k < 0) {  // the rest topology: no load case
      svg.EndGroup();
      svg.Text({corner.x, corner.y + p + 18}, caption, warn ? "warn" : "");
      return;
    }

    const LoadCase& lc = problem_.scene().load_cases[k];
    for (const int i : lc.fixed) {
      const Point2 c = at(x, i);
      svg.Rect({c.x - 3, c.y - 3}, 6, 6, "fixed");
    }
    for (const NodalLoad& load : lc.displacements) {
      for (const int i : load.nodes) {
        const Point2 c = at(x, i);
        svg.Polygon({{c.x - 4, c.y + 3}, {c.x + 4, c.y + 3}, {c.x, c.y - 4}}, "prescribed");
      }
    }
    if (force_scale_ > 0.0) {
      const Vector& force = problem_.load_cases()[k].force;
      for (int i = 0; i < n; ++i) {
        if (force.segment(d_ * i, d_).squaredNorm() == 0.0) continue;
        const Point2 dir = projection_(force, i);
        Arrow(svg, at(x, i), {force_scale_ * dir.x, -force_scale_ * dir.y});
      }
    }
    svg.EndGroup();
    svg.Text({corner.x, corner.y + p + 18}, caption, warn ? "warn" : "");
  }

  static void Arrow(SvgDocument& svg, Point2 from, Point2 delta) {
    const double length = std::hypot(delta.x, delta.y);
    if (length < 1.0) return;  // a force seen end-on in a 3D view
    const Point2 tip{from.x + delta.x, from.y + delta.y};
    const Point2 u{delta.x / length, delta.y / length};
    const double head = std::min(7.0, 0.4 * length);
    svg.Line(from, {tip.x - head * u.x, tip.y - head * u.y}, "force");
    svg.Polygon({tip,
                 {tip.x - head * u.x - 0.5 * head * u.y, tip.y - head * u.y + 0.5 * head * u.x},
                 {tip.x - head * u.x + 0.5 * head * u.y, tip.y - head * u.y - 0.5 * head * u.x}},
                "force-head");
  }

  const Problem& problem_;
  const TopologyFigureOptions& options_;
  int d_;
  Projection projection_;
  Evaluation evaluation_;
  std::optional<TopologyDifference> difference_;
  std::vector<Vector> identified_u_;
  std::vector<Vector> reference_positions_;
  std::vector<Vector> identified_positions_;
  Frame frame_;
  double force_scale_ = 0.0;
  bool widths_ = false;  // line widths follow stiffness (StiffnessRange)
  double k_lo_ = 1.0, k_hi_ = 1.0;
};

}  // namespace

ViewPoint ProjectView(double x, double y, double z, double azimuth, double elevation) {
  const double deg = std::numbers::pi / 180.0;
  const double ca = std::cos(azimuth * deg), sa = std::sin(azimuth * deg);
  const double ce = std::cos(elevation * deg), se = std::sin(elevation * deg);
  // Turn about z, then look along the turned y axis from above: x right, depth away from the
  // viewer, z up; points further away sit higher on the page (a right-handed view).
  const double right = ca * x - sa * y;
  const double depth = sa * x + ca * y;
  return {right, ce * z + se * depth};
}

std::string RenderTopologyFigure(const Problem& problem, const TopologyFigureInput& input,
                                 const TopologyFigureOptions& options) {
  return FigureWriter(problem, options).Write(input);
}

}  // namespace springfit::figures
