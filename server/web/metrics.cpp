#include "server/web/metrics.h"

#include <fmt/format.h>

namespace springfit::server {
namespace {

constexpr std::chrono::seconds kRateWindow{10};

std::string Number(double v) {
  return fmt::format("{}", v);
}

}  // namespace

void Metrics::CountRequest(std::string_view method, bool error) {
  MutexLock lock(mutex_);
  auto it = requests_.find(method);
  if (it == requests_.end()) it = requests_.emplace(std::string(method), Requests{}).first;
  ++it->second.total;
  if (error) ++it->second.errors;
}

void Metrics::ObserveStoreWrite(std::string_view operation, double seconds, bool failed) {
  MutexLock lock(mutex_);
  auto it = store_writes_.find(operation);
  if (it == store_writes_.end())
    it = store_writes_.emplace(std::string(operation), Latency{}).first;
  Latency& l = it->second;
  for (std::size_t b = 0; b < kLatencyBuckets.size(); ++b) {
    if (seconds <= kLatencyBuckets[b]) ++l.buckets[b];
  }
  ++l.count;
  l.sum += seconds;
  if (failed) ++l.failures;
}

void Metrics::AddEvaluations(std::int64_t evaluations) {
  if (evaluations <= 0) return;
  MutexLock lock(mutex_);
  evaluations_ += static_cast<std::uint64_t>(evaluations);
  const auto now = std::chrono::steady_clock::now();
  recent_.emplace_back(now, evaluations_);
  while (recent_.size() > 2 && now - recent_.front().first > kRateWindow) recent_.pop_front();
}

void Metrics::CountHttpRequest(int status) {
  MutexLock lock(mutex_);
  ++http_[status];
}

void Metrics::CountFinished(proto::JobState state, const std::optional<Outcome>& outcome) {
  MutexLock lock(mutex_);
  ++finished_[{std::string(proto::JobStateName(state)),
               outcome ? std::string(VerdictName(outcome->verdict)) : std::string("none")}];
}

double Metrics::EvaluationsPerSecondLocked() {
  const auto now = std::chrono::steady_clock::now();
  while (recent_.size() > 1 && now - recent_.front().first > kRateWindow) recent_.pop_front();
  if (recent_.empty() || now - recent_.back().first > kRateWindow) return 0.0;
  const double seconds =
      std::max(1.0, std::chrono::duration<double>(now - recent_.front().first).count());
  return static_cast<double>(recent_.back().second - recent_.front().second) / seconds;
}

std::string Metrics::Render(const Gauges& g) {
  std::string out;
  auto header = [&](const char* name, const char* type, const char* help) {
    out += fmt::format("# HELP {} {}\n# TYPE {} {}\n", name, help, name, type);
  };
  header("springfit_up", "gauge", "1 when the daemon's store answers, 0 when it does not.");
  out += fmt::format("springfit_up {}\n", g.store_up ? 1 : 0);
  if (g.jobs) {
    header("springfit_jobs", "gauge",
           "Jobs in the store by state (all daemons of a shared store).");
    for (const proto::JobState s : proto::AllJobStates()) {
      const auto it = g.jobs->find(s);
      out += fmt::format("springfit_jobs{{state=\"{}\"}} {}\n", proto::JobStateName(s),
                         it == g.jobs->end() ? 0 : it->second);
    }
  }
  {
    MutexLock lock(mutex_);
    header("springfit_jobs_finished_total", "counter",
           "Jobs run on this daemon that ended, by state and by their result's verdict (usable, "
           "unmet_request, unusable, doubtful; none without a result).");
    for (const auto& [key, count] : finished_)
      out += fmt::format("springfit_jobs_finished_total{{state=\"{}\",verdict=\"{}\"}} {}\n",
                         key.first, key.second, count);
  }
  header("springfit_running_jobs", "gauge", "Jobs running on this daemon.");
  out += fmt::format("springfit_running_jobs {}\n", g.running_here);
  if (g.queued) {
    header("springfit_queue_length", "gauge", "Jobs waiting in the store's queue.");
    out += fmt::format("springfit_queue_length {}\n", *g.queued);
  }
  MutexLock lock(mutex_);
  header("springfit_evaluations_total", "counter",
         "Fitness evaluations of the jobs run on this daemon.");
  out += fmt::format("springfit_evaluations_total {}\n", evaluations_);
  header("springfit_evaluations_per_second", "gauge",
         "Fitness evaluations per second on this daemon over the last 10 s.");
  out += fmt::format("springfit_evaluations_per_second {}\n", Number(EvaluationsPerSecondLocked()));
  header("springfit_rpc_requests_total", "counter", "JSON-RPC requests by method.");
  for (const auto& [method, r] : requests_)
    out += fmt::format("springfit_rpc_requests_total{{method=\"{}\"}} {}\n", method, r.total);
  header("springfit_rpc_errors_total", "counter", "JSON-RPC requests answered with an error.");
  for (const auto& [method, r] : requests_)
    out += fmt::format("springfit_rpc_errors_total{{method=\"{}\"}} {}\n", method, r.errors);
  header("springfit_store_write_seconds", "histogram", "Latency of the store's writes.");
  for (const auto& [op, l] : store_writes_) {
    for (std::size_t b = 0; b < kLatencyBuckets.size(); ++b) {
      out += fmt::format("springfit_store_write_seconds_bucket{{operation=\"{}\",le=\"{}\"}} {}\n",
                         op, Number(kLatencyBuckets[b]), l.buckets[b]);
    }
    out += fmt::format("springfit_store_write_seconds_bucket{{operation=\"{}\",le=\"+Inf\"}} {}\n",
                       op, l.count);
    out += fmt::format("springfit_store_write_seconds_sum{{operation=\"{}\"}} {}\n", op,
                       Number(l.sum));
    out += fmt::format("springfit_store_write_seconds_count{{operation=\"{}\"}} {}\n", op, l.count);
  }
  header("springfit_store_write_failures_total", "counter", "Store writes that failed.");
  for (const auto& [op, l] : store_writes_)
    out += fmt::format("springfit_store_write_failures_total{{operation=\"{}\"}} {}\n", op,
                       l.failures);
  header("springfit_http_requests_total", "counter", "Dashboard HTTP requests by status.");
  for (const auto& [status, n] : http_)
    out += fmt::format("springfit_http_requests_total{{status=\"{}\"}} {}\n", status, n);
  return out;
}

}  // namespace springfit::server
