#include "engine/runtime/worker_pool.h"

#include <condition_variable>
#include <exception>
#include <mutex>
#include <stdexcept>

#include <boost/asio/post.hpp>
#include <boost/asio/thread_pool.hpp>

namespace springfit {
namespace {

// One Run(): the slots not yet claimed and the claimed ones still running. Shared with the
// posted closures, so a closure that starts after Run() returned finds nothing left to claim
// and touches nothing of Run()'s stack.
struct Batch {
  std::mutex mutex;
  std::condition_variable finished;
  int slots = 0;
  int next = 0;
  int running = 0;
  std::exception_ptr failure;
  const std::function<void(int)>* body = nullptr;

  // Claims and runs slots until none is left.
  void Work() {
    for (;;) {
      int slot = 0;
      {
        const std::lock_guard lock(mutex);
        if (next >= slots) return;
        slot = next++;
        ++running;
      }
      std::exception_ptr error;
      try {
        (*body)(slot);
      } catch (...) {
        error = std::current_exception();
      }
      const std::lock_guard lock(mutex);
      if (error && !failure) failure = error;
      if (--running == 0 && next >= slots) finished.notify_all();
    }
  }
};

}  // namespace

WorkerPool::WorkerPool(int threads) : threads_(threads) {
  if (threads < 1) throw std::invalid_argument("WorkerPool: threads must be >= 1");
  if (threads > 1)
    pool_ = std::make_unique<boost::asio::thread_pool>(static_cast<std::size_t>(threads - 1));
}

WorkerPool::~WorkerPool() {
  if (pool_) pool_->join();
}

void WorkerPool::Run(int slots, const std::function<void(int slot)>& body,
                     const std::function<void()>& while_waiting) {
  if (slots <= 0) return;
  auto batch = std::make_shared<Batch>();
  batch->slots = slots;
  batch->body = &body;
  if (pool_) {
    for (int helper = 1; helper < slots; ++helper) {
      boost::asio::post(*pool_, [batch] { batch->Work(); });
    }
  }
  // The caller works too: when every pool thread is busy elsewhere it runs all the slots.
  batch->Work();
  std::unique_lock lock(batch->mutex);
  const auto done = [&] { return batch->running == 0; };
  if (!while_waiting) {
    batch->finished.wait(lock, done);
  } else {
    // The slots still running use the caller's body and its captures: wait for them even
    // when the callback throws, then rethrow.
    std::exception_ptr waiting_failure;
    while (!batch->finished.wait_for(lock, kWaitingPeriod, done)) {
      if (waiting_failure) continue;
      lock.unlock();
      try {
        while_waiting();
      } catch (...) {
        waiting_failure = std::current_exception();
      }
      lock.lock();
    }
    if (waiting_failure && !batch->failure) batch->failure = waiting_failure;
  }
  if (batch->failure) std::rethrow_exception(batch->failure);
}

void RunSlots(WorkerPool* pool, int slots, const std::function<void(int slot)>& body,
              const std::function<void()>& while_waiting) {
  if (pool) {
    pool->Run(slots, body, while_waiting);
    return;
  }
  for (int slot = 0; slot < slots; ++slot) body(slot);
}

}  // namespace springfit
