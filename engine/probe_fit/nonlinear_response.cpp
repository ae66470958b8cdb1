#include "engine/probe_fit/nonlinear_response.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include "engine/probe_fit/probe_evaluation.h"
#include "engine/runtime/options_check.h"

namespace springfit::response {
namespace {

// The probes of `role` in the bank: the named ones all, the generated ones evenly spread up to
// `limit`.
std::vector<int> CaseProbes(const ProbeBank& bank, ProbeRole role, int limit) {
  std::vector<int> named, generated;
  for (std::size_t p = 0; p < bank.probes.size(); ++p) {
    const Probe& probe = bank.probes[p];
    if (probe.role != role || !(probe.reference_norm2 > 0.0)) continue;
    (probe.family == ProbeFamily::kNamed ? named : generated).push_back(static_cast<int>(p));
  }
  std::vector<int> all = EvenlySpread(generated, limit);
  all.insert(all.end(), named.begin(), named.end());
  std::sort(all.begin(), all.end());
  return all;
}

// The free degrees of freedom of a support's free nodes, in free-node order (EquilibriumSolver's).
Vector FreePart(const Vector& full, const FreeNodes& free, int d) {
  Vector out(static_cast<Eigen::Index>(free.count) * d);
  for (std::size_t node = 0; node < free.free_index.size(); ++node) {
    const int i = free.free_index[node];
    if (i >= 0) out.segment(i * d, d) = full.segment(static_cast<Eigen::Index>(node) * d, d);
  }
  return out;
}

double FreeNorm2(const Vector& full, const FreeNodes& free, int d) {
  return FreePart(full, free, d).squaredNorm();
}

FreeNodes FreeOf(const ProbeBank& bank, const Probe& probe) {
  return FreeNodes::FromConstrained(
      bank.supports[static_cast<std::size_t>(probe.support)].constrained);
}

// The model of per-gene `weights` as active springs over the problem's candidates, with the
// candidates no load case sees at their stiffness (as ModelOfWeights).
ActiveSprings ActiveOf(const Problem& problem, const std::vector<double>& weights) {
  ActiveSprings a;
  for (std::size_t g = 0; g < weights.size(); ++g) {
    if (!(weights[g] > 0.0)) continue;
    a.index.push_back(problem.gene_candidates()[g]);
    a.stiffness.push_back(weights[g]);
  }
  for (std::size_t u = 0; u < problem.unidentifiable().size(); ++u) {
    a.index.push_back(problem.unidentifiable()[u]);
    a.stiffness.push_back(problem.unidentifiable_stiffness()[u]);
  }
  return a;
}

// Runs f(i) for i < count on the pool (or here), the owner polling for a stop meanwhile.
void ForEach(WorkerPool* pool, int count, const std::function<void(std::size_t)>& f,
             Interruption* interruption) {
  RunSlots(
      pool, count, [&](int slot) { f(static_cast<std::size_t>(slot)); },
      [interruption] {
        if (interruption) interruption->Check();
      });
  ThrowIfInterrupted(interruption);
}

// The groups of consecutive cases of one probe: [begin, end) index pairs.
std::vector<std::pair<std::size_t, std::size_t>> ByProbe(const std::vector<NonlinearCase>& cases) {
  std::vector<std::pair<std::size_t, std::size_t>> groups;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    if (groups.empty() || cases[groups.back().first].probe != cases[i].probe)
      groups.emplace_back(i, i);
    groups.back().second = i + 1;
  }
  return groups;
}

}  // namespace

void NonlinearFitOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  CheckAmplitudes(check, amplitudes);
  check.Require(max_fitted_probes >= 0, "max_fitted_probes", max_fitted_probes, "value >= 0");
  check.Require(max_bytes >= 0.0 && std::isfinite(max_bytes), "max_bytes", max_bytes,
                "0 <= value < infinity");
  check.Require(max_choosing_probes >= 1, "max_choosing_probes", max_choosing_probes, "value >= 1");
  check.Require(!regularizations.empty(), "regularizations", 0.0, "at least one strength");
  for (double r : regularizations) check.Require(r >= 0.0, "regularizations", r, "each >= 0");
  check.Require(steps_per_strength >= 1, "steps_per_strength", steps_per_strength, "value >= 1");
  check.Require(chord_contraction >= 0.0 && chord_contraction < 1.0, "chord_contraction",
                chord_contraction, "0 <= value < 1");
}

