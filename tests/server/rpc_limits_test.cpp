// The bounds RpcService keeps (rpc_service_test_support.h): bad scenes and limits refused at
// submission, search bounds checked before the work, and names, watches and list pages bounded.
#include "server/rpc/rpc_service.h"

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "proto/rpc.h"
#include "tests/server/rpc_service_test_support.h"

namespace springfit::server {
namespace {

using proto::Json;
namespace rpc = proto::rpc;

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
