// The continuous stiffness fit (engine/fit/stiffness_fit.h) on FEM references: the floor a
// per-spring stiffness reaches on the mesh's own edges (the bounded least-squares fit the
// closed-form recipe is judged against, issue 16) and on the whole candidate set, beside the
// closed-form baseline (bench/RESULTS.md, "Identification on FEM references").
//
//   build/bench/fit_bench examples/fem-plate-5x5.json examples/fem-kidney-2d.json
//   build/bench/fit_bench --response nonlinear examples/fem-kidney-2d.json
//   build/bench/fit_bench --threads 2 --max-iterations 300 examples/fem-block-3d.json
//   build/bench/fit_bench --path examples/fem-plate-5x5.json   # with the sparsity path
//   build/bench/fit_bench --cv 0 0.001 0.01 0.1 examples/fem-kidney-2d.json  # held-out E
//
// E is the relative RMS nodal error sqrt(sum |u - u^R|^2 / sum |u^R|^2) over the free nodes of
// every load case; times are wall seconds of one run on this machine.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "engine/api/problem.h"
#include "engine/fit/sparsity_path.h"
#include "engine/fit/stiffness_fit.h"
#include "engine/problem/baseline_evaluation.h"
#include "proto/names.h"
#include "proto/scene_codec.h"

namespace springfit {
namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

void Report(const char* what, const StiffnessFitResult& fit, int springs, double seconds) {
  std::printf("  %-28s E %-10.4g springs %5d  steps %3d (%3d accepted)  solves %7lld  %7.2f s%s\n",
              what, std::sqrt(fit.normalized_error), springs, fit.iterations, fit.accepted,
              static_cast<long long>(fit.solves), seconds,
              fit.converged ? "" : "  (not converged)");
}

int Main(int argc, char** argv) {
  CLI::App app{"Continuous stiffness fits on FEM references"};
  std::vector<std::string> files;
  std::string response;
  int max_iterations = StiffnessFitOptions{}.descent.max_steps;
  int threads = 1;
  bool path_flag = false;
  std::vector<double> regularizations;
  app.add_option("scenes", files, "FEM scene files")->required();
  app.add_option("--response", response, "linear or nonlinear (default: the scene's)");
  app.add_option("--max-iterations", max_iterations, "trust-region steps per fit");
  app.add_option("--threads", threads, "threads for the load cases' solves");
  app.add_flag("--path", path_flag,
               "also trace the sparsity path and the held-out error of each of its points");
  app.add_option("--cv", regularizations,
                 "cross-validate the fit on every candidate over the load cases (HeldOutErrors) "
                 "at these regularisation strengths");
  CLI11_PARSE(app, argc, argv);
  WorkerPool pool(threads);
  FitContext fit_context;
  fit_context.pool = &pool;

  for (const std::string& file : files) {
    Scene scene = proto::LoadSceneFile(file);
    if (!response.empty()) scene.search.response = proto::ResponseFromName(response, "--response");
    auto t0 = Clock::now();
    const Problem problem(std::move(scene));
    const double prepare = Seconds(t0);
    std::printf("%s: %d nodes, %d genes, %zu load cases, response %s (prepared in %.2f s)\n",
                file.c_str(), problem.scene().node_count(), problem.gene_count(),
                problem.load_cases().size(),
                std::string(proto::ResponseName(problem.response())).c_str(), prepare);
    const auto baseline = EvaluateClosedFormBaseline(problem);
    const auto start = BaselineGeneWeights(problem);
    if (!baseline || !start) {
      std::printf("  not an FEM reference whose mesh edges are all candidates: skipped\n");
      continue;
    }
    std::printf("  %-28s E %-10.4g springs %5d\n", "closed form (van Gelder)",
                baseline->converged ? baseline->rms_error : NAN, baseline->springs);
    StiffnessFitOptions options;
    options.descent.max_steps = max_iterations;
    std::vector<bool> edges(start->size()), all(start->size(), true);
    for (std::size_t g = 0; g < start->size(); ++g) edges[g] = (*start)[g] > 0.0;
    t0 = Clock::now();
    const StiffnessFitResult floor =
        FitStiffness(problem, *start, FitScope{edges, {}, {}}, options, fit_context);
    Report("fit on the mesh edges", floor, PresentSprings(floor.weights), Seconds(t0));
    t0 = Clock::now();
    const StiffnessFitResult rich =
        FitStiffness(problem, *start, FitScope{all, {}, {}}, options, fit_context);
    Report("fit on all candidates", rich, PresentSprings(rich.weights), Seconds(t0));
    for (double lambda : regularizations) {
      // Cross-validation from the start (HeldOutErrors on every candidate): fitted without
      // case k, judged on case k, with fits of --max-iterations steps.
      SparsityPathOptions cv;
      cv.fit = options;
      cv.fit.regularization = lambda;
      cv.fit.saliency_probes = 0;
      cv.held_out_iterations = max_iterations;
      t0 = Clock::now();
      const StiffnessFitResult trained =
          FitStiffness(problem, *start, FitScope{all, {}, {}}, cv.fit, fit_context);
      const std::vector<double> every(start->size(), 1.0);
      const auto held_out = HeldOutErrors(problem, every, *start, cv, fit_context);
      std::printf("  regularization %-8.3g E %-10.4g springs %5d  held-out E %-10.4g %7.2f s\n",
                  lambda, std::sqrt(trained.normalized_error), PresentSprings(trained.weights),
                  held_out ? std::sqrt(held_out->normalized_error) : NAN, Seconds(t0));
      if (held_out) {
        std::printf("    per case:");
        for (double e : held_out->per_case) std::printf(" %.3g", std::sqrt(e));
        std::printf("\n");
      }
    }
    if (path_flag) {
      t0 = Clock::now();
      SparsityPathOptions path_options;
      path_options.fit = options;
      const SparsityPath path =
          TraceSparsityPath(problem, *start, all, path_options, 0.0, 0, fit_context);
      std::printf(
          "  sparsity path: %zu points in %.2f s; per point E, held-out E (refits of %d "
          "steps):\n",
          path.points.size(), Seconds(t0), path_options.refit_iterations);
      for (const PathPoint& point : path.points) {
        const auto h = HeldOutErrors(problem, point.weights, *start, path_options, fit_context);
        std::printf("    %5d springs  E %-10.4g held-out E %.4g\n", point.springs,
                    std::sqrt(point.normalized_error), h ? std::sqrt(h->normalized_error) : NAN);
      }
    }
  }
  return 0;
}

}  // namespace
}  // namespace springfit

int main(int argc, char** argv) {
  return springfit::Main(argc, argv);
}
