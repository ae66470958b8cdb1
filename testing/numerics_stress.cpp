#include "testing/numerics_stress.h"

#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <memory>
#include <random>

#include "engine/api/problem.h"
#include "engine/identification/identify.h"
#include "engine/model/equilibrium.h"
#include "engine/problem/cost.h"
#include "engine/runtime/input_error.h"

namespace springfit::examples {
namespace {

using Random = std::mt19937_64;

double Uniform(Random& random, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(random);
}
int UniformInt(Random& random, int lo, int hi) {
  return std::uniform_int_distribution<int>(lo, hi)(random);
}
double LogUniform(Random& random, double lo_exp, double hi_exp) {
  return std::pow(10.0, Uniform(random, lo_exp, hi_exp));
}

// Singular values of the rigidity matrix (unit stiffness, unit-norm columns) on the free
// nodes: the reference the engine's mode count is held to.
Vector RigiditySingularValues(const SpringGeometry& g, const FreeNodes& free,
                              const ActiveSprings& springs) {
  const int d = g.dimension;
  Matrix r = Matrix::Zero(std::max(springs.size(), 1), d * free.count);
  for (int a = 0; a < springs.size(); ++a) {
    const int s = springs.index[a];
    const int fi = free.free_index[g.pairs[s].first], fj = free.free_index[g.pairs[s].second];
    for (int c = 0; c < d; ++c) {
      const double n = g.rest_separation[d * s + c] / g.rest_length[s];
      if (fi >= 0) r(a, d * fi + c) = n;
      if (fj >= 0) r(a, d * fj + c) = -n;
    }
  }
  for (Eigen::Index c = 0; c < r.cols(); ++c) {
    const double norm = r.col(c).norm();
    if (norm > 0.0) r.col(c) /= norm;
  }
  Vector sigma = Vector::Zero(r.cols());  // a column beyond the rows' count is a zero value
  const Vector computed = Eigen::JacobiSVD<Matrix>(r).singularValues();
  sigma.head(std::min(sigma.size(), computed.size())) =
      computed.head(std::min(sigma.size(), computed.size()));
  return sigma;
}

// The engine's mode count `engine` against the SVD: at least the singular values below 1e-13
// (round-off of an exact mechanism's), at most those below 1e-11.
void CheckModes(int engine, const SpringGeometry& g, const FreeNodes& free,
                const ActiveSprings& springs, StressOutcome& out) {
  const Vector sigma = RigiditySingularValues(g, free, springs);
  const int surely = static_cast<int>((sigma.array() < 1e-13).count());
  const int possibly = static_cast<int>((sigma.array() < 1e-11).count());
  ++out.svd_checks;
  if (engine < surely || engine > possibly) {
    out.false_mechanism = true;
    out.detail += "modes " + std::to_string(engine) + " where the SVD has " +
                  std::to_string(surely) + " to " + std::to_string(possibly) + "; ";
  }
}

// Every free node's force imbalance, summed here from the springs (not through the solver),
// relative to what the solver is allowed: max(1e-10 of the load, 1e-13 k l of the node's
// stiffest spring), times a margin of 100.
bool Balanced(const Problem& p, const ActiveSprings& springs, const PreparedLoadCase& lc,
              const Vector& u, std::string& detail) {
  const int d = p.dimension();
  const SpringGeometry& g = p.candidates();
  const FreeNodes& free = p.free_sets()[lc.free_set];
  Vector imbalance = Vector::Zero(d * free.count);
  std::vector<double> floor(free.count, 0.0);
  double load = 0.0;
  for (int i = 0; i < static_cast<int>(free.free_index.size()); ++i) {
    const int f = free.free_index[i];
    if (f >= 0) {
      imbalance.segment(d * f, d) = lc.force.segment(d * i, d);
      load = std::max(load, lc.force.segment(d * i, d).cwiseAbs().maxCoeff());
    }
  }
  const bool linear = p.response() == Response::kLinear;
  for (int a = 0; a < springs.size(); ++a) {
    const int s = springs.index[a];
    const int i = g.pairs[s].first, j = g.pairs[s].second;
    const Vector d0 = g.rest_separation.segment(d * s, d);
    const Vector du = u.segment(d * i, d) - u.segment(d * j, d);
    const double l = g.rest_length[s], k = springs.stiffness[a];
    Vector pull;  // the force on node i (minus on j)
    if (linear) {
      const Vector n = d0 / l;
      pull = -k * n.dot(du) * n;
    } else {
      const Vector x = d0 + du;
      pull = -k * (x.norm() - l) * x / x.norm();
    }
    for (const int node : {i, j}) {
      const int f = free.free_index[node];
      const double sign = node == i ? 1.0 : -1.0;
      if (f >= 0) {
        imbalance.segment(d * f, d) += sign * pull;
        floor[f] = std::max(floor[f], 1e-13 * k * l);
      } else {
        load = std::max(load, k * lc.prescribed.segment(d * node, d).norm());
      }
    }
  }
  for (int f = 0; f < free.count; ++f) {
    const double allowed = 100.0 * std::max(1e-10 * load, floor[f]);
    const double off = imbalance.segment(d * f, d).cwiseAbs().maxCoeff();
    if (!(off <= allowed)) {
      detail += "unbalanced free node " + std::to_string(f) + " by " + std::to_string(off / load) +
                " of the load; ";
      return false;
    }
  }
  return true;
}

Genome RandomGenome(Random& random, int genes, double density) {
  Genome genome(static_cast<std::size_t>(genes));
  for (auto& gene : genome) gene = Uniform(random, 0.0, 1.0) < density ? 1 : 0;
  return genome;
}

Scene Scaled(Scene s, double factor) {
  s.rest *= factor;
  s.candidates.radius *= factor;
  for (LoadCase& lc : s.load_cases) {
    for (NodalLoad& f : lc.forces) f.value *= factor;
    for (NodalLoad& u : lc.displacements) u.value *= factor;
  }
  return s;
}

}  // namespace

Scene MakeStressScene(std::uint64_t seed) {
  Random random(seed);
  static const char* const kKinds[] = {"grid2d", "grid3d", "jitter2d", "jitter3d",
                                       "line2d", "line3d", "strip2d"};
  const std::string kind = kKinds[UniformInt(random, 0, 6)];
  Scene s;
  s.name = "stress-" + std::to_string(seed) + "-" + kind;
  s.dimension = kind.back() == 'd' && kind[kind.size() - 2] == '3' ? 3 : 2;
  const int d = s.dimension;
  std::vector<double> points;
  double radius = 1.5;
  if (kind == "grid2d" || kind == "jitter2d" || kind == "grid3d" || kind == "jitter3d") {
    const int n = d == 2 ? UniformInt(random, 3, 7) : UniformInt(random, 2, 4);
    const double jitter = kind[0] == 'j' ? 0.3 : 0.0;
    const int count = d == 2 ? n * n : n * n * n;
    for (int i = 0; i < count; ++i) {
      const int ix = i % n, iy = (i / n) % n, iz = i / (n * n);
      points.push_back(ix + jitter * Uniform(random, -1, 1));
      points.push_back(iy + jitter * Uniform(random, -1, 1));
      if (d == 3) points.push_back(iz + jitter * Uniform(random, -1, 1));
    }
    radius = d == 2 ? 1.5 : 1.8;
  } else if (kind == "line2d" || kind == "line3d") {
    const int n = UniformInt(random, 8, 40);
    const double lateral = LogUniform(random, -9, -1);
    double x = 0.0;
    for (int i = 0; i < n; ++i) {
      x += Uniform(random, 0.2, 1.0);
      points.push_back(x);
      for (int a = 1; a < d; ++a) points.push_back(lateral * Uniform(random, -1, 1));
    }
    radius = Uniform(random, 1.5, 3.0);
  } else {  // strip2d: two rows of nodes, h apart
    const int n = UniformInt(random, 4, 30);
    const double h = LogUniform(random, -7, 0);
    for (int i = 0; i < n; ++i) {
      for (int row = 0; row < 2; ++row) {
        points.push_back(i);
        points.push_back(row * h);
      }
    }
    radius = std::sqrt(1.0 + h * h) * 1.01;
  }
  const double length = LogUniform(random, -6, 6);
  s.rest = Eigen::Map<Vector>(points.data(), static_cast<Eigen::Index>(points.size())) * length;
  const int nodes = s.node_count();
  s.candidates.kind = CandidateSpec::Kind::kRadius;
  s.candidates.radius = radius * length;
  // The reference: the candidates within the radius, some left out at random.
  const double spread = std::array<double, 4>{0, 2, 6, 12}[UniformInt(random, 0, 3)];
  // Half the references have every candidate (rigid unless the geometry is not), half lose
  // a twentieth of them at random (mechanisms among them: refused, and checked by SVD).
  const double dropout = Uniform(random, 0, 1) < 0.5 ? 0.0 : 0.05;
  for (int i = 0; i < nodes; ++i) {
    for (int j = i + 1; j < nodes; ++j) {
      if ((s.rest.segment(d * i, d) - s.rest.segment(d * j, d)).norm() > s.candidates.radius)
        continue;
      if (Uniform(random, 0, 1) < dropout) continue;
      s.reference.springs.push_back({i, j});
      s.reference.stiffness.push_back(LogUniform(random, 0, spread));
    }
  }
  if (s.reference.springs.empty()) s.reference.springs.push_back({0, 1});
  if (s.reference.stiffness.size() != s.reference.springs.size())
    s.reference.stiffness.assign(s.reference.springs.size(), 1.0);
  // Loads: the nodes with the smallest first coordinate fixed, the largest loaded.
  std::vector<int> order(nodes);
  for (int i = 0; i < nodes; ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return s.rest[d * a] < s.rest[d * b]; });
  const int side = std::max(d, nodes / 6);
  LoadCase force_case, displacement_case;
  force_case.name = "force";
  displacement_case.name = "displacement";
  std::vector<double> k_sorted = s.reference.stiffness;
  std::nth_element(k_sorted.begin(), k_sorted.begin() + k_sorted.size() / 2, k_sorted.end());
  const double k_median = k_sorted[k_sorted.size() / 2];
  for (LoadCase* lc : {&force_case, &displacement_case})
    lc->fixed.assign(order.begin(), order.begin() + side);
  NodalLoad force, displacement;
  force.nodes.assign(order.end() - side, order.end());
  displacement.nodes = force.nodes;
  Vector direction = Vector::Zero(d);
  for (int a = 0; a < d; ++a) direction[a] = Uniform(random, -1, 1);
  direction.normalize();
  force.value = direction * LogUniform(random, -9, 0) * k_median * length;
  displacement.value = direction * LogUniform(random, -9, 0.3) * length;
  force_case.forces.push_back(force);
  displacement_case.displacements.push_back(displacement);
  s.load_cases = {force_case, displacement_case};
  s.search.strategy = Strategy::kDirect;
  return s;
}

