// The daemon's counters for /metrics (Prometheus text format, version 0.0.4): RPC requests and
// errors by method, store write latency by operation, fitness evaluations. Gauges read at
// scrape time (jobs by state, running, queued) are passed to Render by the caller, who reads
// them from the store and the scheduler.
#pragma once
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "proto/job.h"
#include "server/mutex.h"

namespace springfit::server {

class Metrics {
 public:
  // Upper bounds of the store-latency histogram's buckets, in seconds (+Inf implied).
  static constexpr std::array<double, 10> kLatencyBuckets = {0.0001, 0.00025, 0.0005, 0.001, 0.0025,
                                                             0.005,  0.01,    0.025,  0.1,   1.0};

  // `method` is bounded by the caller's table of methods (unknown ones count as "unknown").
  void CountRequest(std::string_view method, bool error);
  void ObserveStoreWrite(std::string_view operation, double seconds, bool failed);
  // Evaluations done since the last call, by any job running here.
  void AddEvaluations(std::int64_t evaluations);
  void CountHttpRequest(int status);
  // A job run here ended: counted by its state and, with a result, its verdict (verdict.h).
  void CountFinished(proto::JobState state, const std::optional<Outcome>& outcome);

  struct Gauges {
    std::optional<std::map<proto::JobState, int>> jobs;  // null: the store did not answer
    int running_here = 0;
    std::optional<int> queued;
    bool store_up = true;
  };
  std::string Render(const Gauges& gauges);

 private:
  struct Requests {
    std::uint64_t total = 0;
    std::uint64_t errors = 0;
  };
  struct Latency {
    std::array<std::uint64_t, kLatencyBuckets.size()> buckets{};
    std::uint64_t count = 0;
    std::uint64_t failures = 0;
    double sum = 0.0;
  };
  double EvaluationsPerSecondLocked() SF_REQUIRES(mutex_);

  Mutex mutex_;
  std::map<std::string, Requests, std::less<>> requests_ SF_GUARDED_BY(mutex_);
  std::map<std::string, Latency, std::less<>> store_writes_ SF_GUARDED_BY(mutex_);
  std::map<int, std::uint64_t> http_ SF_GUARDED_BY(mutex_);
  // (state, verdict or "none"): jobs finished here.
  std::map<std::pair<std::string, std::string>, std::uint64_t> finished_ SF_GUARDED_BY(mutex_);
  std::uint64_t evaluations_ SF_GUARDED_BY(mutex_) = 0;
  // (time, evaluations so far): the last ten seconds, for a rate that needs no PromQL.
  std::deque<std::pair<std::chrono::steady_clock::time_point, std::uint64_t>> recent_
      SF_GUARDED_BY(mutex_);
};

}  // namespace springfit::server
