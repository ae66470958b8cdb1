// The daemon's methods without sockets: RpcService over a real SQLite store and scheduler
// (rpc_service_test_support.h). This file: the protocol (standard and internal errors, a
// damaged row, notifications, batches, ids, the token); rpc_job_methods_test.cpp has the
// job methods and rpc_limits_test.cpp the bounds.
#include "server/rpc/rpc_service.h"

#include <cstdint>
#include <new>
#include <optional>
#include <stdexcept>
#include <string>

#include <SQLiteCpp/SQLiteCpp.h>
#include <gtest/gtest.h>

#include "proto/rpc.h"
#include "server/store/forwarding_store.h"
#include "tests/server/rpc_service_test_support.h"

namespace springfit::server {
namespace {

using proto::Json;
namespace rpc = proto::rpc;

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

}  // namespace
}  // namespace springfit::server