NonlinearCases::NonlinearCases(const Problem& problem, const ProbeBank& bank,
                               const std::vector<double>& fit_weight,
                               const NonlinearFitOptions& options, Interruption* interruption,
                               WorkerPool* pool)
    : problem_(problem),
      bank_(bank),
      interruption_(interruption),
      pool_(pool),
      solver_options_(LoadStepSolverOptions(problem)) {
  options.Validate();
  solver_options_.chord_contraction = options.chord_contraction;
  const int d = problem.dimension();
  const std::vector<int> fitted = FittedWithinMemory(options);
  const std::vector<int> choosing =
      CaseProbes(bank, ProbeRole::kSelect, options.max_choosing_probes);
  std::vector<int> all = fitted;
  all.insert(all.end(), choosing.begin(), choosing.end());
  const std::size_t amplitudes = options.amplitudes.size();
  // Per probe of `all` and amplitude: the reference's equilibrium (empty: none).
  std::vector<std::vector<Vector>> reference(all.size(), std::vector<Vector>(amplitudes));
  const ReferenceModel model(problem);
  ForEach(
      pool_, static_cast<int>(all.size()),
      [&](std::size_t i) {
        const Probe& probe = bank.probes[static_cast<std::size_t>(all[i])];
        ReferenceSolver solver(model.fem, model.springs, FreeOf(bank, probe), problem,
                               interruption);
        for (std::size_t a = 0; a < amplitudes; ++a) {
          const ScaledLoad load = ScaleLoad(probe.force, probe.prescribed, options.amplitudes[a]);
          if (std::optional<Vector> u = solver.Solve(load.force, load.prescribed))
            reference[i][a] = std::move(*u);
        }
      },
      interruption);

  // Each family's share of the rest-linear objective, spread over its cases.
  std::map<ProbeFamily, double> share;
  std::map<ProbeFamily, int> count;
  for (std::size_t p = 0; p < bank.probes.size(); ++p)
    share[bank.probes[p].family] += fit_weight[p] * bank.probes[p].reference_norm2;
  for (std::size_t i = 0; i < fitted.size(); ++i)
    for (std::size_t a = 0; a < amplitudes; ++a)
      if (reference[i][a].size() > 0)
        ++count[bank.probes[static_cast<std::size_t>(fitted[i])].family];
  for (std::size_t i = 0; i < all.size(); ++i) {
    const bool fit = i < fitted.size();
    const Probe& probe = bank.probes[static_cast<std::size_t>(all[i])];
    const FreeNodes free = FreeOf(bank, probe);
    for (std::size_t a = 0; a < amplitudes; ++a) {
      if (reference[i][a].size() == 0) continue;
      NonlinearCase c{all[i], options.amplitudes[a], std::move(reference[i][a]), 0.0};
      const double norm2 = FreeNorm2(c.reference, free, d);
      if (!(norm2 > 0.0)) continue;
      if (fit) {
        c.weight = share[probe.family] / count[probe.family] / norm2;
        if (!(c.weight > 0.0)) continue;
      }
      (fit ? fitted_ : choosing_).push_back(std::move(c));
    }
  }
}

std::vector<int> NonlinearCases::FittedWithinMemory(const NonlinearFitOptions& options) {
  std::vector<int> fitted = CaseProbes(bank_, ProbeRole::kFit, options.max_fitted_probes);
  if (!(options.max_bytes > 0.0)) return fitted;
  const int d = problem_.dimension();
  const double nodes = static_cast<double>(problem_.scene().node_count());
  const EquilibriumSolver free_body(
      problem_.candidates(),
      FreeNodes::FromConstrained(std::vector<bool>(problem_.scene().node_count(), false)),
      solver_options_);
  // (the solver; the reference's equilibrium; in each of two responses a part, its per-gene
  // columns and stretches, residual and equilibrium)
  case_bytes_ = free_body.Bytes() + 8.0 * d * nodes +
                2.0 * (static_cast<double>(problem_.gene_count()) * (sizeof(SpringColumn) + 8.0) +
                       16.0 * d * nodes);
  const double amplitudes = static_cast<double>(options.amplitudes.size());
  // (clamped in double: a bound far above any bank must not overflow the count)
  const auto probes_within = static_cast<long long>(std::min(
      std::floor(options.max_bytes / (case_bytes_ * amplitudes)), static_cast<double>(1LL << 40)));
  if (static_cast<long long>(fitted.size()) <= probes_within) return fitted;
  int named = 0;
  for (int p : fitted)
    named += bank_.probes[static_cast<std::size_t>(p)].family == ProbeFamily::kNamed;
  const auto generated = static_cast<int>(std::max<long long>(probes_within - named, 0));
  const std::vector<int> within = CaseProbes(bank_, ProbeRole::kFit, generated);
  left_for_memory_ = static_cast<int>(fitted.size() - within.size());
  return within;
}

