// The cost of the store's scheduling statements (bench/RESULTS.md, "Several daemons on one
// database"): N jobs submitted, then each claimed (ClaimNext, from a queue of N down to 1,
// beside the finished ones), renewed (RenewLease, the heartbeat), written to (a fenced
// progress write of one trace row) and finished, on the store given by --store. For PostgreSQL run
// it through tests/server/with_postgres.sh and pass --store "$SPRINGFIT_TEST_PG_URL".
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <vector>

#include <CLI/CLI.hpp>

#include "server/store/store_url.h"

namespace {
using namespace springfit::server;
using Clock = std::chrono::steady_clock;

void Report(const char* what, std::vector<double> us) {
  std::sort(us.begin(), us.end());
  std::printf("%-28s %6zu calls: median %8.1f us, p99 %8.1f us\n", what, us.size(),
              us[us.size() / 2], us[(us.size() - 1) * 99 / 100]);
}

template <typename F>
double Time(F&& f) {
  const auto t0 = Clock::now();
  f();
  return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"store_bench: claim, heartbeat and fenced-write costs of a job store"};
  std::string url;
  int jobs = 2000;
  app.add_option("--store", url, "sqlite:///FILE (created fresh) or postgresql://...")->required();
  app.add_option("--jobs", jobs, "Jobs queued, then claimed one by one")
      ->check(CLI::Range(10, 1000000));
  CLI11_PARSE(app, argc, argv);

  StoreLocation location = ParseStoreUrl(url);
  if (location.kind == StoreLocation::Kind::kSqlite) std::filesystem::remove(location.path);
  const std::unique_ptr<JobStore> store = OpenStore(location);
  std::printf("store %s, %d jobs\n", store->Describe().c_str(), jobs);

  NewJob job;
  job.record.label = "bench";
  job.record.scene_name = "s";
  job.record.strategy = "paper";
  job.record.genes = 72;
  job.scene_json = std::string(20000, ' ') + "{}";  // about a 5x5 scene's size
  std::vector<double> create, claim, renew, save;
  for (int i = 0; i < jobs; ++i) create.push_back(Time([&] { store->CreateJob(job, jobs + 1); }));
  ProgressBatch batch;
  springfit::TraceRow row;
  batch.trace.push_back(row);
  batch.latest = row;
  for (int i = 0; i < jobs; ++i) {
    std::optional<Claim> c;
    claim.push_back(Time([&] { c = store->ClaimNext("bench", 60.0); }));
    renew.push_back(Time([&] { store->RenewLease(c->lease, 60.0); }));
    save.push_back(Time([&] { store->SaveProgress(c->lease, batch); }));
    store->MarkFinished(c->lease, {JobState::kSucceeded, "", "{}", true, 0.0, ""});
  }
  Report("submit (CreateJob)", create);
  Report("claim (ClaimNext)", claim);
  Report("heartbeat (RenewLease)", renew);
  Report("fenced write (1 trace row)", save);
  return 0;
}
