// The PostgreSQL store alone (server/store/postgres_store.h), on the private server of
// tests/server/with_postgres.sh: wake-ups across stores, migrations at once, the watchdog,
// and reads on free connections.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include <pqxx/pqxx>

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

// PostgreSQL alone: a call that runs out of time while the daemon itself is stopped (SIGSTOP
// past the call's limit, as a frozen host does) still ends, but its error names the daemon's
// stall, not a database that did not answer; the same call past its limit with the daemon
// running blames the database. (The call waits on a table lock another session holds.)
TEST(PostgresStoreOnly, ACallThatTimesOutWhileTheDaemonIsStoppedSaysSo) {
  PostgresFactory factory("t_stalled_call");
  PostgresStore::Options options;
  options.call_seconds = 1.5;
  options.readers = 1;
  PostgresStore store(factory.url(), "", options);
  const std::int64_t id = store.CreateJob(StoreTestJob("stalled"), 10).job.id;
  pqxx::connection locker(factory.url());
  pqxx::work lock(locker);
  lock.exec("LOCK TABLE jobs IN ACCESS EXCLUSIVE MODE");
  const auto message = [&] {
    try {
      store.GetJob(id);
    } catch (const StoreUnavailable& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  // Running: the database's delay.
  const std::string running = message();
  EXPECT_NE(running.find("did not answer within 1.5 s"), std::string::npos) << running;
  // Stopped from 0.3 s to 3.3 s into the call by a child process (which only sleeps and
  // signals: safe after fork in a threaded process).
  const pid_t self = ::getpid();
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::usleep(300000);
    ::kill(self, SIGSTOP);
    ::sleep(3);
    ::kill(self, SIGCONT);
    ::_exit(0);
  }
  const std::string stopped = message();
  ::waitpid(child, nullptr, 0);
  EXPECT_NE(stopped.find("this daemon itself did not run for"), std::string::npos) << stopped;
  EXPECT_NE(stopped.find("not the database's"), std::string::npos) << stopped;
  EXPECT_EQ(stopped.find("did not answer"), std::string::npos) << stopped;
  lock.abort();
  EXPECT_TRUE(store.GetJob(id));  // the store works on once the lock is gone
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

// Restarts tests/server/with_postgres.sh's server (`pg_ctl restart -m MODE`, as the user that
// runs it); returns pg_ctl's exit status.
int RestartServer(const std::string& mode) {
  const char* dir = std::getenv("SPRINGFIT_TEST_PG_DIR");
  const char* bin = std::getenv("SPRINGFIT_TEST_PG_BIN");
  if (!dir || !bin) return -1;
  const std::string as_server = ::geteuid() == 0 ? "runuser -u postgres -- " : "";
  const std::string command = as_server + bin + "/pg_ctl -D " + dir + "/data -l " + dir +
                              "/server.log -m " + mode + " -w -t 30 restart >/dev/null 2>&1";
  return std::system(command.c_str());
}

// The pids of the sessions open on `factory`'s database, but the asking one's.
std::vector<int> SessionPids(PostgresFactory& factory) {
  pqxx::connection c(factory.url());
  const pqxx::result r = pqxx::nontransaction(c).exec(
      "SELECT pid FROM pg_stat_activity WHERE datname = current_database() AND pid <> "
      "pg_backend_pid()");
  std::vector<int> pids;
  for (const auto& row : r) pids.push_back(row[0].as<int>());
  return pids;
}

// Until every process of `pids` has exited (its sockets closed), at most 30 s.
void WaitUntilGone(const std::vector<int>& pids) {
  for (int pid : pids) {
    for (int i = 0; i < 3000 && ::kill(pid, 0) == 0; ++i) std::this_thread::sleep_for(10ms);
    EXPECT_NE(::kill(pid, 0), 0) << "session " << pid << " still there after 30 s";
  }
}

// Until the server takes a new session (after a restart or a crash recovery), at most 30 s.
void WaitUntilAccepting(const std::string& url) {
  for (int i = 0; i < 300; ++i) {
    try {
      pqxx::connection c(url);
      pqxx::nontransaction(c).exec("SELECT 1");
      return;
    } catch (const std::exception&) {
      std::this_thread::sleep_for(100ms);
    }
  }
  ADD_FAILURE() << "the server takes no session 30 s after its restart";
}

// PostgreSQL alone: the server drops the store's connections (a restart, an administrator's
// pg_terminate_backend, a backend killed). The store's next calls find their connections
// closed before using them and open new ones: they succeed. A statement the drop cuts off is
// "the store is unavailable" (the daemon's callers retry, a job keeps its lease), never an
// internal error, and the call after it works. (The hour's soak met "database: server closed
// the connection unexpectedly" as an internal error of job.submit after a PostgreSQL restart;
// CI met a write that committed just before a restart ended its session, and the next call
// failing on that connection.)
TEST(PostgresStoreOnly, ConnectionsTheServerDroppedAreReplacedAndACutOffStatementIsUnavailable) {
  PostgresFactory factory("t_dropped");
  PostgresStore::Options options;
  options.readers = 1;
  PostgresStore store(factory.url(), "", options);
  const std::int64_t id = store.CreateJob(StoreTestJob("before"), 10).job.id;
  ASSERT_TRUE(store.GetJob(id));
  // An administrator's termination (the server says why: SQLSTATE 57P01), a backend that dies
  // without a word (SIGKILL, the OOM killer: the server resets every session and recovers by
  // itself), then the server restarted fast and immediately (an immediate stop closes the
  // sockets with nothing said).
  for (const char* drop : {"terminate", "kill", "fast", "immediate", "immediate"}) {
    SCOPED_TRACE(drop);
    const std::vector<int> sessions = SessionPids(factory);  // the writer's, reader's, listener's
    ASSERT_FALSE(sessions.empty());
    if (std::string(drop) == "terminate") {
      for (int pid : sessions)
        factory.ExecRaw("SELECT pg_terminate_backend(" + std::to_string(pid) + ")");
    } else if (std::string(drop) == "kill") {
      for (int pid : sessions) ::kill(pid, SIGKILL);
    } else {
      ASSERT_EQ(RestartServer(drop), 0) << "pg_ctl restart -m " << drop;
    }
    WaitUntilGone(sessions);
    WaitUntilAccepting(factory.url());
    // The writer's call, then the reader's, each on a connection the server closed.
    EXPECT_NO_THROW(store.CreateJob(StoreTestJob("dropped"), 10));
    EXPECT_NO_THROW(EXPECT_TRUE(store.GetJob(id)));
  }
  // The server restarted while a write waits inside its transaction (another session locks the
  // jobs table): the connection goes mid-statement.
  for (const char* mode : {"fast", "immediate", "immediate"}) {
    SCOPED_TRACE(std::string("a write in flight, restart ") + mode);
    auto locker = std::make_unique<pqxx::connection>(factory.url());
    auto lock = std::make_unique<pqxx::work>(*locker);
    lock->exec("LOCK TABLE jobs IN ACCESS EXCLUSIVE MODE");
    auto write = std::async(std::launch::async, [&] {
      try {
        store.CreateJob(StoreTestJob("in flight"), 10);
        return std::string("succeeded");
      } catch (const StoreUnavailable&) {
        return std::string("unavailable");
      } catch (const std::exception& e) {
        return std::string("internal error: ") + e.what();
      }
    });
    // Until the write waits on the lock, at most 30 s.
    for (int i = 0; i < 3000; ++i) {
      pqxx::connection c(factory.url());
      const pqxx::result r = pqxx::nontransaction(c).exec(
          "SELECT count(*) FROM pg_stat_activity WHERE datname = current_database() AND "
          "wait_event_type = 'Lock'");
      if (r[0][0].as<int>() > 0) break;
      std::this_thread::sleep_for(10ms);
    }
    ASSERT_EQ(RestartServer(mode), 0) << "pg_ctl restart -m " << mode;
    // Cut off ("unavailable"), or committed: a fast stop ends the sessions one by one, and
    // the locker's may end first, freeing the write before its own session ends.
    const std::string outcome = write.get();
    EXPECT_TRUE(outcome == "unavailable" || outcome == "succeeded") << outcome;
    lock.reset();  // (its session is gone with the restart)
    locker.reset();
    EXPECT_NO_THROW(store.CreateJob(StoreTestJob("after"), 10));
  }
}

}  // namespace
}  // namespace springfit::server