double NonlinearCases::ChoosingError(const std::vector<double>& weights, int* failed) const {
  const int d = problem_.dimension();
  const SpringModel springs = ModelOfWeights(problem_, weights);
  const SpringSolverInput input(problem_.scene(), springs);
  const auto groups = ByProbe(choosing_);
  // Per group: the RMS of E over its amplitudes, and its failed cases.
  std::vector<double> error(groups.size());
  std::vector<int> misses(groups.size(), 0);
  ForEach(
      pool_, static_cast<int>(groups.size()),
      [&](std::size_t g) {
        const auto [begin, end] = groups[g];
        const Probe& probe = bank_.probes[static_cast<std::size_t>(choosing_[begin].probe)];
        const FreeNodes free = FreeOf(bank_, probe);
        SpringResponse solver(input, free, solver_options_, interruption_);
        double sum = 0.0;
        for (std::size_t i = begin; i < end; ++i) {
          const ScaledLoad load = ScaleLoad(probe.force, probe.prescribed, choosing_[i].amplitude);
          const std::optional<Vector> u = solver.Solve(load.force, load.prescribed);
          double e = 1.0;
          if (u && InvertedElements(problem_.scene(), *u) == 0)
            e = std::min(1.0, RelativeError(*u, choosing_[i].reference, free, d));
          else
            ++misses[g];
          sum += e * e;
        }
        error[g] = std::sqrt(sum / static_cast<double>(end - begin));
      },
      interruption_);
  std::vector<double> per_probe(bank_.probes.size(), std::numeric_limits<double>::quiet_NaN());
  for (std::size_t g = 0; g < groups.size(); ++g)
    per_probe[static_cast<std::size_t>(choosing_[groups[g].first].probe)] = error[g];
  if (failed) {
    *failed = 0;
    for (int m : misses) *failed += m;
  }
  return FamilyBalancedRms(bank_, per_probe);
}

std::unique_ptr<EquilibriumSolver> NonlinearCases::TakeSolver(std::size_t fitted_case) const {
  {
    const std::lock_guard lock(spare_mutex_);
    if (spare_solvers_.size() == fitted_.size() && spare_solvers_[fitted_case])
      return std::move(spare_solvers_[fitted_case]);
  }
  const Probe& probe = bank_.probes[static_cast<std::size_t>(fitted_[fitted_case].probe)];
  ++solvers_built_;
  return std::make_unique<EquilibriumSolver>(problem_.candidates(), FreeOf(bank_, probe),
                                             solver_options_);
}

void NonlinearCases::ReturnSolvers(std::vector<std::unique_ptr<EquilibriumSolver>>& solvers) const {
  const std::lock_guard lock(spare_mutex_);
  spare_solvers_.resize(fitted_.size());
  for (std::size_t i = 0; i < solvers.size() && i < fitted_.size(); ++i)
    if (solvers[i]) spare_solvers_[i] = std::move(solvers[i]);
  solvers.clear();
}

int NonlinearCases::StartFrom(const std::vector<double>& start_errors) {
  std::map<ProbeFamily, double> share_before, share_kept;
  std::vector<NonlinearCase> kept;
  std::vector<std::unique_ptr<EquilibriumSolver>> kept_solvers;
  const std::lock_guard lock(spare_mutex_);
  const bool spares = spare_solvers_.size() == fitted_.size();
  for (std::size_t i = 0; i < fitted_.size(); ++i) {
    const ProbeFamily family = bank_.probes[static_cast<std::size_t>(fitted_[i].probe)].family;
    share_before[family] += fitted_[i].weight;
    const double e =
        i < start_errors.size() ? start_errors[i] : std::numeric_limits<double>::quiet_NaN();
    if (std::isnan(e)) continue;
    share_kept[family] += fitted_[i].weight;
    kept.push_back(std::move(fitted_[i]));
    if (e > 1.0) kept.back().weight /= e * e;
    if (spares) kept_solvers.push_back(std::move(spare_solvers_[i]));
  }
  const int left_out = static_cast<int>(fitted_.size() - kept.size());
  if (left_out > 0) {
    for (NonlinearCase& c : kept) {
      const ProbeFamily family = bank_.probes[static_cast<std::size_t>(c.probe)].family;
      c.weight *= share_before[family] / share_kept[family];
    }
  }
  fitted_ = std::move(kept);
  spare_solvers_ = std::move(kept_solvers);
  return left_out;
}

NonlinearResponse::NonlinearResponse(const NonlinearCases& cases, const GeneSprings& springs,
                                     const Vector& scale, Interruption* interruption,
                                     WorkerPool* pool)
    : SpringSensitivities(scale, springs.size(), interruption, pool),
      cases_(&cases),
      springs_(&springs) {}

NonlinearResponse::~NonlinearResponse() {
  cases_->ReturnSolvers(solvers_);
}

