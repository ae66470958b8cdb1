// Stopping a long computation within a bounded time.
//
// An identification runs for minutes; its caller must be able to stop it (job.cancel, SIGTERM,
// Ctrl-C, a time limit) and see progress within a second. The run's thread (the owner) makes
// an Interruption with a poll: a callback that reports progress, reads the caller's stop
// requests and returns true to stop. Long loops call Check() between units of work short
// enough for that second: a Newton iteration, an NNLS pivoting round, a standard error's
// solve, a genome's evaluation. On the owner's thread Check() runs the poll when `period`
// has passed since the last one; on a worker thread (a pool evaluating a batch) it only reads
// the flag the owner sets, so the poll never runs concurrently with itself.
//
// A computation that cannot return a partial result throws Interrupted when Check() says so;
// one that can (a genetic step keeping its best so far) returns early. Once requested, a
// stop stays requested.
#pragma once

#include <atomic>
#include <chrono>
#include <exception>
#include <functional>
#include <thread>
#include <utility>

namespace springfit {

class Interruption {
 public:
  // Never requested but by Request().
  Interruption() : owner_(std::this_thread::get_id()) {}
  // `poll` runs on the constructing thread from Check(), at most every `period_seconds`.
  Interruption(std::function<bool()> poll, double period_seconds)
      : poll_(std::move(poll)),
        period_(std::chrono::duration_cast<Clock::duration>(
            std::chrono::duration<double>(period_seconds))),
        owner_(std::this_thread::get_id()),
        last_poll_(Clock::now()) {}
  Interruption(const Interruption&) = delete;
  Interruption& operator=(const Interruption&) = delete;

  // True when a stop has been requested; on the owner's thread, polls first when due.
  bool Check() {
    if (requested()) return true;
    if (!poll_ || std::this_thread::get_id() != owner_) return false;
    const Clock::time_point now = Clock::now();
    if (now - last_poll_ < period_) return false;
    last_poll_ = now;
    if (poll_()) Request();
    return requested();
  }
  // The owner reported progress by other means: the next poll is due a period from now.
  void Postpone() { last_poll_ = Clock::now(); }
  void Request() { requested_.store(true, std::memory_order_relaxed); }
  bool requested() const { return requested_.load(std::memory_order_relaxed); }

 private:
  using Clock = std::chrono::steady_clock;
  std::function<bool()> poll_;
  Clock::duration period_{};
  std::thread::id owner_;
  Clock::time_point last_poll_{};
  std::atomic<bool> requested_{false};
};

// Thrown out of a computation stopped by its Interruption.
class Interrupted : public std::exception {
 public:
  const char* what() const noexcept override { return "interrupted"; }
};

// For computations that have no partial result to return.
inline void ThrowIfInterrupted(Interruption* interruption) {
  if (interruption && interruption->Check()) throw Interrupted();
}

}  // namespace springfit
