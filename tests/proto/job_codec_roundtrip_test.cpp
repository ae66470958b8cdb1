// Round trips of job records and verdicts through their text (proto/job.h, outcome_codec.h),
// what a reader of a newer server ignores, and the one wording of a job's E.
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "engine/runtime/input_error.h"
#include "proto/job.h"
#include "proto/json_reader.h"
#include "proto/outcome_codec.h"
#include "proto/rpc.h"
#include "proto/search_codec.h"

namespace springfit::proto {
namespace {

void ExpectSameJob(const JobRecord& a, const JobRecord& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.label, b.label);
  EXPECT_EQ(a.priority, b.priority);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.idempotency_key, b.idempotency_key);
  EXPECT_EQ(a.state, b.state);
  EXPECT_EQ(a.error, b.error);
  EXPECT_EQ(a.scene_name, b.scene_name);
  EXPECT_EQ(a.genes, b.genes);
  EXPECT_EQ(a.strategy, b.strategy);
  EXPECT_EQ(a.max_generations, b.max_generations);
  EXPECT_EQ(a.created_at, b.created_at);
  EXPECT_EQ(a.started_at, b.started_at);
  EXPECT_EQ(a.finished_at, b.finished_at);
  ASSERT_EQ(a.progress.has_value(), b.progress.has_value());
  if (a.progress) {
    EXPECT_TRUE(a.progress->SameSearch(*b.progress));
    EXPECT_EQ(a.progress->wall_seconds, b.progress->wall_seconds);
  }
  EXPECT_EQ(a.checkpoint_generation, b.checkpoint_generation);
  EXPECT_EQ(a.exact, b.exact);
}

TEST(JobCodecRoundTrip, JobRecordsReadBackAsWrittenOnTheWire) {
  JobRecord full;
  full.id = 123456789012;
  full.label = "nightly \"ci\" \xc3\xb1";  // quotes and UTF-8
  full.priority = -7;
  full.seed = std::numeric_limits<std::uint64_t>::max();
  full.idempotency_key = "key-1";
  full.state = JobState::kSucceeded;
  full.scene_name = "paper-aniso-5x5";
  full.genes = 72;
  full.strategy = "paper";
  full.max_generations = 1000;
  full.created_at = 1700000000.125;
  full.started_at = 1700000001.5;
  full.finished_at = 1700000042.0000001;
  TraceRow progress;
  progress.generation = 40;
  progress.wall_seconds = 3.25;
  progress.evaluations = 820;
  progress.cache_hits = 17;
  progress.best_cost = 1e-5;
  progress.best_normalized_error = 2.5e-7;
  progress.mean_cost = 0.3;
  progress.missing = 0;
  progress.extra = 2;
  full.progress = progress;
  full.checkpoint_generation = 0;  // a checkpoint at generation 0 is one: not "none"
  full.exact = false;

  JobRecord failed;
  failed.id = 2;
  failed.label = "";
  failed.state = JobState::kFailed;
  failed.error = "cannot read the job: disk I/O error";
  failed.scene_name = "s";
  failed.strategy = "default";
  failed.created_at = 1.5e9;
  failed.started_at = 1.5e9 + 1;
  failed.finished_at = 1.5e9 + 2;

  JobRecord queued;  // times not yet (null), no progress, no checkpoint, exact unknown
  queued.id = 1;
  queued.scene_name = "q";
  queued.strategy = "hybrid";
  queued.created_at = 1.5e9;

  for (const JobRecord& job : {full, failed, queued}) {
    SCOPED_TRACE("job " + std::to_string(job.id));
    const std::string text = rpc::Serialize(JobToJson(job));
    const JobRecord back = JobFromJson(ParseJson(text));
    ExpectSameJob(job, back);
    EXPECT_EQ(rpc::Serialize(JobToJson(back)), text);
  }
  const Json queued_json = JobToJson(queued);
  EXPECT_TRUE(queued_json.at("started_at").is_null());
  EXPECT_TRUE(queued_json.at("checkpoint_generation").is_null());
  EXPECT_TRUE(queued_json.at("idempotency_key").is_null());
  EXPECT_EQ(JobToJson(full).at("checkpoint_generation"), 0);

  for (const JobState state : {JobState::kPreparing, JobState::kQueued, JobState::kRunning,
                               JobState::kSucceeded, JobState::kFailed, JobState::kCancelled}) {
    EXPECT_EQ(ParseJobState(JobStateName(state)), std::optional<JobState>(state))
        << JobStateName(state);
  }
}

