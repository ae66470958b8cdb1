#include "engine/search/worker_pool.h"

#include <exception>
#include <latch>
#include <mutex>
#include <stdexcept>

#include <boost/asio/post.hpp>
#include <boost/asio/thread_pool.hpp>

namespace springfit {

WorkerPool::WorkerPool(int threads) : threads_(threads) {
  if (threads < 1) throw std::invalid_argument("WorkerPool: threads must be >= 1");
  if (threads > 1) pool_ = std::make_unique<boost::asio::thread_pool>(static_cast<std::size_t>(threads - 1));
}

WorkerPool::~WorkerPool() {
  if (pool_) pool_->join();
}

void WorkerPool::Run(int slots, const std::function<void(int slot)>& body) {
  if (slots <= 0) return;
  std::exception_ptr failure;
  std::mutex failure_mutex;
  auto guarded = [&](int slot) {
    try {
      body(slot);
    } catch (...) {
      const std::lock_guard lock(failure_mutex);
      if (!failure) failure = std::current_exception();
    }
  };
  if (!pool_ || slots == 1) {
    for (int slot = 0; slot < slots; ++slot) guarded(slot);
  } else {
    std::latch done(slots - 1);
    for (int slot = 1; slot < slots; ++slot) {
      boost::asio::post(*pool_, [&, slot] {
        guarded(slot);
        done.count_down();
      });
    }
    guarded(0);
    done.wait();
  }
  if (failure) std::rethrow_exception(failure);
}

}  // namespace springfit
