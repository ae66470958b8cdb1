// Threads that run a batch of independent work: a generation's fitness evaluations, the
// stiffness fit's solves (below every part of the engine that runs in parallel).
//
// A thin layer over boost::asio::thread_pool. Run(slots, body) calls body(slot) once for
// every slot in [0, slots) and returns when all have returned. The calling thread claims
// slots too, and waits only for slots a pool thread has actually started: a batch finishes
// even when every pool thread is busy with other work (a daemon shares one pool between
// jobs). Which thread runs a slot is arbitrary: callers give each slot its own state and
// make results independent of the thread that computed them.
#pragma once

#include <chrono>
#include <functional>
#include <memory>

namespace boost::asio {
class thread_pool;
}

namespace springfit {

class WorkerPool {
 public:
  // `threads` >= 1 threads in total, the calling thread included (threads - 1 are started).
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return threads_; }
  // Calls body(slot) for slot in [0, slots) in parallel; rethrows the first exception. While
  // the calling thread waits for slots running on pool threads it calls `while_waiting`
  // every kWaitingPeriod (a run's progress and stop checks go on during a long evaluation).
  void Run(int slots, const std::function<void(int slot)>& body,
           const std::function<void()>& while_waiting = {});
  static constexpr std::chrono::milliseconds kWaitingPeriod{50};

 private:
  int threads_;

  std::unique_ptr<boost::asio::thread_pool> pool_;
};

// pool->Run(slots, body, while_waiting), or body(0), body(1), ... on the calling thread when
// there is no pool: for callers whose pool is optional. Each slot must have its own state.
void RunSlots(WorkerPool* pool, int slots, const std::function<void(int slot)>& body,
              const std::function<void()>& while_waiting = {});

}  // namespace springfit
