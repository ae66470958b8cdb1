// The daemon's methods without sockets: RpcService over a real SQLite store and scheduler.
#include "server/rpc/rpc_service.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <mutex>

#include <thread>

#include <SQLiteCpp/SQLiteCpp.h>
#include <gtest/gtest.h>

#include "io/example_catalog.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "server/store/forwarding_store.h"
#include "server/store/sqlite_store.h"

namespace springfit::server {
namespace {
using proto::Json;
namespace rpc = proto::rpc;

// Collects notifications sent to a session, from any thread.
class Inbox {
 public:
  void Push(const Json& n) {
    std::lock_guard lock(mutex_);
    messages_.push_back(n);
    cv_.notify_all();
  }
  // Waits (at most 60 s) for a notification of `method`; null when none came.
  Json WaitFor(const std::string& method) {
    std::unique_lock lock(mutex_);
    Json found;
    cv_.wait_for(lock, std::chrono::seconds(60), [&] {
      for (const Json& m : messages_) {
        if (m["method"] == method) {
          found = m;
          return true;
        }
      }
      return false;
    });
    return found;
  }
  std::vector<Json> All() {
    std::lock_guard lock(mutex_);
    return messages_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Json> messages_;
};

class RpcServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           (std::string("springfit-rpc-") +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    store_ = std::make_unique<SqliteStore>((dir_ / "jobs.db").string());
    session_.notify = [this](const Json& n) { inbox_.Push(n); };
  }
  void TearDown() override {
    service_.reset();
    scheduler_.reset();
    store_.reset();
    std::filesystem::remove_all(dir_);
  }
  // `start` = false leaves every job queued (no runner threads).
  void MakeService(bool start, ServiceOptions options = {}) {
    SchedulerOptions so;
    so.workers = 2;
    so.max_running = 1;
    scheduler_ = std::make_unique<Scheduler>(*store_, so);
    if (start) scheduler_->Start();
    service_ = std::make_unique<RpcService>(*store_, *scheduler_, options);
  }
  Json Call(const std::string& method, Json params = Json::object()) {
    const std::string text = rpc::Serialize(rpc::Request(++id_, method, std::move(params)));
    return proto::ParseJson(service_->HandleMessage(text, session_));
  }
  static int Code(const Json& response) { return response.at("error").at("code").get<int>(); }
  static Json Scene(const std::string& name) { return proto::SceneToJson(examples::Make(name)); }
  Json Submit(const std::string& name, Json extra = Json::object()) {
    Json params = std::move(extra);
    params["scene"] = Scene(name);
    return Call("job.submit", params);
  }

