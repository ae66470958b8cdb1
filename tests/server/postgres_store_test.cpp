// The PostgreSQL store alone (server/store/postgres_store.h), on the private server of
// tests/server/with_postgres.sh: wake-ups across stores, migrations at once, the watchdog,
// and reads on free connections.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "server/store/job_store.h"
#include "server/store/postgres_store.h"
#include "tests/server/store_suite_test_support.h"
#include "tests/server/store_test_data.h"

namespace springfit::server {
namespace {

using namespace std::chrono_literals;

// PostgreSQL alone: a change made through one daemon's store wakes the others' listeners.
TEST(PostgresStoreOnly, AJobSubmittedThroughOneStoreWakesTheOthers) {
  PostgresFactory factory("t_wakeup");
  std::unique_ptr<JobStore> a = factory.Open();
  std::unique_ptr<JobStore> b = factory.Second();
  std::atomic<int> wakes{0};
  b->SetChangeListener([&] { ++wakes; });
  std::this_thread::sleep_for(300ms);  // its LISTEN is in place
  const int before = wakes.load();
  a->CreateJob(NewJob{[] {
                        JobRecord r;
                        r.label = "x";
                        r.scene_name = "s";
                        r.strategy = "paper";
                        return r;
                      }(),
                      "{}", "", 10.0},
               10);
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (wakes.load() == before && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(10ms);
  EXPECT_GT(wakes.load(), before) << "no wake-up within 5 s";
}

// PostgreSQL alone: daemons starting together on a new database migrate it once (under the
// advisory lock); none fails on a table another created.
TEST(PostgresStoreOnly, DaemonsStartingTogetherMigrateOnce) {
  PostgresFactory factory("t_migrate_together");
  std::vector<std::future<int>> opens;
  std::atomic<int> ready{0};
  for (int i = 0; i < 4; ++i) {
    opens.push_back(std::async(std::launch::async, [&] {
      ++ready;
      while (ready.load() < 4) std::this_thread::yield();
      auto store = factory.Open();
      return static_cast<PostgresStore&>(*store).schema_version();
    }));
  }
  for (auto& f : opens) EXPECT_EQ(f.get(), PostgresStore::kSchemaVersion);
}

// PostgreSQL alone: a call whose deadline passes after its last round trip succeeds, and the
// watchdog shuts its socket all the same. The next call on that connection (the writer's, here
// a progress write; a reader's) must not fail on the dead socket: the connection is replaced.
TEST(PostgresStoreOnly, AWatchdogFiringAfterASuccessfulCallLeavesNoDeadConnection) {
  PostgresFactory factory("t_late_watchdog");
  std::atomic<bool> linger{false};
  PostgresStore::Options options;
  options.call_seconds = 1.0;
  options.readers = 1;
  // The call has answered; its end comes after the deadline (and the watchdog's 50 ms beat).
  options.on_call_end = [&] {
    if (linger.exchange(false)) std::this_thread::sleep_for(1500ms);
  };
  PostgresStore store(factory.url(), "", options);
  const std::int64_t id = store.CreateJob(StoreTestJob("late"), 10).job.id;
  const std::optional<Claim> claim = store.ClaimNext("d", 30.0);
  ASSERT_TRUE(claim);
  linger = true;
  EXPECT_TRUE(store.RenewLease(claim->lease, 30.0).held);
  ProgressBatch batch;
  batch.latest = StoreTestRow(1, 0.5);
  EXPECT_NO_THROW(store.SaveProgress(claim->lease, batch));
  linger = true;
  EXPECT_TRUE(store.GetJob(id));
  try {
    const std::optional<JobRecord> job = store.GetJob(id);
    ASSERT_TRUE(job && job->progress);
    EXPECT_EQ(job->progress->generation, 1);
  } catch (const StoreUnavailable& e) {
    ADD_FAILURE() << "the reader kept the connection the watchdog shut: " << e.what();
  }
}

// PostgreSQL alone: a read takes a reading connection no call holds. One read held on its
// connection (a slow query) must not delay the others, which the other connection serves
// within server.info's kind of deadline.
TEST(PostgresStoreOnly, AReadTakesAFreeConnectionWhileAnotherIsHeld) {
  PostgresFactory factory("t_free_reader");
  std::atomic<bool> hold_next{false};
  std::atomic<bool> holding{false};
  std::atomic<bool> release{false};
  PostgresStore::Options options;
  options.readers = 2;
  // The next call to end holds its connection until released (its thread: the slow read's).
  options.on_call_end = [&] {
    if (!hold_next.exchange(false)) return;
    holding = true;
    while (!release.load()) std::this_thread::sleep_for(5ms);
  };
  PostgresStore store(factory.url(), "", options);
  const std::int64_t id = store.CreateJob(StoreTestJob("read"), 10).job.id;
  hold_next = true;
  auto slow = std::async(std::launch::async, [&] { return store.GetJob(id).has_value(); });
  // (Released however the test ends: `slow` waits for its thread.)
  const std::shared_ptr<void> release_at_end(nullptr, [&](void*) { release = true; });
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while (!holding.load() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(5ms);
  ASSERT_TRUE(holding.load()) << "the slow read did not start";
  for (int i = 0; i < 6; ++i) {
    SCOPED_TRACE("read " + std::to_string(i));
    const ScopedStoreDeadline within(1.0);
    const auto start = std::chrono::steady_clock::now();
    EXPECT_NO_THROW(EXPECT_TRUE(store.GetJob(id)));
    EXPECT_NO_THROW(EXPECT_EQ(store.CountQueued(), 1));
    EXPECT_LT(std::chrono::steady_clock::now() - start, 1s);
  }
  release = true;
  EXPECT_TRUE(slow.get());
}

}  // namespace
}  // namespace springfit::server
