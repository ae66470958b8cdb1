// A store that times its writes for /metrics (server/web/metrics.h): every call that changes the
// store, by operation, with its failures. Reads are not timed: their cost shows in the
// latency of the RPC answers.
#pragma once
#include <chrono>

#include "server/store/forwarding_store.h"
#include "server/web/metrics.h"

namespace springfit::server {

class MeteredStore final : public ForwardingStore {
 public:
  MeteredStore(JobStore& inner, Metrics& metrics) : ForwardingStore(inner), metrics_(metrics) {}

  Created CreateJob(const NewJob& job, int max_queued) override {
    return Timed("create", [&] { return inner_.CreateJob(job, max_queued); });
  }
  JobState FinishPreparing(const Lease& lease, const JobRecord& prepared) override {
    return Timed("prepared", [&] { return inner_.FinishPreparing(lease, prepared); });
  }
  void DropPreparing(const Lease& lease) override {
    Timed("drop", [&] { inner_.DropPreparing(lease); });
  }
  std::optional<Claim> ClaimNext(const std::string& owner, double lease_seconds) override {
    return Timed("claim", [&] { return inner_.ClaimNext(owner, lease_seconds); });
  }
  LeaseStatus RenewLease(const Lease& lease, double lease_seconds) override {
    return Timed("renew", [&] { return inner_.RenewLease(lease, lease_seconds); });
  }
  void ReleaseLease(const Lease& lease) override {
    Timed("release", [&] { inner_.ReleaseLease(lease); });
  }
  void SaveProgress(const Lease& lease, const ProgressBatch& batch) override {
    Timed("progress", [&] { inner_.SaveProgress(lease, batch); });
  }
  void MarkFinished(const Lease& lease, const JobEnd& end) override {
    Timed("finish", [&] { inner_.MarkFinished(lease, end); });
  }
  void RewindTo(const Lease& lease, int generation) override {
    Timed("rewind", [&] { inner_.RewindTo(lease, generation); });
  }
  CancelOutcome RequestCancel(std::int64_t id) override {
    return Timed("cancel", [&] { return inner_.RequestCancel(id); });
  }
  bool DeleteJob(std::int64_t id) override {
    return Timed("delete", [&] { return inner_.DeleteJob(id); });
  }

 private:
  template <typename F>
  auto Timed(const char* operation, F&& f) -> decltype(f()) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto seconds = [&] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    };
    try {
      if constexpr (std::is_void_v<decltype(f())>) {
        f();
        metrics_.ObserveStoreWrite(operation, seconds(), false);
      } else {
        auto r = f();
        metrics_.ObserveStoreWrite(operation, seconds(), false);
        return r;
      }
    } catch (...) {
      metrics_.ObserveStoreWrite(operation, seconds(), true);
      throw;
    }
  }

  Metrics& metrics_;
};

}  // namespace springfit::server
