// The dashboard's HTTP server: health and metrics answer while every page thread is busy
// (issue 32 item 4: two figure requests of large jobs used to make a health check time out).
#include "server/net/http_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <thread>

#include <SQLiteCpp/SQLiteCpp.h>
#include <gtest/gtest.h>
#include <boost/asio/io_context.hpp>

#include "engine/identification/identify.h"
#include "io/example_catalog.h"
#include "proto/outcome_codec.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "server/jobs/scheduler.h"
#include "server/store/forwarding_store.h"
#include "server/store/sqlite_store.h"
#include "server/web/dashboard.h"
#include "server/web/metrics.h"

namespace springfit::server {
namespace {

// Whether `body` (a page) holds `text`; a failure prints the page.
::testing::AssertionResult Holds(const std::string& body, const std::string& text) {
  if (body.find(text) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "the page lacks \"" << text << "\":\n" << body;
}

// Job reads stall until released (a figure building a large job's problem stands for them).
class StallingStore final : public ForwardingStore {
 public:
  using ForwardingStore::ForwardingStore;
  std::atomic<bool> stall{false};
  std::atomic<int> stalled{0};
  std::optional<JobRecord> GetJob(std::int64_t id) override {
    ++stalled;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (stall.load() && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    --stalled;
    return inner_.GetJob(id);
  }
};

// GET `target` on 127.0.0.1:port; the status line, or "" when no answer came within 10 s.
std::string Get(unsigned short port, const std::string& target) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  timeval timeout{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(port);
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string status;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0) {
    const std::string request =
        "GET " + target + " HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
    if (::send(fd, request.data(), request.size(), 0) == static_cast<ssize_t>(request.size())) {
      char buffer[256];
      const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
      if (n > 0) status.assign(buffer, static_cast<std::size_t>(n));
      status = status.substr(0, status.find("\r\n"));
    }
  }
  ::close(fd);
  return status;
}

TEST(HttpServer, HealthAndMetricsAnswerWhilePagesKeepEveryThreadBusy) {
  const auto dir = std::filesystem::temp_directory_path() / "springfit-http-health";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  {
    SqliteStore sqlite((dir / "jobs.db").string());
    StallingStore store(sqlite);
    Metrics metrics;
    Scheduler scheduler(store, SchedulerOptions{});
    Dashboard dashboard(store, scheduler, metrics, DashboardOptions{});
    boost::asio::io_context io;
    HttpServerOptions options;
    options.port = 0;
    options.handler_threads = 2;
    HttpServer http(io, dashboard, options);
    http.Start();
    std::thread loop([&] { io.run(); });

    store.stall = true;
    std::thread page1([&] { Get(http.port(), "/jobs/1/error.svg"); });
    std::thread page2([&] { Get(http.port(), "/jobs/1/topology.svg"); });
    const auto busy_by = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (store.stalled.load() < 2 && std::chrono::steady_clock::now() < busy_by)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ASSERT_EQ(store.stalled.load(), 2) << "the two page requests did not reach the store";

    for (const char* target : {"/healthz", "/metrics"}) {
      const auto start = std::chrono::steady_clock::now();
      const std::string status = Get(http.port(), target);
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      EXPECT_EQ(status, "HTTP/1.1 200 OK") << target;
      EXPECT_LT(seconds, 2.0) << target << " waited behind the pages";
    }
    store.stall = false;
    page1.join();
    page2.join();
    http.Stop();
    io.stop();
    loop.join();
  }
  std::filesystem::remove_all(dir);
}

// The job page opens with the result card and links a large figure instead of inlining it
// (issue 33 item 4).
// A finished job of paper-iso-5x5 in `store`, its result JSON (its outcome too) passed through
// `edit` first; returns the job's page path.
std::string FinishedPaperJob(SqliteStore& store,
                             const std::function<void(proto::Json&)>& edit = {}) {
  const Scene scene = examples::Make("paper-iso-5x5");
  const Problem problem(scene);
  const IdentificationResult r = RunIdentification(
      problem, ResolveSearchOptions(scene.search, problem.gene_count()), RunContext{});
  NewJob job;
  job.record.label = "figure";
  job.record.scene_name = scene.name;
  job.record.genes = problem.gene_count();
  job.record.strategy = "direct";
  job.scene_json = proto::SceneToJson(scene).dump();
  const std::int64_t id = store.CreateJob(job, 100).job.id;
  const std::optional<Claim> claim = store.ClaimNext("test", 30.0);
  EXPECT_TRUE(claim);
  proto::Json result = proto::ResultToJson(problem, r, false);
  if (edit) edit(result);
  // (The outcome column as the result's, edited or not.)
  store.MarkFinished(claim->lease,
                     {JobState::kSucceeded, "", result.dump(), r.exact(), 1.7e9,
                      result.value("outcome", proto::OutcomeToJson(r.outcome)).dump()});
  return "/jobs/" + std::to_string(id);
}

// A dashboard over a fresh SQLite store in a temporary directory of its own (removed at the end).
struct DashboardOnStore {
  explicit DashboardOnStore(const std::string& name)
      : dir(Fresh(std::filesystem::temp_directory_path() / name)),
        store((dir / "jobs.db").string()),
        scheduler(store, SchedulerOptions{}) {}
  ~DashboardOnStore() { std::filesystem::remove_all(dir); }
  HttpResponse Get(const std::string& target, const DashboardOptions& options = {}) {
    Dashboard dashboard(store, scheduler, metrics, options);
    return dashboard.Handle({"GET", target, {}, ""});
  }
  static std::filesystem::path Fresh(const std::filesystem::path& path) {
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
    return path;
  }
  std::filesystem::path dir;
  SqliteStore store;
  Metrics metrics;
  Scheduler scheduler;
};

TEST(Dashboard, TheJobPageLinksALargeFigureInsteadOfInliningIt) {
  DashboardOnStore d("springfit-dashboard-figure");
  const std::string target = FinishedPaperJob(d.store);
  const std::string img = "<img src=\"" + target + "/topology.svg?of=result\"";
  for (const std::size_t limit : {std::size_t{1} << 30, std::size_t{1000}}) {
    DashboardOptions options;
    options.max_inline_figure_bytes = limit;
    const HttpResponse page = d.Get(target, options);
    ASSERT_EQ(page.status, 200) << page.body;
    const bool linked = limit < 1000000;
    EXPECT_EQ(page.body.find("<figure id=\"topology\"><svg") != std::string::npos, !linked);
    EXPECT_EQ(page.body.find(img) != std::string::npos, linked);
    EXPECT_LT(page.body.find("id=\"result-card\""), page.body.find("id=\"topology\""));
  }
}

// Issue 31: a result whose dependent groups were not analysed (too many seen genes) shows no
// count of groups but the reason, where an analysed one shows its count.
TEST(Dashboard, GroupsNotAnalysedAreNotCountedOnTheJobPage) {
  DashboardOnStore d("springfit-dashboard-groups");
  const std::string analysed = FinishedPaperJob(d.store);
  const std::string not_analysed = FinishedPaperJob(d.store, [](proto::Json& result) {
    result["identifiability"]["analysed"] = false;
    result["identifiability"]["rank"] = nullptr;
    result["identifiability"]["groups"] = proto::Json::array();
    result["identifiability"]["not_analysed"] = "more than 5 seen genes";
  });
  const std::string row = "<tr><th>groups of springs the loads do not tell apart</th><td>";
  const HttpResponse counted = d.Get(analysed);
  ASSERT_EQ(counted.status, 200) << counted.body;
  EXPECT_TRUE(Holds(counted.body, row + "0</td>"));
  const HttpResponse page = d.Get(not_analysed);
  ASSERT_EQ(page.status, 200) << page.body;
  EXPECT_EQ(page.body.find(row + "0</td>"), std::string::npos);
  EXPECT_TRUE(Holds(page.body, row + "not analysed (more than 5 seen genes)</td>"));
  EXPECT_EQ(page.body.find("rank of the analysed groups"), std::string::npos);
}

// Issue 47 item 5: the springs between held nodes are named on the job page as check and run
// name them, apart from the unseen ones (the page said "unseen springs 0" beside check's 635).
TEST(Dashboard, TheSpringsBetweenHeldNodesAreCountedApartFromTheUnseen) {
  DashboardOnStore d("springfit-dashboard-held");
  const std::string target = FinishedPaperJob(
      d.store, [](proto::Json& result) { result["outcome"]["unseen_springs"] = 635; });
  const HttpResponse page = d.Get(target);
  ASSERT_EQ(page.status, 200) << page.body;
  EXPECT_TRUE(Holds(page.body,
                    "<tr><th>between held nodes</th><td>635 springs (both nodes held in every load "
                    "case: " +
                        proto::HeldSpringsText(false) + ")</td>"));
  EXPECT_TRUE(Holds(page.body,
                    "<tr><th>unseen springs (no load case changes their length)</th><td>0 "
                    "besides the 635 between held nodes</td>"));
  const HttpResponse plain = d.Get(FinishedPaperJob(d.store));
  EXPECT_EQ(plain.body.find("between held nodes"), std::string::npos);
}

// Issue 50: the job page shows the tool loads (the shape's E and the tool's force error, beside
// the baseline's, over how many pushes and grasps) and the nonlinear fit's choosing errors, in the
// summary's words.
TEST(Dashboard, TheJobPageShowsToolPushesAndTheNonlinearFit) {
  DashboardOnStore d("springfit-dashboard-pushes");
  const std::string target = FinishedPaperJob(d.store, [](proto::Json& result) {
    proto::Json g = proto::Json::object();
    g["tool_pushes"] = proto::Json::array({{{"amplitude", 1.0},
                                            {"model", {{"median", 0.159}}},
                                            {"baseline", {{"median", 0.16}}},
                                            {"model_force", {{"median", 0.126}}},
                                            {"baseline_force", {{"median", 0.152}}},
                                            {"pushes", 10},
                                            {"grasps", 8},
                                            {"model_inverted", 2}}});
    g["fit"] = {{"nonlinear",
                 {{"gauss_newton_steps", 12},
                  {"start_choosing_rms_error", 0.124},
                  {"choosing_rms_error", 0.123},
                  {"baseline_choosing_rms_error", 0.319},
                  {"fitted_left_out", 3},
                  {"failed", 2}}}};
    result["generalization"] = g;
  });
  const HttpResponse page = d.Get(target);
  ASSERT_EQ(page.status, 200) << page.body;
  EXPECT_TRUE(Holds(page.body,
                    "<tr><th>tool push at 100% of the loads</th><td>median E 0.159, "
                    "tool force error 0.126 (baseline 0.16, 0.152); 2 invert an "
                    "element over 10 pushes and 8 grasps</td>"));
  EXPECT_TRUE(
      Holds(page.body,
            "<tr><th>nonlinear fit</th><td>12 Gauss-Newton steps: choosing E "
            "0.124 at rest-linear fit, 0.123 returned (baseline 0.319); 3 fitted equilibria "
            "left out (the rest-linear model folds there or has none); 2 choosing "
            "equilibria not found (a fold or no equilibrium)</td>"));
}

// Issue 47: a doubtful result's card says its doubts and, as `springfit run` does, where to
// read what changes them.
TEST(Dashboard, ADoubtfulResultsCardPointsToWhatToTry) {
  DashboardOnStore d("springfit-dashboard-doubtful");
  const std::string target = FinishedPaperJob(d.store, [](proto::Json& result) {
    result["outcome"]["verdict"] = "doubtful";
    result["outcome"]["doubts"] = proto::Json::array({"the certificate: a soft mode"});
  });
  const HttpResponse page = d.Get(target);
  ASSERT_EQ(page.status, 200) << page.body;
  EXPECT_TRUE(Holds(page.body,
                    "<tr><th>WARNING</th><td>the certificate: a soft mode</td></tr>\n"
                    "<tr><th>what to try</th><td>proto/RUN.md, &quot;What to "
                    "try&quot;: what changes each doubt, and what it costs</td></tr>"));
}

// Issue 48: a job whose row cannot be read is listed apart, as quarantined, with its incident
// and its reason (escaped: it quotes the damaged value); its page says why it cannot be shown.
TEST(Dashboard, AQuarantinedJobIsListedApartWithItsIncident) {
  const auto dir = std::filesystem::temp_directory_path() / "springfit-dashboard-quarantine";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  {
    SqliteStore store((dir / "jobs.db").string());
    NewJob job;
    job.record.label = "fine";
    job.record.scene_name = "s";
    job.scene_json = "{}";
    const std::int64_t fine = store.CreateJob(job, 100).job.id;
    const std::int64_t damaged = store.CreateJob(job, 100).job.id;
    {
      SQLite::Database db((dir / "jobs.db").string(), SQLite::OPEN_READWRITE);
      db.exec("UPDATE jobs SET state = '<b>x</b>' WHERE id = " + std::to_string(damaged));
    }
    Metrics metrics;
    Scheduler scheduler(store, SchedulerOptions{});
    Dashboard dashboard(store, scheduler, metrics, DashboardOptions{});
    const HttpResponse list = dashboard.Handle({"GET", "/", {}, ""});
    ASSERT_EQ(list.status, 200) << list.body;
    EXPECT_NE(list.body.find("<a href=\"/jobs/" + std::to_string(fine) + "\">"), std::string::npos);
    const std::size_t table = list.body.find("<table id=\"quarantined\">");
    ASSERT_NE(table, std::string::npos) << list.body;
    EXPECT_NE(list.body.find("<tr><td>" + std::to_string(damaged) + "</td><td>1</td>", table),
              std::string::npos)
        << list.body;
    EXPECT_NE(list.body.find("unknown state '&lt;b&gt;x&lt;/b&gt;'", table), std::string::npos)
        << list.body;
    EXPECT_NE(list.body.find("<td>&lt;b&gt;x&lt;/b&gt;</td></tr>", table), std::string::npos)
        << list.body;  // the state before
    EXPECT_EQ(list.body.find("<b>x</b>"), std::string::npos);
    const HttpResponse page = dashboard.Handle({"GET", "/jobs/" + std::to_string(damaged), {}, ""});
    EXPECT_TRUE(Holds(page.body, "is quarantined (quarantine incident 1)"));
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace springfit::server
