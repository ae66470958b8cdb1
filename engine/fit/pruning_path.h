// The one sparsity path (docs/ARCHITECTURE.md, "What a model leaves out"): a model loses its
// least salient springs a fraction at a time, each removal refitted, down to a size or until
// its caller says stop. The named-case path (sparsity_path.h) and the probe fit's spring budget
// (engine/probe_fit/matrix_free_fit.h) walk it; each says what saliency, a removal and a refit
// are for its objective.
//
// A step: the present springs not kept, least salient first; the first `count` of them
// removed, count = the prune fraction of the present springs (at least one, at most down to
// the size asked for). A removal that leaves no model (a mechanism, no equilibrium) or that the
// model's own rule refuses (too costly) is retried with half as many springs; a single spring
// whose removal fails is kept (it may hold a mode no load loads) and the step goes on with the
// next. The path ends when no spring can leave; with `retry_kept`, the kept springs are first
// tried once more after any removal since they were marked (a nonlinear model's solves depend
// on the stiffness the refits changed).
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace springfit {

// What a path prunes: a fitted model that can lose springs.
class PrunableModel {
 public:
  enum class Removal {
    kAccepted,    // the model is now the one without them, refitted
    kInfeasible,  // no model without them: the model is unchanged
    kTooCostly,   // the model's own rule refuses it (only when `may_refuse`): unchanged
  };
  virtual ~PrunableModel() = default;
  virtual int PresentSprings() const = 0;
  // The present springs, least salient first (ties by gene: deterministic).
  virtual std::vector<int> BySaliency() const = 0;
  // Removes `genes` and refits. `may_refuse`: the model may apply its own rule (kTooCostly).
  // Throws Interrupted when stopped.
  virtual Removal Remove(const std::vector<int>& genes, bool may_refuse) = 0;
};

struct PruningOptions {
  double prune_fraction = 0.1;  // of the present springs removed per step, in (0, 1)
  // The fraction's count rounded up (else down), at least one either way.
  bool round_up = false;
  // Refusals of the model's own rule (kTooCostly) per step at most; then a removal stands.
  int max_refusals = 2;
  bool retry_kept = false;  // see above

  // Throws std::invalid_argument naming the field, its value and the rule it breaks.
  void Validate(const std::string& owner = "PruningOptions") const;
};

// Prunes `model` towards `min_springs` springs: a step while `go_on()` (asked before each) and
// the model has more. Throws Interrupted from the model.
void PruneModel(PrunableModel& model, int min_springs, const PruningOptions& options,
                const std::function<bool()>& go_on = {});

}  // namespace springfit