  std::filesystem::path dir_;
  std::unique_ptr<SqliteStore> store_;
  std::unique_ptr<Scheduler> scheduler_;
  std::unique_ptr<RpcService> service_;
  SessionContext session_;
  Inbox inbox_;
  std::int64_t id_ = 0;
};

TEST_F(RpcServiceTest, StandardErrors) {
  MakeService(false);
  auto raw = [&](const std::string& text) {
    return proto::ParseJson(service_->HandleMessage(text, session_));
  };
  EXPECT_EQ(Code(raw("{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"server.info\"")),
            rpc::kParseError);
  EXPECT_EQ(Code(raw("{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"x\xff\"}")),
            rpc::kParseError);  // not UTF-8
  EXPECT_EQ(Code(raw("{\"id\":1,\"method\":\"server.info\"}")), rpc::kInvalidRequest);
  EXPECT_EQ(Code(raw("{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":7}")), rpc::kInvalidRequest);
  EXPECT_EQ(Code(raw("{\"jsonrpc\":\"2.0\",\"id\":{},\"method\":\"server.info\"}")),
            rpc::kInvalidRequest);
  EXPECT_EQ(Code(raw("{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"server.info\",\"extra\":1}")),
            rpc::kInvalidRequest);
  EXPECT_EQ(Code(raw("[]")), rpc::kInvalidRequest);
  EXPECT_EQ(Code(raw("{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"job.nope\"}")),
            rpc::kMethodNotFound);
  EXPECT_EQ(Code(raw("{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"job.get\",\"params\":[1]}")),
            rpc::kInvalidParams);
  const Json wrong_type = Call("job.get", {{"job_id", "12"}});
  EXPECT_EQ(Code(wrong_type), rpc::kInvalidParams);
  EXPECT_EQ(wrong_type["error"]["data"]["path"], "params.job_id");
  EXPECT_EQ(Call("job.get", Json::object())["error"]["data"]["path"], "params.job_id");
  EXPECT_EQ(Call("job.get", {{"job_id", 1}, {"jobid", 1}})["error"]["data"]["path"],
            "params.jobid");
  const Json missing = Call("job.get", {{"job_id", 404}});
  EXPECT_EQ(Code(missing), rpc::kNoSuchJob);
  EXPECT_EQ(missing["error"]["data"]["job_id"], 404);
  EXPECT_EQ(Code(Call("job.get", {{"job_id", 1e300}})), rpc::kInvalidParams);
  // The id comes back as sent, string ids included.
  EXPECT_EQ(raw("{\"jsonrpc\":\"2.0\",\"id\":\"abc\",\"method\":\"server.info\"}")["id"], "abc");
}

// A store whose reads fail as libraries fail: with their own texts, and out of memory.
class ThrowingStore final : public ForwardingStore {
 public:
  using ForwardingStore::ForwardingStore;
  std::optional<JobRecord> GetJob(std::int64_t) override {
    throw std::runtime_error("[json.exception.type_error.302] SQLite internals: secret 0xdead");
  }
  JobPage ListJobs(const JobFilter&) override { throw std::bad_alloc(); }
};

TEST_F(RpcServiceTest, InternalErrorsAnswerDocumentedMessagesNotLibraryTexts) {
  MakeService(false);
  ThrowingStore throwing(*store_);
  RpcService service(throwing, *scheduler_, ServiceOptions{});
  auto call = [&](const std::string& method, const Json& params) {
    return proto::ParseJson(
        service.HandleMessage(rpc::Serialize(rpc::Request(++id_, method, params)), session_));
  };
  const Json failed = call("job.get", {{"job_id", 1}});
  EXPECT_EQ(Code(failed), rpc::kInternalError);
  EXPECT_EQ(failed["error"]["message"],
            "internal error: the request failed inside the server (incident 1 in its log)");
  EXPECT_EQ(failed["error"]["data"]["incident"], 1);
  EXPECT_EQ(failed.dump().find("secret"), std::string::npos);
  EXPECT_EQ(call("job.get", {{"job_id", 1}})["error"]["data"]["incident"], 2);
  const Json memory = call("job.list", Json::object());
  EXPECT_EQ(Code(memory), rpc::kInternalError);
  EXPECT_EQ(memory["error"]["message"],
            "internal error: out of memory: the server could not get the memory this request "
            "needs");
}

// A damaged row in the store: its own documented error with the number of its quarantine,
// not invalid params and not a job of another state; the same at every read; job.list lists
// the other jobs and this one apart, as quarantined; the server answers as before.
TEST_F(RpcServiceTest, ADamagedStoredJobIsCorruptionWithAnIncident) {
  MakeService(false);
  const std::int64_t id = Submit("paper-iso-5x5")["result"]["job"]["job_id"].get<std::int64_t>();
  const std::int64_t other = Submit("paper-iso-5x5")["result"]["job"]["job_id"].get<std::int64_t>();
  {
    SQLite::Database db((dir_ / "jobs.db").string(), SQLite::OPEN_READWRITE);
    db.exec("UPDATE jobs SET state = 'bogus' WHERE id = " + std::to_string(id));
  }
  for (int read = 0; read < 2; ++read) {
    const Json got = Call("job.get", {{"job_id", id}});
    ASSERT_TRUE(got.contains("error")) << got.dump();
    EXPECT_EQ(Code(got), rpc::kStoreCorrupt);
    EXPECT_EQ(got["error"]["data"]["incident"], 1);
    EXPECT_EQ(got["error"]["data"]["quarantined"], true);
    const std::string message = got["error"]["message"].get<std::string>();
    EXPECT_NE(message.find("the store holds a damaged record: job " + std::to_string(id) +
                           " is quarantined (quarantine incident 1)"),
              std::string::npos)
        << message;
    EXPECT_NE(message.find("unknown state 'bogus'"), std::string::npos) << message;
  }
  const Json list = Call("job.list", Json::object());
  ASSERT_TRUE(list.contains("result")) << list.dump();
  ASSERT_EQ(list["result"]["jobs"].size(), 1u) << list.dump();
  EXPECT_EQ(list["result"]["jobs"][0]["job_id"], other);
  ASSERT_EQ(list["result"]["quarantined"].size(), 1u) << list.dump();
  const Json& quarantined = list["result"]["quarantined"][0];
  EXPECT_EQ(quarantined["job_id"], id);
  EXPECT_EQ(quarantined["state"], "quarantined");
  EXPECT_EQ(quarantined["incident"], 1);
  EXPECT_EQ(quarantined["previous_state"], "bogus");
  EXPECT_NE(quarantined["reason"].get<std::string>().find("unknown state 'bogus'"),
            std::string::npos);
  EXPECT_TRUE(Call("server.info").contains("result"));
}

TEST_F(RpcServiceTest, AnUnknownListStateNamesEveryState) {
  MakeService(false);
  const Json r = Call("job.list", {{"state", "bogus"}});
  EXPECT_EQ(Code(r), rpc::kInvalidParams);
  EXPECT_NE(r["error"]["message"].get<std::string>().find(
                "(expected preparing, queued, running, succeeded, failed or cancelled)"),
            std::string::npos)
      << r.dump();
}

TEST(RpcServiceParse, SubmissionsAreFoundByTheirParsedMethod) {
  EXPECT_TRUE(
      RpcService::Parse(R"({"jsonrpc":"2.0","id":1,"method":"job.submit"})").prepares_scene);
  // The same method spelled with an escape: the text has no "job.submit" in it.
  EXPECT_TRUE(
      RpcService::Parse(R"({"jsonrpc":"2.0","id":1,"method":"job\u002esubmit"})").prepares_scene);
  EXPECT_TRUE(RpcService::Parse(R"([{"jsonrpc":"2.0","id":1,"method":"server.info"},)"
                                R"({"jsonrpc":"2.0","id":2,"method":"job.submit","params":{}}])")
                  .prepares_scene);
  // Mentioning the method elsewhere does not make a submission.
  EXPECT_FALSE(
      RpcService::Parse(
          R"({"jsonrpc":"2.0","id":1,"method":"job.list","params":{"label":"job.submit"}})")
          .prepares_scene);
  const RpcService::ParsedMessage bad = RpcService::Parse("{\"jsonrpc\":");
  EXPECT_FALSE(bad.prepares_scene);
  EXPECT_NE(bad.parse_error.find("parse error"), std::string::npos);
}

TEST_F(RpcServiceTest, NotificationsAndBatches) {
  MakeService(false);
  EXPECT_EQ(service_->HandleMessage("{\"jsonrpc\":\"2.0\",\"method\":\"server.info\"}", session_),
            "");
  EXPECT_EQ(service_->HandleMessage("[{\"jsonrpc\":\"2.0\",\"method\":\"server.info\"}]", session_),
            "");
  const Json batch = proto::ParseJson(service_->HandleMessage(
      "[{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"server.info\"}, 5, "
      "{\"jsonrpc\":\"2.0\",\"method\":\"job.list\"},"
      "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"job.get\",\"params\":{\"job_id\":9}}]",
      session_));
  ASSERT_TRUE(batch.is_array());
  ASSERT_EQ(batch.size(), 3u);
  EXPECT_EQ(batch[0]["result"]["name"], "springfitd");
  EXPECT_EQ(Code(batch[1]), rpc::kInvalidRequest);
  EXPECT_EQ(Code(batch[2]), rpc::kNoSuchJob);
  std::string big = "[";
  for (int i = 0; i < 101; ++i)
    big += std::string(i ? "," : "") + "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"server.info\"}";
  const Json too_big = proto::ParseJson(service_->HandleMessage(big + "]", session_));
  EXPECT_EQ(Code(too_big), rpc::kLimitExceeded);
  EXPECT_EQ(too_big["error"]["data"]["limit"], "max_batch");
}

TEST_F(RpcServiceTest, IdsAreEchoedExactlyAsSent) {
  MakeService(false);
  // 2^64 does not fit an integer: it came back as 1.8446744073709552e+19.
  std::string answer = service_->HandleMessage(
      R"({"jsonrpc":"2.0","id":18446744073709551616,"method":"server.info"})", session_);
  EXPECT_NE(answer.find(R"("id":18446744073709551616,)"), std::string::npos) << answer;
  answer = service_->HandleMessage(R"({"jsonrpc":"2.0","id":1.50,"method":"nope"})", session_);
  EXPECT_NE(answer.find(R"("id":1.50,)"), std::string::npos) << answer;
  EXPECT_EQ(proto::ParseJson(answer)["error"]["code"], rpc::kMethodNotFound);
  // In a batch, each its own, around a notification, an integer and a string.
  answer = service_->HandleMessage(
      R"([{"jsonrpc":"2.0","id":-0.0,"method":"server.info"},)"
      R"({"jsonrpc":"2.0","method":"server.info"},)"
      R"({"jsonrpc":"2.0","id":7,"method":"server.info","params":{"id":1.5e300}},)"
      R"({"jsonrpc":"2.0","id":"1e5","method":"server.info"},)"
      R"({"jsonrpc":"2.0","id":123456789012345678901234567890,"method":"server.info"}])",
      session_);
  const Json batch = proto::ParseJson(answer);
  ASSERT_EQ(batch.size(), 4u) << answer;
  EXPECT_NE(answer.find(R"("id":-0.0,)"), std::string::npos) << answer;
  EXPECT_EQ(batch[1]["id"], 7);
  EXPECT_EQ(batch[2]["id"], "1e5");
  EXPECT_NE(answer.find(R"("id":123456789012345678901234567890,)"), std::string::npos) << answer;
}

TEST_F(RpcServiceTest, TokenIsRequiredForJobMethods) {
  ServiceOptions o;
  o.token = "0123456789abcdef0123456789abcdef";
  MakeService(false, o);
  EXPECT_TRUE(Call("server.info")["result"]["auth_required"].get<bool>());
  EXPECT_EQ(Code(Call("job.list")), rpc::kUnauthorized);
  EXPECT_EQ(Code(Call("session.auth", {{"token", "0123456789abcdef0123456789abcdeX"}})),
            rpc::kUnauthorized);
  EXPECT_EQ(Code(Call("session.auth", {{"token", "0123456789abcdef"}})), rpc::kUnauthorized);
  EXPECT_EQ(Code(Call("job.list")), rpc::kUnauthorized);
  EXPECT_TRUE(Call("session.auth", {{"token", o.token}})["result"]["authenticated"].get<bool>());
  EXPECT_TRUE(Call("job.list")["result"]["jobs"].is_array());
}

TEST_F(RpcServiceTest, BadScenesAndLimitsAreRefusedAtSubmission) {
  ServiceOptions o;
  o.limits.max_nodes = 20;
  o.limits.max_queued = 2;
  MakeService(false, o);
  Json scene = Scene("paper-iso-5x5");
  const Json too_many = Call("job.submit", {{"scene", scene}});
  EXPECT_EQ(Code(too_many), rpc::kLimitExceeded);
  EXPECT_EQ(too_many["error"]["data"]["limit"], "max_nodes");
  EXPECT_EQ(too_many["error"]["data"]["value"], 25);

  Json small = Scene("paper-iso-5x5");
  small["nodes"] = Json::array({{0.0, 0.0}, {1.0, 0.0}});
  const Json bad = Call("job.submit", {{"scene", small}});
  EXPECT_EQ(Code(bad), rpc::kInvalidScene);
  EXPECT_FALSE(bad["error"]["data"]["path"].get<std::string>().empty());
  EXPECT_EQ(Code(Call("job.submit", {{"scene", "file.json"}})), rpc::kInvalidParams);
  EXPECT_EQ(Code(Call("job.submit", {{"scene", Json::object()}, {"label", 3}})),
            rpc::kInvalidParams);
  EXPECT_EQ(Code(Call("job.submit", {{"scene", Json::object()}, {"priority", 5000}})),
            rpc::kInvalidParams);
  EXPECT_EQ(store_->ListJobs({}).jobs.size(), 0u);  // nothing stored

  ServiceOptions roomy;
  roomy.limits.max_queued = 2;
  MakeService(false, roomy);
  EXPECT_TRUE(Submit("paper-iso-5x5")["result"]["created"].get<bool>());
  EXPECT_TRUE(Submit("paper-iso-5x5")["result"]["created"].get<bool>());
  EXPECT_EQ(Code(Submit("paper-iso-5x5")), rpc::kBusy);
}

TEST_F(RpcServiceTest, SearchBoundsAreCheckedBeforeTheWork) {
  ServiceOptions o;
  o.limits.max_population = 1000;
  o.limits.max_candidates = 100000;
  o.limits.max_population_genes = 50000;
  MakeService(false, o);
  // A population of 1e8 was stored as a job (and re-queued at every restart).
  Json scene = Scene("paper-iso-5x5");
  scene["search"] = {{"population", 100000000}};
  Json refused = Call("job.submit", {{"scene", scene}});
  EXPECT_EQ(Code(refused), rpc::kLimitExceeded);
  EXPECT_EQ(refused["error"]["data"]["limit"], "max_population");
  EXPECT_EQ(refused["error"]["data"]["value"], 100000000);

  // 3,000 nodes and a radius that takes every pair (4.5 million): refused from the estimate,
  // before a single candidate is generated.
  Json big = Scene("paper-iso-5x5");
  Json nodes = Json::array();
  for (int i = 0; i < 3000; ++i) nodes.push_back({0.001 * (i % 60), 0.001 * (i / 60)});
  big["nodes"] = nodes;
  big["candidates"] = {{"type", "radius"}, {"radius", 10.0}};
  refused = Call("job.submit", {{"scene", big}});
  EXPECT_EQ(Code(refused), rpc::kLimitExceeded);
  EXPECT_EQ(refused["error"]["data"]["limit"], "max_candidates");
  EXPECT_GT(refused["error"]["data"]["value"].get<std::int64_t>(), 100000);

  // 72 genes x a population of 800 = 57,600 bytes a generation, above 50,000.
  scene["search"] = {{"population", 800}};
  refused = Call("job.submit", {{"scene", scene}});
  EXPECT_EQ(Code(refused), rpc::kLimitExceeded);
  EXPECT_EQ(refused["error"]["data"]["limit"], "max_population_genes");
  EXPECT_EQ(refused["error"]["data"]["value"], 57600);
  EXPECT_EQ(store_->ListJobs({}).jobs.size(), 0u);  // nothing stored

  scene["search"] = {{"population", 600}};
  EXPECT_TRUE(Call("job.submit", {{"scene", scene}})["result"]["created"].get<bool>());
  const Json limits = Call("server.info")["result"]["limits"];
  EXPECT_EQ(limits["max_population"], 1000);
  EXPECT_EQ(limits["max_candidates"], 100000);
  EXPECT_EQ(limits["max_population_genes"], 50000);
}

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

// Bounds on what one request can make the daemon hold or send: scene names, watches per
// connection, bytes per job.list page.
TEST_F(RpcServiceTest, NamesWatchesAndListPagesAreBounded) {
  ServiceOptions options;
  options.limits.max_watches = 3;
  options.limits.max_list_bytes = 2000;  // a few jobs a page
  MakeService(false, options);
  Json long_name = Scene("paper-iso-5x5");
  long_name["name"] = std::string(201, 'n');
  Json params;
  params["scene"] = long_name;
  const Json refused = Call("job.submit", params);
  ASSERT_TRUE(refused.contains("error")) << refused.dump();
  EXPECT_EQ(Code(refused), rpc::kInvalidScene);
  EXPECT_EQ(refused["error"]["data"]["path"], "scene.name");
  long_name["name"] = std::string(200, 'n');
  params["scene"] = long_name;
  EXPECT_TRUE(Call("job.submit", params).contains("result"));

  std::vector<std::int64_t> ids;
  for (int i = 0; i < 11; ++i)
    ids.push_back(Submit("paper-iso-5x5")["result"]["job"]["job_id"].get<std::int64_t>());
  for (int i = 0; i < 3; ++i) {
    Json p;
    p["job_id"] = ids[static_cast<std::size_t>(i)];
    EXPECT_TRUE(Call("job.watch", p).contains("result")) << "watch " << i;
  }
  Json p;
  p["job_id"] = ids[3];
  const Json fourth = Call("job.watch", p);
  ASSERT_TRUE(fourth.contains("error")) << fourth.dump();
  EXPECT_EQ(Code(fourth), rpc::kLimitExceeded);
  EXPECT_EQ(fourth["error"]["data"]["limit"], "max_watches");
  // Finished watches feed nothing more and do not count: once the three watched jobs end
  // (cancelled while queued, each one's job.finished sent), the connection watches again (the
  // count had grown for good, and after 100 watches a client could never watch again).
  for (int i = 0; i < 3; ++i) {
    Json c;
    c["job_id"] = ids[static_cast<std::size_t>(i)];
    EXPECT_EQ(Call("job.cancel", c)["result"]["state"], "cancelled");
  }
  for (int spin = 0; spin < 600; ++spin) {  // up to 6 s for the three notifications
    int finished = 0;
    for (const Json& m : inbox_.All()) finished += m["method"] == "job.finished" ? 1 : 0;
    if (finished >= 3) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  for (int i = 3; i < 6; ++i) {
    Json w;
    w["job_id"] = ids[static_cast<std::size_t>(i)];
    EXPECT_TRUE(Call("job.watch", w).contains("result")) << "watch " << i << " after three ended";
  }
  Json seventh;
  seventh["job_id"] = ids[6];
  EXPECT_EQ(Code(Call("job.watch", seventh)), rpc::kLimitExceeded);  // three open again

  // Every job once, in order, over pages cut by bytes rather than by the count asked for.
  std::vector<std::int64_t> listed;
  Json cursor = nullptr;
  int pages = 0;
  do {
    Json q;
    q["limit"] = 100;
    if (!cursor.is_null()) q["cursor"] = cursor;
    const Json page = Call("job.list", q)["result"];
    EXPECT_LE(page["jobs"].dump().size(), 2000u + 600u);  // the bound, and at most one job past it
    for (const Json& j : page["jobs"]) listed.push_back(j["job_id"].get<std::int64_t>());
    cursor = page["next_cursor"];
    ++pages;
  } while (!cursor.is_null() && pages < 50);
  EXPECT_GT(pages, 2);
  EXPECT_EQ(listed.size(), 12u);
  EXPECT_TRUE(std::is_sorted(listed.begin(), listed.end()));
}

}  // namespace
}  // namespace springfit::server
