#include "engine/probe_fit/probe_evaluation.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include <Eigen/Eigenvalues>

#include "engine/search/random_stream.h"

namespace springfit::response {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
// Lanczos stops where the next basis vector's B-norm falls below this fraction of the last
// diagonal entry: the Krylov space is exhausted (an invariant subspace found), and one more
// vector would be round-off.
constexpr double kLanczosBreakdown = 1e-12;

double Quantile(std::vector<double> sorted, double q) {
  std::sort(sorted.begin(), sorted.end());
  const double position = q * static_cast<double>(sorted.size() - 1);
  const auto below = static_cast<std::size_t>(std::floor(position));
  const std::size_t above = std::min(below + 1, sorted.size() - 1);
  if (std::isinf(sorted[above]) || std::isinf(sorted[below]))
    return sorted[above];  // (an interpolation with infinity)
  return sorted[below] + (position - static_cast<double>(below)) * (sorted[above] - sorted[below]);
}

// Lanczos on B^-1 A in the B inner product (`b` holds B's factor), full reorthogonalisation:
// the basis (free degrees of freedom, B-orthonormal) and the tridiagonal matrix.
struct PencilLanczos {
  std::vector<Vector> basis;
  Matrix t;
};
PencilLanczos RunPencilLanczos(const SupportSystem& a, const SupportSystem& b, int iterations,
                               std::uint64_t seed, Interruption* interruption = nullptr) {
  const int n = a.free_dofs();
  RandomStream random(seed);
  Vector q(n);
  for (int i = 0; i < n; ++i) q[i] = random.Uniform() - 0.5;
  const int steps = std::min(iterations, n);
  PencilLanczos l;
  std::vector<Vector> b_basis;  // B q_j
  std::vector<double> alpha, beta;
  Vector bq = b.Multiply(q);
  double norm = std::sqrt(q.dot(bq));
  q /= norm;
  bq /= norm;
  for (int j = 0; j < steps; ++j) {
    if (interruption && interruption->Check()) throw Interrupted();
    l.basis.push_back(q);
    b_basis.push_back(bq);
    const Vector aq = a.Multiply(q);
    alpha.push_back(q.dot(aq));
    Vector w = aq;
    b.Solve(w);                           // B^-1 A q
    for (int pass = 0; pass < 2; ++pass)  // full reorthogonalisation, twice
      for (std::size_t i = 0; i < l.basis.size(); ++i) w -= b_basis[i].dot(w) * l.basis[i];
    const Vector bw = b.Multiply(w);
    const double next = std::sqrt(std::max(w.dot(bw), 0.0));
    if (!(next > kLanczosBreakdown * std::abs(alpha.back()))) break;
    beta.push_back(next);
    q = w / next;
    bq = bw / next;
  }
  const int k = static_cast<int>(alpha.size());
  l.t = Matrix::Zero(k, k);
  for (int i = 0; i < k; ++i) {
    l.t(i, i) = alpha[static_cast<std::size_t>(i)];
    if (i + 1 < k) l.t(i, i + 1) = l.t(i + 1, i) = beta[static_cast<std::size_t>(i)];
  }
  return l;
}

// The largest eigenvalue of B^-1 A.
double LargestPencilEigenvalue(const SupportSystem& a, const SupportSystem& b, int iterations,
                               std::uint64_t seed, Interruption* interruption = nullptr) {
  const PencilLanczos l = RunPencilLanczos(a, b, iterations, seed, interruption);
  Eigen::SelfAdjointEigenSolver<Matrix> eig(l.t, Eigen::EigenvaluesOnly);
  return eig.eigenvalues().maxCoeff();
}

}  // namespace

