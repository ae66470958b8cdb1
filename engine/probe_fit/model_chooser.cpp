#include "engine/probe_fit/model_chooser.h"

#include <algorithm>
#include <cmath>

#include "engine/probe_fit/response_fit.h"

namespace springfit::response {

ModelChooser::ModelChooser(const ResponseFitOptions& options)
    : min_lambda_(options.min_lambda),
      lambda_slack_(options.lambda_slack),
      max_springs_(options.max_springs) {}

std::size_t ModelChooser::Best(const std::vector<CandidateModel>& candidates,
                               std::size_t from) const {
  double best = INFINITY;
  for (std::size_t i = from; i < candidates.size(); ++i)
    best = std::min(best, candidates[i].choosing_error);
  bool supported_near = false;
  for (std::size_t i = from; i < candidates.size(); ++i)
    supported_near |= candidates[i].lambda_min >= min_lambda_ &&
                      candidates[i].choosing_error <= (1.0 + lambda_slack_) * best;
  std::size_t chosen = from;
  double chosen_score = INFINITY;
  for (std::size_t i = from; i < candidates.size(); ++i) {
    const double score = supported_near && candidates[i].lambda_min < min_lambda_
                             ? INFINITY
                             : candidates[i].choosing_error;
    if (score < chosen_score) {
      chosen = i;
      chosen_score = score;
    }
  }
  return chosen;
}

std::optional<std::size_t> ModelChooser::BestWithinBudget(
    const std::vector<CandidateModel>& candidates) const {
  if (max_springs_ == 0) return std::nullopt;
  std::vector<std::size_t> models;
  std::vector<CandidateModel> within;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const CandidateModel& c = candidates[i];
    if (c.springs <= max_springs_ && c.lambda_min > 0.0 && std::isfinite(c.choosing_error)) {
      models.push_back(i);
      within.push_back(c);
    }
  }
  if (models.empty()) return std::nullopt;
  return models[Best(within)];
}

std::size_t ModelChooser::Choose(const std::vector<CandidateModel>& candidates) const {
  if (const std::optional<std::size_t> within = BestWithinBudget(candidates)) return *within;
  return Best(candidates);
}

}  // namespace springfit::response
