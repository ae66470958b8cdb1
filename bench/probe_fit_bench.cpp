// The probe fit (engine/probe_fit/response_fit.h) on FEM and MSS references: the model's error
// on held-out probes by family beside the closed-form baseline's, the extreme generalised
// eigenvalues of (K_model, K_ref) on the user's supports, and the time of each step
// (bench/RESULTS.md, "Fitting the response").
//
//   build/bench/probe_fit_bench examples/fem-plate-5x5.json examples/fem-kidney-2d.json
//
// E is the relative RMS nodal error of one load, |u - u_ref| / |u_ref| over the free nodes,
// both responses linear at rest; times are wall seconds of one run on this machine.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "engine/api/problem.h"
#include "engine/fit/stiffness_fit.h"
#include "engine/probe_fit/generalization.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/probe_fit/response_fit.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/rest_stiffness.h"
#include "proto/names.h"
#include "proto/scene_codec.h"

namespace springfit {
namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

void PrintFamilies(const char* what, const std::vector<response::FamilyErrors>& families) {
  std::printf("    %-10s", what);
  for (const auto& f : families)
    std::printf("  %s %.3g (p95 %.3g)", response::ProbeFamilyName(f.family), f.errors.median,
                f.errors.p95);
  std::printf("\n");
}

// The cost per right-hand side of a support's solves against how many are solved together
// (SupportSystem::SolveColumns: one pass over the factor for all of them), on the bank's first
// support with the reference's factor; each count timed for about a second.
void PrintSolveTiming(const Problem& problem, const SparseMatrix& k_ref,
                      const response::ProbeBank& bank) {
  response::SupportSystem system(problem.dimension(), bank.supports[0].constrained);
  if (!system.Factorize(k_ref)) return;
  std::printf("  solves on support 0 (%d free degrees of freedom), ms per right-hand side:",
              system.free_dofs());
  for (const int columns : {1, 8, 32, 128}) {
    const Matrix b = Matrix::Random(system.free_dofs(), columns);
    const auto start = Clock::now();
    int repeats = 0;
    while (Seconds(start) < 1.0) {
      Matrix x = b;
      system.SolveColumns(x);
      ++repeats;
    }
    std::printf(" %d: %.3g", columns, 1e3 * Seconds(start) / repeats / columns);
  }
  std::printf("\n");
}

int Main(int argc, char** argv) {
  CLI::App app{"The probe fit on FEM and MSS references"};
  std::vector<std::string> files;
  std::uint64_t seed = 1;
  app.add_option("scenes", files, "scene files")->required();
  app.add_option("--seed", seed, "the probe bank's seed");
  int threads = 1;
  app.add_option("--threads", threads, "threads of the fit")->check(CLI::Range(1, 256));
  response::ResponseFitOptions defaults;
  app.add_option("--min-lambda", defaults.min_lambda, "ResponseFitOptions::min_lambda");
  app.add_option("--soft-mode-rounds", defaults.soft_mode_rounds,
                 "ResponseFitOptions::soft_mode_rounds");
  app.add_option("--soft-modes-per-round", defaults.soft_modes_per_round,
                 "ResponseFitOptions::soft_modes_per_round");
  app.add_option("--regularizations", defaults.regularizations,
                 "ResponseFitOptions::regularizations");
  app.add_option("--steps-per-strength", defaults.steps_per_strength,
                 "ResponseFitOptions::steps_per_strength");
  app.add_option("--cg-iterations", defaults.cg_iterations, "ResponseFitOptions::cg_iterations");
  app.add_option("--continuation-patience", defaults.continuation_patience,
                 "ResponseFitOptions::continuation_patience");
  app.add_option("--hold-weight", defaults.hold.weight, "ModeHoldOptions::weight");
  app.add_option("--hold-target", defaults.hold.target, "ModeHoldOptions::target");
  app.add_option("--lift", defaults.lift_soft_modes, "ResponseFitOptions::lift_soft_modes");
  app.add_option("--named-weight", defaults.probes.named_weight, "ProbeOptions::named_weight");
  app.add_option("--extra-supports", defaults.probes.extra_supports,
                 "ProbeOptions::extra_supports");
  bool solve_timing = false;
  app.add_flag("--solve-timing", solve_timing,
               "time the solves per right-hand side against how many run together, no fit");
  CLI11_PARSE(app, argc, argv);
  std::unique_ptr<WorkerPool> pool;
  if (threads > 1) pool = std::make_unique<WorkerPool>(threads);
  for (const std::string& file : files) {
    const auto t0 = Clock::now();
    const Problem problem(proto::LoadSceneFile(file));
    std::printf("%s: %d genes, prepared in %.2f s\n", file.c_str(), problem.gene_count(),
                Seconds(t0));
    const auto t1 = Clock::now();
    const SparseMatrix k_ref = ReferenceRestStiffness(problem);
    response::ResponseFitOptions options = defaults;
    options.probes.seed = seed;
    const response::ProbeBanks banks = response::MakeProbeBanks(problem, k_ref, options.probes);
    const response::ProbeBank& bank = banks.fit;
    std::printf("  probe bank: %zu probes (and %d held out) on %zu supports, %.2f s\n",
                bank.probes.size(), banks.held_out.size(), bank.supports.size(), Seconds(t1));
    if (solve_timing) {
      PrintSolveTiming(problem, k_ref, bank);
      continue;
    }
    std::vector<double> prior;
    if (const auto baseline = BaselineGeneWeights(problem))
      prior = *baseline;
    else
      prior.assign(static_cast<std::size_t>(problem.gene_count()), problem.training_stiffness());
    const auto t2 = Clock::now();
    const response::ResponseFitResult fit =
        response::FitResponse(problem, bank, k_ref, prior, options, nullptr, {}, pool.get());
    // (The returned fit's phases: after a soft-mode refit, the refit's.)
    std::printf(
        "  fit: %.2f s (Gauss-Newton continuation %.2f s, spring budget %.2f s), %d springs, "
        "regularisation %g, %d GN steps\n",
        Seconds(t2), fit.seconds_continuation, fit.seconds_budget, PresentSprings(fit.weights),
        fit.regularization, fit.gauss_newton_accepted);
    std::printf("    %s fit, strengths:", fit.method.c_str());
    for (std::size_t i = 0; i < fit.regularizations.size(); ++i)
      std::printf(" %g:%.3g (lambda %.3g)", fit.regularizations[i],
                  fit.regularization_select_errors[i], fit.regularization_lambda_min[i]);
    std::printf("\n    soft modes (probes: springs, choosing error, lambda):");
    for (const auto& m : fit.soft_mode_rounds)
      std::printf(" %s%d: %d %.3g %.3g", m.lifted ? "lift " : "", m.probes, m.springs,
                  m.select_error, m.lambda_min);
    std::printf(" (chosen %d)", fit.soft_mode_chosen);
    std::printf("\n    path:");
    for (const auto& p : fit.path) std::printf(" %d:%.3g", p.springs, p.select_error);
    std::printf("  (chosen %d)\n", fit.chosen);
    // The certificate: the held-out probes and the named cases, and the pencil per user support.
    const auto t3 = Clock::now();
    const response::Generalization g =
        response::Certifier(problem, bank, banks.held_out, k_ref)
            .Certify(fit.weights, SpringRestStiffness(problem, prior));
    PrintFamilies("model", g.model);
    PrintFamilies("baseline", g.baseline);
    for (const auto& pencil : g.pencils) {
      std::printf(
          "    %s: model lambda [%.3g, %.3g] bound %.3g; baseline [%.3g, %.3g] bound %.3g\n",
          pencil.support.c_str(), pencil.model.lambda_min, pencil.model.lambda_max,
          pencil.model.Bound(), pencil.baseline.lambda_min, pencil.baseline.lambda_max,
          pencil.baseline.Bound());
    }
    std::printf("  certificate: %.2f s\n", Seconds(t3));
  }
  return 0;
}

}  // namespace
}  // namespace springfit

int main(int argc, char** argv) {
  return springfit::Main(argc, argv);
}