std::vector<double> ProbeErrorsFor(const ProbeBank& bank, const SparseMatrix& model,
                                   const std::vector<bool>& include, Interruption* interruption,
                                   const FactorizedOn& factorized, ToolSolves tool_solves) {
  const auto check = [interruption] {
    if (interruption && interruption->Check()) throw Interrupted();
  };
  std::vector<double> errors(bank.probes.size(), kNaN);
  const int d = bank.probes.empty() ? 2
                                    : static_cast<int>(bank.probes[0].force.size()) /
                                          static_cast<int>(bank.supports[0].constrained.size());
  std::vector<std::vector<std::size_t>> mine(bank.supports.size());
  for (std::size_t p = 0; p < bank.probes.size(); ++p)
    if (include[p]) mine[static_cast<std::size_t>(bank.probes[p].support)].push_back(p);
  // The errors of support s's probes, solved with `system` (held: factorised).
  const auto judge = [&](std::size_t s, const SupportSystem& system, bool held) {
    if (!held) {
      for (std::size_t p : mine[s]) errors[p] = kInf;
      return;
    }
    // The probes' solves in batches of 16 (one pass over the factor each), a stop check
    // before every batch.
    for (std::size_t first = 0; first < mine[s].size(); first += 16) {
      check();
      const std::size_t count = std::min<std::size_t>(16, mine[s].size() - first);
      Matrix u(system.free_dofs(), static_cast<Eigen::Index>(count));
      for (std::size_t j = 0; j < count; ++j) {
        const Probe& probe = bank.probes[mine[s][first + j]];
        u.col(static_cast<Eigen::Index>(j)) = system.RightHandSide(probe.force, probe.prescribed);
      }
      system.SolveColumns(u);
      for (std::size_t j = 0; j < count; ++j) {
        const Probe& probe = bank.probes[mine[s][first + j]];
        const double e2 =
            (u.col(static_cast<Eigen::Index>(j)) - system.Gather(probe.reference)).squaredNorm();
        errors[mine[s][first + j]] = std::sqrt(e2 / probe.reference_norm2);
      }
    }
  };
  // Per support that is no tool load's, its probes, then those of the tool loads on it, each
  // solved through its factor (support_system.h), which is factorised once for them all.
  std::vector<std::vector<std::size_t>> tools(bank.supports.size());
  for (std::size_t s = 0; s < bank.supports.size(); ++s)
    if (bank.supports[s].base >= 0 && !mine[s].empty())
      tools[static_cast<std::size_t>(bank.supports[s].base)].push_back(s);
  for (std::size_t s = 0; s < bank.supports.size(); ++s) {
    if (bank.supports[s].base >= 0 || (mine[s].empty() && tools[s].empty())) continue;
    check();
    const SupportSystem* given = factorized ? factorized(s) : nullptr;
    std::optional<SupportSystem> own;
    if (!given) own.emplace(d, bank.supports[s].constrained);
    const bool held = given || own->Factorize(model);
    const SupportSystem& system = given ? *given : *own;
    judge(s, system, held);
    for (std::size_t t : tools[s]) {
      check();
      const SupportSystem* given_tool = factorized ? factorized(t) : nullptr;
      std::optional<SupportSystem> own_tool;
      const bool through_base = held && tool_solves == ToolSolves::kThroughBase;
      if (!given_tool)
        own_tool.emplace(d, bank.supports[t].constrained, through_base ? &system : nullptr);
      const bool tool_held = given_tool || own_tool->Factorize(model);
      judge(t, given_tool ? *given_tool : *own_tool, tool_held);
    }
  }
  return errors;
}

ErrorSummary Summarize(const std::vector<double>& errors) {
  std::vector<double> values;
  for (double e : errors)
    if (!std::isnan(e)) values.push_back(e);
  ErrorSummary s;
  s.probes = static_cast<int>(values.size());
  if (values.empty()) return s;
  s.median = Quantile(values, 0.5);
  s.p95 = Quantile(values, 0.95);
  double sum = 0.0;
  for (double e : values) sum += e * e;
  s.rms = std::sqrt(sum / static_cast<double>(values.size()));
  return s;
}

std::vector<FamilyErrors> SummarizeByFamily(const ProbeBank& bank,
                                            const std::vector<double>& errors) {
  std::vector<FamilyErrors> out;
  for (int f = 0; f < kProbeFamilies; ++f) {
    std::vector<double> mine;
    for (std::size_t p = 0; p < bank.probes.size(); ++p)
      if (static_cast<int>(bank.probes[p].family) == f && !std::isnan(errors[p]))
        mine.push_back(errors[p]);
    if (mine.empty()) continue;
    out.push_back({static_cast<ProbeFamily>(f), Summarize(mine)});
  }
  return out;
}

