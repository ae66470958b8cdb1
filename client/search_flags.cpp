#include "client/search_flags.h"

#include "proto/names.h"

namespace springfit::cli {

void AddSearchFlags(CLI::App* command, SearchFlags& flags) {
  command->add_option("--strategy", flags.strategy,
                      "Search strategy: " + proto::StrategyNames() + " (default: the scene's)");
  command->add_option("--identify", flags.identify,
                      "What to identify: " + proto::IdentifyNames() +
                          " (the latter with strategy direct only; default: the scene's, else "
                          "topology_and_stiffness for direct, topology otherwise)");
  command->add_option("--seed", flags.seed, "Random seed (default: the scene's, else 1)");
  command
      ->add_option("--generations", flags.generations,
                   "Generation limit (default: the scene's, else 1000)")
      ->check(CLI::Range(1, 100000000));
  command
      ->add_option("--time-limit", flags.time_limit,
                   "Stop after this many seconds of wall time from the run's start, keeping the "
                   "best so far (default: the scene's, else none; a run it stops is not "
                   "reproducible)")
      ->check(CLI::PositiveNumber);
  command
      ->add_option("--stall", flags.stall,
                   "Stop when the best has not improved for this many generations; 0 = never "
                   "(default: the scene's, else 200 for default and hybrid, never for paper)")
      ->check(CLI::NonNegativeNumber);
}

void ApplySearchFlags(const SearchFlags& flags, SearchSettings& st) {
  if (flags.strategy) st.strategy = proto::StrategyFromName(*flags.strategy, "--strategy");
  if (flags.identify) st.identify = proto::IdentifyFromName(*flags.identify, "--identify");
  if (flags.seed) st.seed = *flags.seed;
  if (flags.generations) st.max_generations = *flags.generations;
  if (flags.time_limit) st.max_seconds = *flags.time_limit;
  if (flags.stall) st.stall_generations = *flags.stall;
}

void ApplySearchFlags(const SearchFlags& flags, proto::Json& scene) {
  if (!(flags.strategy || flags.identify || flags.generations || flags.time_limit || flags.stall))
    return;
  proto::Json& search = scene["search"];
  if (search.is_null()) search = proto::Json::object();
  if (flags.strategy)
    search["strategy"] =
        proto::StrategyName(proto::StrategyFromName(*flags.strategy, "--strategy"));
  if (flags.identify)
    search["identify"] =
        proto::IdentifyName(proto::IdentifyFromName(*flags.identify, "--identify"));
  if (flags.generations) search["max_generations"] = *flags.generations;
  if (flags.time_limit) search["max_seconds"] = *flags.time_limit;
  if (flags.stall) search["stall_generations"] = *flags.stall;
}

}  // namespace springfit::cli
