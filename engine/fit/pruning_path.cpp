#include "engine/fit/pruning_path.h"

#include <algorithm>
#include <cmath>

#include "engine/runtime/options_check.h"

namespace springfit {

void PruningOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(InOpenUnit(prune_fraction), "prune_fraction", prune_fraction, "0 < value < 1");
  check.Require(max_refusals >= 0, "max_refusals", max_refusals, "value >= 0");
}

void PruneModel(PrunableModel& model, int min_springs, const PruningOptions& options,
                const std::function<bool()>& go_on) {
  options.Validate();
  using Removal = PrunableModel::Removal;
  std::vector<bool> kept;
  bool removed_since_marked = false;
  while (model.PresentSprings() > min_springs && (!go_on || go_on())) {
    std::vector<int> removable;
    for (int g : model.BySaliency()) {
      if (static_cast<std::size_t>(g) >= kept.size()) kept.resize(static_cast<std::size_t>(g) + 1);
      if (!kept[static_cast<std::size_t>(g)]) removable.push_back(g);
    }
    if (removable.empty()) {
      if (!options.retry_kept || !removed_since_marked) return;
      kept.assign(kept.size(), false);
      removed_since_marked = false;
      continue;
    }
    const int present = model.PresentSprings();
    const double share = options.prune_fraction * present;
    int count = std::max(1, static_cast<int>(options.round_up ? std::ceil(share) : share));
    count =
        std::min({count, std::max(1, present - min_springs), static_cast<int>(removable.size())});
    for (int refusals = 0;;) {
      const bool may_refuse = count > 1 && refusals < options.max_refusals;
      const Removal outcome =
          model.Remove(std::vector<int>(removable.begin(), removable.begin() + count), may_refuse);
      if (outcome == Removal::kAccepted) {
        removed_since_marked = true;
        break;
      }
      if (count == 1) {
        kept[static_cast<std::size_t>(removable.front())] = true;  // the next step, the next one
        break;
      }
      count /= 2;
      if (outcome == Removal::kTooCostly) ++refusals;
    }
  }
}

}  // namespace springfit
