#include "client/search_flags.h"

#include "proto/names.h"

namespace springfit::cli {

void AddSearchFlags(CLI::App* command, SearchFlags& flags) {
  command->add_option("--strategy", flags.strategy,
                      "Search strategy: " + proto::StrategyNames() + " (default: the scene's)");
  command->add_option("--identify", flags.identify,
                      "What to identify: " + proto::IdentifyNames() +
                          " (the latter with strategies direct and continuous, which is default "
                          "on an FEM reference; default: the scene's, else "
                          "topology_and_stiffness for direct and continuous, topology otherwise)");
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
  command->add_option("--response", flags.response,
                      "How the model responds: linear (at rest, the small-load limit) or "
                      "nonlinear (default: the scene's, else linear for a linear FEM reference, "
                      "nonlinear otherwise)");
  command
      ->add_option("--max-springs", flags.max_springs,
                   "Strategy continuous (default on an FEM reference): the lowest error with at "
                   "most this many springs")
      ->check(CLI::Range(1, 100000000));
  command
      ->add_option("--target-error", flags.target_error,
                   "Strategy continuous (default on an FEM reference): the fewest springs with "
                   "a relative RMS nodal error E at most this")
      ->check(CLI::PositiveNumber);
  command
      ->add_option("--max-spread", flags.max_spread,
                   "Strategy continuous fitted to probes: the model's largest stiffness over its "
                   "smallest, at most this (> 1; springs below the largest / this leave the "
                   "model)")
      ->check(CLI::Range(1.0, 1e300));
  command
      ->add_option("--load-size", flags.load_size,
                   "Strategy continuous fitted to probes: the size of the loads the simulator "
                   "will apply, as the largest nodal displacement in the scene's length; the "
                   "nonlinear fit and judgement and the tool pushes run at 25, 50 and 100% of it "
                   "(default: the scene's, else the named loads' size)")
      ->check(CLI::PositiveNumber);
  command->add_option("--regularization", flags.regularization,
                      "Strategy continuous (default on an FEM reference): pull the stiffness "
                      "toward the closed-form baseline by this strength (>= 0; 0.01: moving "
                      "every spring by its own stiffness costs E^2 = 0.01), or auto: the "
                      "strength with the lowest held-out error (one fit per load case and "
                      "strength tried)");
  command->add_option("--probes", flags.probes,
                      "Strategy continuous (default on an FEM reference) with an FEM or MSS "
                      "reference: the probe loads the model is fitted to and judged on (point, "
                      "patch and body loads on several supports, a part held out): auto, none "
                      "(the named load cases alone) or about N probes (default: the scene's, "
                      "else auto)");
}

void ApplySearchFlags(const SearchFlags& flags, SearchSettings& st) {
  if (flags.strategy) st.strategy = proto::StrategyFromName(*flags.strategy, "--strategy");
  if (flags.identify) st.identify = proto::IdentifyFromName(*flags.identify, "--identify");
  if (flags.seed) st.seed = *flags.seed;
  if (flags.generations) st.max_generations = *flags.generations;
  if (flags.time_limit) st.max_seconds = *flags.time_limit;
  if (flags.stall) st.stall_generations = *flags.stall;
  if (flags.response) st.response = proto::ResponseFromName(*flags.response, "--response");
  if (flags.max_springs) st.max_springs = *flags.max_springs;
  if (flags.target_error) st.target_error = *flags.target_error;
  if (flags.max_spread) st.max_spread = *flags.max_spread;
  if (flags.load_size) st.load_size = *flags.load_size;
  if (flags.regularization)
    st.regularization = proto::RegularizationFromText(*flags.regularization, "--regularization");
  if (flags.probes) st.probes = proto::ProbesFromText(*flags.probes, "--probes");
}

}  // namespace springfit::cli
