// The one rule by which a probe fit chooses among candidate models (docs/ARCHITECTURE.md,
// "Probes by role"): every iterate of the continuation, every point of a budget path, every
// soft-mode round and the lift are candidates, each judged by its choosing error (the
// family-balanced E over the choosing probes, probe_objective.h: ChoosingError) and the
// smallest generalised eigenvalue on the user's supports. Held-out probes never reach it: they
// are a type only the certificate reads (probe_bank.h, HeldOutProbes).
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

namespace springfit::response {

struct ResponseFitOptions;

struct CandidateModel {
  int springs = 0;
  double choosing_error = 0.0;  // kNoModel (infinity): not a model
  double lambda_min = 0.0;      // the smallest generalised eigenvalue on the user supports
};

class ModelChooser {
 public:
  // Reads min_lambda, lambda_slack and max_springs.
  explicit ModelChooser(const ResponseFitOptions& options);

  // The lowest choosing error among candidates[from...], with those that leave a mode soft
  // (lambda_min below min_lambda) set aside when one that does not is within lambda_slack of
  // the best: a supported model is preferred where it costs little. Precondition: from <
  // candidates.size().
  std::size_t Best(const std::vector<CandidateModel>& candidates, std::size_t from = 0) const;
  // With a spring budget, the best (as Best) among the candidates within it that are models (a
  // finite choosing error, lambda_min > 0: every support holds them); nothing without a budget
  // or when no model is within it.
  std::optional<std::size_t> BestWithinBudget(const std::vector<CandidateModel>& candidates) const;
  // The budget's choice when there is one, else Best.
  std::size_t Choose(const std::vector<CandidateModel>& candidates) const;

 private:
  double min_lambda_;
  double lambda_slack_;
  int max_springs_;
};

}  // namespace springfit::response
