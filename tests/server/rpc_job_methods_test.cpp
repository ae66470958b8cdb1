// The job methods of RpcService (rpc_service_test_support.h): submit, watch, result, trace,
// list, scene, improvements, cancel and delete, on queued, running and finished jobs.
#include "server/rpc/rpc_service.h"

#include <algorithm>
#include <cstdint>
#include <string>

#include <gtest/gtest.h>

#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "tests/server/rpc_service_test_support.h"

namespace springfit::server {
namespace {

using proto::Json;
namespace rpc = proto::rpc;

TEST_F(RpcServiceTest, QueuedJobsCancelAndRefuseResultAndDelete) {
  MakeService(false);
  const Json submitted = Submit("paper-iso-5x5", {{"label", "x"}, {"seed", 42}, {"priority", 3}});
  const Json job = submitted["result"]["job"];
  const std::int64_t id = job["job_id"].get<std::int64_t>();
  EXPECT_EQ(job["state"], "queued");
  EXPECT_EQ(job["seed"], 42);
  EXPECT_EQ(job["genes"], 72);
  const Json early = Call("job.result", {{"job_id", id}});
  EXPECT_EQ(Code(early), rpc::kWrongState);
  EXPECT_EQ(early["error"]["data"]["state"], "queued");
  EXPECT_EQ(Code(Call("job.delete", {{"job_id", id}})), rpc::kWrongState);
  EXPECT_EQ(Call("job.cancel", {{"job_id", id}})["result"]["state"], "cancelled");
  EXPECT_EQ(Call("job.get", {{"job_id", id}})["result"]["state"], "cancelled");
  EXPECT_EQ(Code(Call("job.cancel", {{"job_id", id}})), rpc::kWrongState);
  EXPECT_EQ(Code(Call("job.result", {{"job_id", id}})), rpc::kWrongState);
  EXPECT_TRUE(Call("job.delete", {{"job_id", id}})["result"]["deleted"].get<bool>());
  EXPECT_EQ(Code(Call("job.get", {{"job_id", id}})), rpc::kNoSuchJob);
}

TEST_F(RpcServiceTest, SubmitWatchResultTraceListAndIdempotency) {
  MakeService(true);
  const Json first = Submit("paper-aniso-5x5", {{"idempotency_key", "ci-1"}, {"label", "nightly"}});
  ASSERT_TRUE(first.contains("result")) << first.dump();
  const std::int64_t id = first["result"]["job"]["job_id"].get<std::int64_t>();
  const Json watched = Call("job.watch", {{"job_id", id}});
  ASSERT_TRUE(watched.contains("result"));
  const Json finished = inbox_.WaitFor("job.finished");
  ASSERT_FALSE(finished.is_null()) << "no job.finished within 60 s";
  EXPECT_EQ(finished["params"]["job_id"], id);
  EXPECT_EQ(finished["params"]["state"], "succeeded");
  EXPECT_EQ(finished["params"]["exact"], true);
  // Generation 0 is always sent to a watcher registered before it ran: one that found the job
  // still queued (the job can also have run already, in a few milliseconds, on the problem its
  // submission prepared).
  if (watched["result"]["state"] == "queued") {
    EXPECT_FALSE(inbox_.WaitFor("job.progress").is_null());
  }

  const Json retry = Submit("paper-aniso-5x5", {{"idempotency_key", "ci-1"}});
  EXPECT_FALSE(retry["result"]["created"].get<bool>());
  EXPECT_EQ(retry["result"]["job"]["job_id"], id);
  // The same key for another scene, or another seed, is an error naming the job and what
  // differs (it returned the old job with created false, and a pipeline its old result).
  const Json other_scene = Submit("paper-iso-5x5", {{"idempotency_key", "ci-1"}});
  EXPECT_EQ(Code(other_scene), rpc::kInvalidParams);
  EXPECT_EQ(other_scene["error"]["data"]["job_id"], id);
  EXPECT_EQ(other_scene["error"]["data"]["path"], "params.idempotency_key");
  EXPECT_NE(other_scene["error"]["message"].get<std::string>().find("a different scene"),
            std::string::npos)
      << other_scene["error"]["message"];
  const Json other_seed = Submit("paper-aniso-5x5", {{"idempotency_key", "ci-1"}, {"seed", 43}});
  EXPECT_EQ(Code(other_seed), rpc::kInvalidParams);
  EXPECT_NE(other_seed["error"]["message"].get<std::string>().find("a different seed"),
            std::string::npos)
      << other_seed["error"]["message"];

  const Json result = Call("job.result", {{"job_id", id}})["result"];
  EXPECT_EQ(result["exact"], true);
  EXPECT_EQ(result["job_id"], id);
  EXPECT_EQ(result["state"], "succeeded");
  EXPECT_EQ(result["hamming"], 0);

  const int generations = result["generations"].get<int>();
  Json params = {{"job_id", id}, {"limit", 1}};
  int rows = 0;
  for (int page = 0; page < 10000; ++page) {
    const Json t = Call("job.trace", params)["result"];
    rows += static_cast<int>(t["rows"].size());
    if (t["next_after"].is_null()) break;
    params["after"] = t["next_after"];
  }
  EXPECT_EQ(rows, generations + 1);  // every generation below 10,000 is kept

  const Json list = Call("job.list", {{"label", "nightly"}})["result"];
  ASSERT_EQ(list["jobs"].size(), 1u);
  EXPECT_EQ(list["jobs"][0]["job_id"], id);
  EXPECT_EQ(Code(Call("job.list", {{"state", "done"}})), rpc::kInvalidParams);

  // Watching a finished job: job.finished follows at once, and only once.
  SessionContext other;
  Inbox other_inbox;
  other.notify = [&](const Json& n) { other_inbox.Push(n); };
  service_->HandleMessage(rpc::Serialize(rpc::Request(1, "job.watch", {{"job_id", id}})), other);
  EXPECT_EQ(other_inbox.All().size(), 1u);
  EXPECT_EQ(other_inbox.All()[0]["method"], "job.finished");
  service_->EndSession(other);
  service_->EndSession(session_);
}

TEST_F(RpcServiceTest, SceneAndImprovementsOfAFinishedJob) {
  MakeService(true);
  Json scene = Scene("paper-iso-5x5");
  scene["search"] = {{"strategy", "paper"}, {"max_generations", 40}};
  const Json submitted = Call("job.submit", {{"scene", scene}, {"seed", 42}});
  ASSERT_TRUE(submitted.contains("result")) << submitted.dump();
  const std::int64_t id = submitted["result"]["job"]["job_id"].get<std::int64_t>();
  Call("job.watch", {{"job_id", id}});
  ASSERT_FALSE(inbox_.WaitFor("job.finished").is_null()) << "no job.finished within 60 s";
  const Json result = Call("job.result", {{"job_id", id}})["result"];

  // The stored scene is the submitted one with the job's seed written in.
  const Json stored = Call("job.scene", {{"job_id", id}})["result"];
  EXPECT_EQ(stored["job_id"], id);
  const springfit::Scene read = proto::SceneFromJson(stored["scene"]);
  EXPECT_EQ(read.search.seed, 42u);
  EXPECT_EQ(read.search.strategy, Strategy::kPaper);
  EXPECT_EQ(stored["scene"]["nodes"], scene["nodes"]);

  // Improvements: strictly better, generation after generation, ending at the result.
  const Json improvements = Call("job.improvements", {{"job_id", id}})["result"]["improvements"];
  ASSERT_GE(improvements.size(), 2u) << "the paper GA improves more than once in 40 generations";
  for (std::size_t i = 1; i < improvements.size(); ++i) {
    EXPECT_LT(improvements[i]["cost"].get<double>(), improvements[i - 1]["cost"].get<double>());
    EXPECT_GT(improvements[i]["generation"].get<int>(),
              improvements[i - 1]["generation"].get<int>());
  }
  const Json& last = improvements.back();
  EXPECT_EQ(last["cost"], result["cost"]);
  // Paged: a page of one says where the next starts; `last` is the best alone.
  const Json first_page = Call("job.improvements", {{"job_id", id}, {"limit", 1}})["result"];
  ASSERT_EQ(first_page["improvements"].size(), 1u);
  EXPECT_EQ(first_page["improvements"][0], improvements[0]);
  EXPECT_EQ(first_page["next_after"], improvements[0]["generation"]);
  const Json rest =
      Call("job.improvements", {{"job_id", id}, {"after", first_page["next_after"]}})["result"];
  EXPECT_EQ(rest["improvements"].size(), improvements.size() - 1);
  EXPECT_TRUE(rest["next_after"].is_null());
  const Json best = Call("job.improvements", {{"job_id", id}, {"last", true}})["result"];
  ASSERT_EQ(best["improvements"].size(), 1u);
  EXPECT_EQ(best["improvements"][0], last);
  EXPECT_EQ(last["generation"], result["best_generation"]);
  const std::string genome = last["genome"].get<std::string>();
  const Problem problem = Problem::Build(read);
  ASSERT_EQ(static_cast<int>(genome.size()), problem.gene_count());
  Json springs = Json::array();
  for (int g = 0; g < problem.gene_count(); ++g) {
    if (genome[g] == '1') {
      const NodePair p = problem.candidates().pairs[problem.gene_candidates()[g]];
      springs.push_back({p.first, p.second});
    }
  }
  EXPECT_EQ(springs, result["springs"]);
  EXPECT_EQ(Code(Call("job.scene", {{"job_id", id + 100}})), rpc::kNoSuchJob);
  EXPECT_EQ(Code(Call("job.improvements", {{"job_id", id}, {"last", 3}})), rpc::kInvalidParams);
  EXPECT_EQ(Code(Call("job.improvements", {{"job_id", id}, {"newest", true}})),
            rpc::kInvalidParams);
  service_->EndSession(session_);
}

TEST_F(RpcServiceTest, StrategyDirectRunsAsAJobWithOneTraceRow) {
  MakeService(true);
  Json scene = Scene("stiff-2d");
  scene["search"] = {{"strategy", "direct"}};
  const Json submitted = Call("job.submit", {{"scene", scene}});
  ASSERT_TRUE(submitted.contains("result")) << submitted.dump();
  const std::int64_t id = submitted["result"]["job"]["job_id"].get<std::int64_t>();
  EXPECT_EQ(submitted["result"]["job"]["strategy"], "direct");
  Call("job.watch", {{"job_id", id}});
  const Json finished = inbox_.WaitFor("job.finished");
  ASSERT_FALSE(finished.is_null());
  EXPECT_EQ(finished["params"]["state"], "succeeded");
  EXPECT_EQ(finished["params"]["exact"], true);
  const Json result = Call("job.result", {{"job_id", id}})["result"];
  EXPECT_EQ(result["strategy"], "direct");
  EXPECT_EQ(result["stop"], "target_reached");
  ASSERT_EQ(result["stiffness"].size(), result["springs"].size());
  // stiff-2d's stiffness spans 1e-4..1e4: the identified values are the reference's.
  const auto [lo, hi] = std::minmax_element(result["stiffness"].begin(), result["stiffness"].end());
  EXPECT_NEAR(lo->get<double>(), 1e-4,
              1e-6 * 1e-4);  // the softest: round-off of the stiff springs' forces
  EXPECT_NEAR(hi->get<double>(), 1e4, 1e-8 * 1e4);
  EXPECT_EQ(Call("job.trace", {{"job_id", id}})["result"]["rows"].size(), 1u);
  EXPECT_EQ(Call("job.improvements", {{"job_id", id}})["result"]["improvements"].size(), 1u);
  service_->EndSession(session_);
}

TEST_F(RpcServiceTest, RunningJobCancelsWithinAGenerationAndKeepsItsBest) {
  MakeService(true);
  Json scene = Scene("kidney-2d");
  scene["search"] = {{"strategy", "paper"}, {"max_generations", 100000}};
  const Json submitted = Call("job.submit", {{"scene", scene}});
  const std::int64_t id = submitted["result"]["job"]["job_id"].get<std::int64_t>();
  Call("job.watch", {{"job_id", id}});
  ASSERT_FALSE(inbox_.WaitFor("job.progress").is_null());
  EXPECT_EQ(Code(Call("job.delete", {{"job_id", id}})), rpc::kWrongState);
  EXPECT_EQ(Call("job.cancel", {{"job_id", id}})["result"]["state"], "cancelling");
  const Json finished = inbox_.WaitFor("job.finished");
  ASSERT_FALSE(finished.is_null());
  EXPECT_EQ(finished["params"]["state"], "cancelled");
  const Json result = Call("job.result", {{"job_id", id}})["result"];
  EXPECT_EQ(result["stop"], "cancelled");
  EXPECT_EQ(result["state"], "cancelled");
  EXPECT_LT(result["generations"].get<int>(), 100000);
  service_->EndSession(session_);
}

}  // namespace
}  // namespace springfit::server