double FamilyBalancedRms(const ProbeBank& bank, const std::vector<double>& errors) {
  const std::vector<FamilyErrors> families = SummarizeByFamily(bank, errors);
  if (families.empty()) return kNaN;
  double sum = 0.0;
  for (const FamilyErrors& f : families) sum += f.errors.rms * f.errors.rms;
  return std::sqrt(sum / static_cast<double>(families.size()));
}

double PencilExtremes::Bound() const {
  if (!(lambda_min > 0.0)) return kInf;
  return std::max(1.0 / lambda_min - 1.0, 1.0 - 1.0 / lambda_max);
}

double SmallestGeneralizedEigenvalue(const SparseMatrix& model, const SupportSystem& reference,
                                     int iterations, Interruption* interruption) {
  SupportSystem m(reference.dimension(), reference.constrained());
  if (!m.Factorize(model)) return 0.0;
  return SmallestGeneralizedEigenvalue(m, reference, iterations, interruption);
}

double SmallestGeneralizedEigenvalue(const SupportSystem& model, const SupportSystem& reference,
                                     int iterations, Interruption* interruption) {
  return 1.0 / LargestPencilEigenvalue(reference, model, iterations, kSmallestEigenvalueSeed,
                                       interruption);
}

LowestModes SmallestGeneralizedEigenpairs(const SupportSystem& model,
                                          const SupportSystem& reference, double below, int count,
                                          int iterations, Interruption* interruption) {
  // The largest eigenvalues of K_model^-1 K_ref are the smallest of the pencil, inverted; the
  // same Lanczos run as SmallestGeneralizedEigenvalue's (its seed), so the first is its value.
  const PencilLanczos l =
      RunPencilLanczos(reference, model, iterations, kSmallestEigenvalueSeed, interruption);
  const Eigen::SelfAdjointEigenSolver<Matrix> eig(l.t);
  const Vector none = Vector::Zero(static_cast<Eigen::Index>(
      reference.constrained().size() * static_cast<std::size_t>(reference.dimension())));
  LowestModes lowest;
  lowest.lambda_min = 1.0 / eig.eigenvalues().maxCoeff();
  for (Eigen::Index j = l.t.rows() - 1; j >= 0 && static_cast<int>(lowest.modes.size()) < count;
       --j) {
    const double lambda = 1.0 / eig.eigenvalues()[j];
    if (!(lambda < below)) break;
    Vector free = Vector::Zero(reference.free_dofs());
    for (std::size_t i = 0; i < l.basis.size(); ++i)
      free += eig.eigenvectors()(static_cast<Eigen::Index>(i), j) * l.basis[i];
    lowest.modes.push_back({lambda, reference.Scatter(free, none)});
  }
  return lowest;
}

std::vector<SoftMode> SoftModes(const SparseMatrix& model, const SupportSystem& reference,
                                double below, int count, int iterations,
                                Interruption* interruption) {
  SupportSystem m(reference.dimension(), reference.constrained());
  if (!m.Factorize(model)) return {};
  return SmallestGeneralizedEigenpairs(m, reference, below, count, iterations, interruption).modes;
}

PencilExtremes PencilExtremesOn(const SparseMatrix& model, const SparseMatrix& reference,
                                SupportSystem m, SupportSystem r, int iterations,
                                Interruption* interruption) {
  PencilExtremes x;
  if (!r.Factorize(reference)) return x;  // (callers pass supports that hold the reference)
  if (interruption && interruption->Check()) throw Interrupted();
  const bool held = m.Factorize(model);
  x.lambda_max = LargestPencilEigenvalue(m, r, iterations, kLargestEigenvalueSeed, interruption);
  if (held)
    x.lambda_min =
        1.0 / LargestPencilEigenvalue(r, m, iterations, kSmallestEigenvalueSeed, interruption);
  return x;
}

PencilExtremes GeneralizedEigenvalueExtremes(const SparseMatrix& model,
                                             const SparseMatrix& reference,
                                             const std::vector<bool>& constrained, int dimension,
                                             int iterations, Interruption* interruption) {
  return PencilExtremesOn(model, reference, SupportSystem(dimension, constrained),
                          SupportSystem(dimension, constrained), iterations, interruption);
}

}  // namespace springfit::response