bool NonlinearResponse::At(const std::vector<double>& weights) {
  const Problem& problem = cases_->problem();
  const ProbeBank& bank = cases_->bank();
  const std::vector<NonlinearCase>& cases = cases_->fitted();
  const int d = problem.dimension();
  active_ = ActiveOf(problem, weights);
  const ActiveSprings& active = active_;
  const SpringGeometry& geometry = problem.candidates();
  const std::vector<int>& gene_candidate = problem.gene_candidates();
  parts_.assign(cases.size(), Part{});
  case_errors_.assign(cases.size(), std::numeric_limits<double>::quiet_NaN());
  cases_->ReturnSolvers(solvers_);
  solvers_.resize(cases.size());
  equilibria_.assign(cases.size(), Vector());
  const auto groups = ByProbe(cases);
  std::vector<char> held(groups.size(), 0);
  ForEach(
      pool_, static_cast<int>(groups.size()),
      [&](std::size_t g) {
        const auto [begin, end] = groups[g];
        const Probe& probe = bank.probes[static_cast<std::size_t>(cases[begin].probe)];
        const FreeNodes free = FreeOf(bank, probe);
        Vector u = Vector::Zero(static_cast<Eigen::Index>(problem.scene().rest.size()));
        for (std::size_t i = begin; i < end; ++i) {
          solvers_[i] = cases_->TakeSolver(i);
          EquilibriumSolver& solver = *solvers_[i];
          solver.set_interruption(interruption_);
          if (i == begin && solver.RestMechanismModes(active) != 0) return;
          // A load step: from the last amplitude's equilibrium, scaled (its linear
          // prediction), and its tangent, which its adjoint factorised.
          const EquilibriumSolver* previous = nullptr;
          if (i > begin) {
            u *= cases[i].amplitude / cases[i - 1].amplitude;
            previous = solvers_[i - 1].get();
          }
          const ScaledLoad load = ScaleLoad(probe.force, probe.prescribed, cases[i].amplitude);
          const EquilibriumSummary summary =
              solver.Solve(active, load.force, load.prescribed, u, previous);
          if (summary.termination == Termination::kInterrupted) throw Interrupted();
          // (No equilibrium, or one that is not a minimum of the energy, or one that turns an
          // element of the FEM mesh inside out: the model folds, a failure as in the choice.)
          if (!summary.converged() || !solver.FactorizeTangent(active, u) ||
              InvertedElements(problem.scene(), u) > 0)
            return;
          equilibria_[i] = u;
          Part& part = parts_[i];
          part.key = i;
          const double root = std::sqrt(cases[i].weight);
          const Vector error = FreePart(u - cases[i].reference, free, d);
          part.residual = root * error;
          case_errors_[i] = std::sqrt(error.squaredNorm() / FreeNorm2(cases[i].reference, free, d));
          // Per gene: dL/du on the free degrees of freedom and the stretch L - l at u.
          part.columns.resize(static_cast<std::size_t>(springs_->size()));
          part.elongation.resize(springs_->size(), 1);
          for (int e = 0; e < springs_->size(); ++e) {
            const NodePair pair = springs_->pairs[static_cast<std::size_t>(e)];
            const auto c = static_cast<std::size_t>(gene_candidate[static_cast<std::size_t>(e)]);
            const Vector current =
                (problem.scene().rest.segment(d * pair.second, d) + u.segment(d * pair.second, d)) -
                (problem.scene().rest.segment(d * pair.first, d) + u.segment(d * pair.first, d));
            const double length = current.norm();
            part.elongation(e, 0) = root * (length - geometry.rest_length[c]);
            SpringColumn& column = part.columns[static_cast<std::size_t>(e)];
            column.count = 0;
            for (int side = 0; side < 2; ++side) {
              const int node = side == 0 ? pair.first : pair.second;
              const int index = free.free_index[static_cast<std::size_t>(node)];
              if (index < 0 || !(length > 0.0)) continue;
              const double sign = side == 0 ? -1.0 : 1.0;
              for (int a = 0; a < d; ++a) {
                column.index[column.count] = d * index + a;
                column.value[column.count] = sign * current[a] / length;
                ++column.count;
              }
            }
          }
        }
        held[g] = 1;
      },
      interruption_);
  return std::find(held.begin(), held.end(), 0) == held.end();
}

void NonlinearResponse::Idle() {
  cases_->ReturnSolvers(solvers_);
  solvers_.resize(cases_->fitted().size());
}

void NonlinearResponse::Solve(std::size_t part, Matrix& b) const {
  if (!solvers_[part]) {
    std::unique_ptr<EquilibriumSolver> solver = cases_->TakeSolver(part);
    // (At() factorised this tangent at this equilibrium: it is positive definite again.)
    if (!solver->FactorizeTangent(active_, equilibria_[part]))
      throw std::logic_error("NonlinearResponse: an idle part's tangent lost its factorisation");
    solvers_[part] = std::move(solver);
  }
  for (Eigen::Index j = 0; j < b.cols(); ++j) {
    Vector column = b.col(j);
    solvers_[part]->SolveTangent(column);
    b.col(j) = column;
  }
}

}  // namespace springfit::response