// A client reads what a newer server writes: members it does not know are ignored, in a job,
// its progress row and a job.progress notification's params.
TEST(JobCodecRoundTrip, AReaderIgnoresMembersOfANewerServer) {
  JobRecord job;
  job.id = 7;
  job.scene_name = "s";
  job.strategy = "default";
  job.created_at = 1.5e9;
  TraceRow row;
  row.generation = 3;
  row.best_normalized_error = 0.25;
  job.progress = row;
  Json json = JobToJson(job);
  json["ran"] = "continuous";
  json["verdict"] = {{"usable", true}};
  json["progress"]["phase"] = "probe_fit";
  const JobRecord back = JobFromJson(ParseJson(rpc::Serialize(json)));  // as read off the wire
  EXPECT_EQ(back.id, 7);
  ASSERT_TRUE(back.progress);
  EXPECT_EQ(back.progress->generation, 3);
  Json params = TraceRowToJson(row);
  params["job_id"] = 7;
  params["max_generations"] = 100;
  params["phase"] = "probe_fit";
  EXPECT_EQ(TraceRowFromJson(ParseJson(rpc::Serialize(params)), "params").best_normalized_error,
            0.25);
}

// A verdict reads back with its lines: the doubts of a doubtful one as well as the unmet requests.
TEST(OutcomeCodecRoundTrip, EveryVerdictAndItsLinesReadBack) {
  Outcome o;
  o.verdict = Verdict::kDoubtful;
  o.doubts = {"a soft mode: ...", "unseen loads: ..."};
  o.unmet = {"spring budget not met: ..."};
  o.springs = 80;
  o.rms_error = 0.05;
  const Outcome back = OutcomeFromJson(ParseJson(OutcomeToJson(o).dump()), "outcome");
  EXPECT_EQ(back.verdict, Verdict::kDoubtful);
  EXPECT_EQ(back.doubts, o.doubts);
  EXPECT_EQ(back.unmet, o.unmet);
  EXPECT_EQ(back.springs, 80);
  EXPECT_EQ(OutcomeToJson(back).dump(), OutcomeToJson(o).dump());
  // E as simulated (a linear response) only where there is one; "inf" for no equilibrium.
  EXPECT_FALSE(OutcomeToJson(o).contains("simulated_rms_error"));
  EXPECT_FALSE(back.simulated_rms_error);
  Outcome simulated = o;
  simulated.simulated_rms_error = HUGE_VAL;
  simulated.baseline_simulated_rms_error = 0.3;
  const Outcome read = OutcomeFromJson(ParseJson(OutcomeToJson(simulated).dump()), "outcome");
  EXPECT_EQ(read.simulated_rms_error, HUGE_VAL);
  EXPECT_EQ(read.baseline_simulated_rms_error, 0.3);
  EXPECT_EQ(OutcomeToJson(simulated)["simulated_rms_error"], "inf");
  Json bad = OutcomeToJson(o);
  bad["doubts"][1] = 3;
  try {
    OutcomeFromJson(bad, "outcome");
    ADD_FAILURE() << "a doubt that is not a string was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("outcome.doubts[1]"), std::string::npos) << e.what();
  }
}

// The one wording of a job's E (list, the dashboard) and the one test of step-counted progress.
TEST(JobText, ErrorIsTheVerdictsOnceFinishedAndTheBestSoFarWhileRunning) {
  JobRecord job;
  EXPECT_EQ(JobErrorText(job), "-");
  TraceRow row;
  row.best_normalized_error = 0.04;  // E 0.2
  job.progress = row;
  EXPECT_EQ(JobErrorText(job), "0.2~");
  Outcome outcome;
  outcome.rms_error = 0.0123456;
  job.outcome = outcome;
  EXPECT_EQ(JobErrorText(job), "0.0123");
  job.outcome->simulated_rms_error = 0.0234567;  // a linear response: E as simulated first
  EXPECT_EQ(JobErrorText(job), "0.0235");
  job.outcome->simulated_rms_error.reset();
  job.outcome->rms_error.reset();
  EXPECT_EQ(JobErrorText(job), "-");
  EXPECT_TRUE(ProgressCountsSteps("continuous"));
  EXPECT_FALSE(ProgressCountsSteps("hybrid"));
  EXPECT_FALSE(ProgressCountsSteps("default"));
}

}  // namespace
}  // namespace springfit::proto