StressOutcome RunStressScene(std::uint64_t seed, double max_seconds) {
  const auto start = std::chrono::steady_clock::now();
  StressOutcome out;
  Scene scene = MakeStressScene(seed);
  out.kind = scene.name.substr(scene.name.rfind('-') + 1);
  // The reference's own verdict per load case, before anything else (its scene may be
  // refused below: a thin strip, nearly collinear nodes), against the SVD.
  {
    const SpringGeometry geometry(scene.dimension, scene.rest, scene.reference.springs);
    ActiveSprings springs;
    for (int m = 0; m < geometry.size(); ++m) {
      springs.index.push_back(m);
      springs.stiffness.push_back(scene.reference.stiffness[static_cast<std::size_t>(m)]);
    }
    for (const LoadCase& lc : scene.load_cases) {
      std::vector<bool> constrained(static_cast<std::size_t>(scene.node_count()), false);
      for (const int node : lc.fixed) constrained[static_cast<std::size_t>(node)] = true;
      for (const NodalLoad& u : lc.displacements) {
        for (const int node : u.nodes) constrained[static_cast<std::size_t>(node)] = true;
      }
      const FreeNodes free = FreeNodes::FromConstrained(constrained);
      if (scene.dimension * free.count > 400) continue;
      EquilibriumSolver solver(geometry, free);
      CheckModes(solver.RestStabilityOf(springs).modes, geometry, free, springs, out);
    }
  }
  std::unique_ptr<Problem> problem;
  try {
    problem = std::make_unique<Problem>(scene);
  } catch (const InputError& e) {
    out.refused = true;
    out.refusal = e.what();
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return out;
  }
  const Problem& p = *problem;
  Random random(seed ^ 0x9e3779b97f4a7c15ULL);
  CostFunction cost(p, {CostOptions::WarmStart::kReference, true, std::nullopt});

  // Random topologies: verdicts against the SVD, flags against the penalty, equilibria
  // against the forces.
  for (int t = 0; t < 3; ++t) {
    const Genome genome =
        RandomGenome(random, p.gene_count(), t == 0 ? 1.0 : Uniform(random, 0.5, 0.95));
    const ActiveSprings springs = p.SpringsFromMask(p.MaskFromGenome(genome));
    std::vector<Vector> u;
    const Evaluation e = cost.Evaluate(springs, &u);
    if (!std::isfinite(e.cost) || !std::isfinite(e.normalized_error)) {
      out.non_finite = true;
      out.detail += "non-finite evaluation; ";
    }
    int modes = 0;
    for (const LoadCaseEvaluation& c : e.load_cases) modes += c.solve.mechanism_modes;
    if (e.mechanism != (e.mechanism_modes > 0) || modes != e.mechanism_modes ||
        (e.mechanism && e.normalized_error != kPenaltyBase * (1.0 + e.mechanism_modes))) {
      out.inconsistent = true;
      out.detail += "flag, modes and penalty disagree; ";
    }
    for (std::size_t k = 0; k < p.load_cases().size(); ++k) {
      const PreparedLoadCase& lc = p.load_cases()[k];
      const FreeNodes& free = p.free_sets()[lc.free_set];
      if (p.dimension() * free.count <= 400) {
        const int engine = e.load_cases[k].solve.termination == Termination::kMechanism
                               ? e.load_cases[k].solve.mechanism_modes
                               : 0;
        CheckModes(engine, p.candidates(), free, springs, out);
      }
      if (e.load_cases[k].solve.converged() && !Balanced(p, springs, lc, u[k], out.detail))
        out.unbalanced = true;
    }
    // The same topology with every length scaled: the same normalised error.
    if (t == 0) {
      const double factor = LogUniform(random, -3, 3);
      try {
        const Problem scaled = Problem::Build(Scaled(scene, factor));
        const Evaluation es =
            CostFunction(scaled).Evaluate(scaled.SpringsFromMask(scaled.MaskFromGenome(genome)));
        // Per load case. Equal to 1e-9, or to what double precision resolves of these loads
        // if that is less: each solve balances forces to its loosest node's tolerance (1e-13
        // k l of its stiffest spring, relative to the load), which a load of 1e-8 of k l makes
        // 1e-5. And no finer than the reference itself is determined: round-off in its forces,
        // through a tangent that a stiffness spread near 1e12 or nearly collinear springs make
        // nearly singular, leaves its displacements uncertain by a fraction rho of their size
        // (ReferenceSolve::resolution), so e = |u^M - u^R|^2 / |u^R|^2 by about
        // 2 sqrt(e) rho + rho^2. A model that is no answer (e >= 1) under compression can have
        // several equilibria, and which one a solve finds may turn on round-off: there both
        // only have to be finite and agree on being stable.
        for (std::size_t k = 0; k < e.load_cases.size(); ++k) {
          const LoadCaseEvaluation &ca = e.load_cases[k], &cb = es.load_cases[k];
          const double a = ca.normalized_error, b = cb.normalized_error;
          const double allowed =
              std::max({1e-9, 10.0 * ca.solve.tolerance, 10.0 * cb.solve.tolerance});
          double rho = 0.0;
          for (const Problem* q : {&p, &scaled}) {
            const auto& solve = q->load_cases()[k].reference_solve;
            if (solve) rho = std::max(rho, solve->resolution);
          }
          const double by_reference =
              10.0 * (2.0 * std::sqrt(std::max({a, b, 0.0})) * rho + rho * rho);
          const double allowed_difference =
              std::max(allowed * std::max({std::abs(a), std::abs(b), 1e-3}), by_reference);
          const bool no_answer = std::min(a, b) >= 1.0 &&
                                 ca.solve.converged() == cb.solve.converged() &&
                                 e.mechanism == es.mechanism;
          if (!no_answer && !(std::abs(a - b) <= allowed_difference)) {
            out.scale_dependent = true;
            out.detail += "load_cases[" + std::to_string(k) + "]: normalised error " +
                          std::to_string(a) + " became " + std::to_string(b) + " with lengths x" +
                          std::to_string(factor) + " (allowed " + std::to_string(allowed) +
                          " relative, " + std::to_string(by_reference) + " by the reference); ";
          }
        }
      } catch (const InputError& error) {
        // Unless the refusal says that double precision cannot resolve the scene (a near
        // mechanism, whose solve may converge at one scale and not at another).
        if (std::string(error.what()).find("double precision") == std::string::npos) {
          out.scale_dependent = true;
          out.detail += std::string("refused only when scaled: ") + error.what() + "; ";
        }
      }
    }
  }

  // Strategy direct, bounded: never silently wrong.
  SearchSettings settings = scene.search;
  settings.max_seconds = max_seconds;
  const SearchOptions options = ResolveSearchOptions(settings, p.gene_count());
  const IdentificationResult r = RunIdentification(p, options);
  const double run_seconds = r.wall_seconds;
  if (run_seconds > max_seconds + 2.0) {
    out.hang = true;
    out.detail += "direct ran " + std::to_string(run_seconds) + " s; ";
  }
  if (!std::isfinite(r.evaluation.normalized_error)) {
    out.non_finite = true;
    out.detail += "non-finite result; ";
  }
  ActiveSprings model;
  for (std::size_t m = 0; m < r.springs.size(); ++m) {
    model.index.push_back(p.CandidateIndex(r.springs[m]));
    model.stiffness.push_back(r.stiffness[m]);
    if (!std::isfinite(r.stiffness[m]) || !(r.stiffness[m] > 0.0)) out.non_finite = true;
  }
  const Evaluation again = CostFunction(p).Evaluate(model);
  const bool stopped_early = r.stop == StopReason::kCancelled || r.stop == StopReason::kTimeLimit;
  const bool says_no_answer = r.stop == StopReason::kMechanism ||
                              r.stop == StopReason::kNoEquilibrium ||
                              r.stop == StopReason::kNotReproduced;
  if (!r.usable() && !says_no_answer && !stopped_early) {
    out.silent_wrong = true;
    out.detail += "unusable result with stop " + std::string(r.stop_message) + "; ";
  }
  if (again.mechanism != r.evaluation.mechanism ||
      !(std::abs(again.normalized_error - r.evaluation.normalized_error) <=
        1e-6 * std::max(again.normalized_error, 1e-9))) {
    out.silent_wrong = true;
    out.detail += "reported error " + std::to_string(r.evaluation.normalized_error) +
                  ", its model has " + std::to_string(again.normalized_error) + "; ";
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace springfit::examples
