// The evaluation threads (engine/runtime/worker_pool.h): every slot exactly once, exceptions
// rethrown, and a batch that finishes while every pool thread is busy with another one. Every
// wait is bounded: a hang fails the test instead of blocking it forever.
#include "engine/runtime/worker_pool.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <future>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace springfit {
namespace {

constexpr std::chrono::seconds kBound{30};

// Runs `f` on a thread of its own and waits at most kBound for it; rethrows what it threw. A
// thread still running then cannot be joined, so a hang aborts the test program (a failure)
// rather than leaving it blocked.
void Bounded(const std::string& what, std::function<void()> f) {
  std::packaged_task<void()> task(std::move(f));
  std::future<void> done = task.get_future();
  std::thread thread(std::move(task));
  if (done.wait_for(kBound) != std::future_status::ready) {
    std::fprintf(stderr, "%s: still running after %lld s: aborting\n", what.c_str(),
                 static_cast<long long>(kBound.count()));
    std::abort();
  }
  thread.join();
  done.get();
}

struct Calls {
  std::vector<int> per_slot;  // calls of each slot in [0, slots)
  int outside = 0;            // calls with a slot outside [0, slots)
};

// One Run(slots) with a counting body, from a thread of its own.
Calls CountCalls(WorkerPool& pool, int slots) {
  std::vector<std::atomic<int>> counts(static_cast<std::size_t>(std::max(slots, 0)));
  std::atomic<int> outside{0};
  Bounded("Run(" + std::to_string(slots) + ")", [&] {
    pool.Run(slots, [&](int slot) {
      if (slot < 0 || slot >= slots) {
        outside.fetch_add(1);
        return;
      }
      counts[static_cast<std::size_t>(slot)].fetch_add(1);
    });
  });
  Calls calls;
  for (const std::atomic<int>& n : counts) calls.per_slot.push_back(n.load());
  calls.outside = outside.load();
  return calls;
}

struct SlotError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

TEST(WorkerPool, CallsEverySlotExactlyOnceForAnyThreadAndSlotCount) {
  for (const int threads : {1, 2, 3, 4, 8}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    // No slots; fewer slots than threads; as many; more; many more. One pool for all: it is
    // reused batch after batch.
    for (const int slots :
         {-3, 0, 1, 2, threads - 1, threads, threads + 1, 5 * threads + 3, 1000}) {
      SCOPED_TRACE("threads " + std::to_string(threads) + ", slots " + std::to_string(slots));
      const Calls calls = CountCalls(pool, slots);
      EXPECT_EQ(calls.outside, 0);
      ASSERT_EQ(calls.per_slot.size(), static_cast<std::size_t>(std::max(slots, 0)));
      int wrong = 0;
      for (std::size_t s = 0; s < calls.per_slot.size(); ++s) {
        if (calls.per_slot[s] != 1) {
          ADD_FAILURE() << "slot " << s << " called " << calls.per_slot[s] << " times";
          if (++wrong == 5) break;
        }
      }
    }
  }
}

TEST(WorkerPool, NeedsAtLeastOneThread) {
  EXPECT_THROW({ WorkerPool pool(0); }, std::invalid_argument);
  EXPECT_THROW({ WorkerPool pool(-2); }, std::invalid_argument);
}

TEST(WorkerPool, RunRethrowsABodysExceptionAfterEveryStartedSlotEndedAndStaysUsable) {
  for (const int threads : {1, 2, 4}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    std::atomic<int> in_flight{0};
    std::atomic<int> calls{0};
    bool caught = false;
    int in_flight_at_throw = -1;
    std::string message;
    WorkerPool pool(threads);  // joined before the state its bodies use goes
    Bounded("a batch with a failing slot", [&] {
      try {
        pool.Run(64, [&](int slot) {
          in_flight.fetch_add(1);
          calls.fetch_add(1);
          struct Leave {
            std::atomic<int>& count;
            ~Leave() { count.fetch_sub(1); }
          } leave{in_flight};
          if (slot == 5) throw SlotError("slot 5 failed");
          std::this_thread::sleep_for(std::chrono::microseconds(200));  // overlap the others
        });
      } catch (const SlotError& e) {  // the body's own exception type, not a wrapper
        caught = true;
        message = e.what();
        in_flight_at_throw = in_flight.load();
      }
    });
    EXPECT_TRUE(caught) << "Run swallowed the exception of slot 5";
    EXPECT_EQ(message, "slot 5 failed");
    // Run returns only when no body runs any more: bodies use the caller's state.
    EXPECT_EQ(in_flight_at_throw, 0);
    // The header's contract: body(slot) for every slot, a failure notwithstanding.
    EXPECT_EQ(calls.load(), 64);

    // Every slot failing: one of their exceptions comes back.
    caught = false;
    message.clear();
    Bounded("a batch where every slot fails", [&] {
      try {
        pool.Run(16, [&](int slot) { throw SlotError("slot " + std::to_string(slot)); });
      } catch (const SlotError& e) {
        caught = true;
        message = e.what();
      }
    });
    EXPECT_TRUE(caught);
    EXPECT_EQ(message.rfind("slot ", 0), 0u) << message;

    // The pool works on as before.
    const Calls after = CountCalls(pool, 50);
    EXPECT_EQ(after.per_slot, std::vector<int>(50, 1));
  }
}

// The daemon's case: one pool shared by jobs. A batch whose pool threads are all held by
// another batch is run by its calling thread alone, instead of waiting for them.
TEST(WorkerPool, ABatchFinishesWhileEveryPoolThreadIsBusyWithAnother) {
  for (const int threads : {2, 4}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    std::mutex mutex;
    std::condition_variable changed;
    int blocked = 0;   // slots of the occupying batch that have started
    int returned = 0;  // ... and returned
    bool release = false;
    // After the state its slots use, so that it is joined before that state goes.
    WorkerPool pool(threads);

    struct Ran {
      std::thread::id caller;
      std::vector<std::thread::id> slots;
    };
    std::future<void> occupier;
    std::future<Ran> other;
    // Declared after the futures, so destroyed before them: on every way out of this scope the
    // blocked slots are released before the futures' destructors wait for their threads.
    struct Release {
      std::mutex& m;
      std::condition_variable& cv;
      bool& flag;
      ~Release() {
        {
          std::lock_guard lock(m);
          flag = true;
        }
        cv.notify_all();
      }
    } guard{mutex, changed, release};

    // `threads` slots that each hold their thread until released: all of them run at once
    // only when the calling thread and every pool thread are inside one.
    occupier = std::async(std::launch::async, [&] {
      pool.Run(threads, [&](int) {
        std::unique_lock lock(mutex);
        ++blocked;
        changed.notify_all();
        changed.wait_for(lock, kBound, [&] { return release; });
        ++returned;
      });
    });
    {
      std::unique_lock lock(mutex);
      ASSERT_TRUE(changed.wait_for(lock, kBound, [&] { return blocked == threads; }))
          << "the occupying batch never held every thread (" << blocked << " of " << threads << ")";
    }

    // Another caller's batch, while every pool thread is blocked.
    other = std::async(std::launch::async, [&] {
      Ran ran;
      ran.caller = std::this_thread::get_id();
      ran.slots.resize(8);
      pool.Run(8, [&](int slot) {
        ran.slots[static_cast<std::size_t>(slot)] = std::this_thread::get_id();
      });
      return ran;
    });
    const bool finished = other.wait_for(kBound) == std::future_status::ready;
    EXPECT_TRUE(finished) << "Run waited for pool threads that were busy with another batch";
    {
      std::lock_guard lock(mutex);
      EXPECT_EQ(returned, 0) << "the occupying batch let a thread go before the other finished";
      release = true;
    }
    changed.notify_all();
    ASSERT_EQ(occupier.wait_for(kBound), std::future_status::ready);
    occupier.get();
    {
      std::lock_guard lock(mutex);
      EXPECT_EQ(returned, threads);
    }
    if (finished) {
      const Ran ran = other.get();
      // Every slot ran, each on the calling thread: no pool thread was free to take one.
      for (std::size_t s = 0; s < ran.slots.size(); ++s)
        EXPECT_EQ(ran.slots[s], ran.caller) << "slot " << s;
    }
  }
}

TEST(WorkerPool, ConcurrentCallersShareOnePool) {
  WorkerPool pool(3);
  Bounded("four callers, 20 batches each", [&] {
    std::vector<std::future<int>> callers;
    for (int c = 0; c < 4; ++c) {
      callers.push_back(std::async(std::launch::async, [&pool] {
        int wrong = 0;
        for (int round = 0; round < 20; ++round) {
          std::vector<std::atomic<int>> counts(50);
          pool.Run(50, [&](int slot) { counts[static_cast<std::size_t>(slot)].fetch_add(1); });
          for (const std::atomic<int>& n : counts) {
            if (n.load() != 1) ++wrong;
          }
        }
        return wrong;
      }));
    }
    for (std::future<int>& f : callers) EXPECT_EQ(f.get(), 0) << "slots not called exactly once";
  });
}

}  // namespace
}  // namespace springfit
