// A JobStore that forwards every call to another store: the base of stores that add to some
// calls (MeteredStore's timings; the tests' hooked and failing stores).
#pragma once
#include "server/store/job_store.h"

namespace springfit::server {

class ForwardingStore : public JobStore {
 public:
  explicit ForwardingStore(JobStore& inner) : inner_(inner) {}

  Created CreateJob(const NewJob& job, int max_queued) override {
    return inner_.CreateJob(job, max_queued);
  }
  JobState FinishPreparing(const Lease& lease, const JobRecord& prepared) override {
    return inner_.FinishPreparing(lease, prepared);
  }
  void DropPreparing(const Lease& lease) override { inner_.DropPreparing(lease); }
  std::optional<JobRecord> GetJob(std::int64_t id) override { return inner_.GetJob(id); }
  std::optional<std::string> GetScene(std::int64_t id) override { return inner_.GetScene(id); }
  JobPage ListJobs(const JobFilter& filter) override { return inner_.ListJobs(filter); }
  std::vector<JobRecord> UnfinishedJobs() override { return inner_.UnfinishedJobs(); }
  int CountQueued() override { return inner_.CountQueued(); }
  std::map<JobState, int> CountJobs() override { return inner_.CountJobs(); }
  std::optional<Claim> ClaimNext(const std::string& owner, double lease_seconds) override {
    return inner_.ClaimNext(owner, lease_seconds);
  }
  LeaseStatus RenewLease(const Lease& lease, double lease_seconds) override {
    return inner_.RenewLease(lease, lease_seconds);
  }
  void ReleaseLease(const Lease& lease) override { inner_.ReleaseLease(lease); }
  void SaveProgress(const Lease& lease, const ProgressBatch& batch) override {
    inner_.SaveProgress(lease, batch);
  }
  void MarkFinished(const Lease& lease, const JobEnd& end) override {
    inner_.MarkFinished(lease, end);
  }
  void RewindTo(const Lease& lease, int generation) override { inner_.RewindTo(lease, generation); }
  CancelOutcome RequestCancel(std::int64_t id) override { return inner_.RequestCancel(id); }
  std::optional<std::string> GetResult(std::int64_t id) override { return inner_.GetResult(id); }
  std::vector<TraceRow> GetTrace(std::int64_t id, int after, int limit) override {
    return inner_.GetTrace(id, after, limit);
  }
  using JobStore::GetImprovements;
  std::vector<Improvement> GetImprovements(std::int64_t id, const ImprovementPage& page) override {
    return inner_.GetImprovements(id, page);
  }
  std::optional<std::string> GetCheckpoint(std::int64_t id) override {
    return inner_.GetCheckpoint(id);
  }
  std::vector<LeaseRecord> LeaseHistory(std::int64_t id) override {
    return inner_.LeaseHistory(id);
  }
  bool DeleteJob(std::int64_t id) override { return inner_.DeleteJob(id); }
  void SetChangeListener(std::function<void()> listener) override {
    inner_.SetChangeListener(std::move(listener));
  }
  std::string Describe() const override { return inner_.Describe(); }

 protected:
  JobStore& inner_;
};

}  // namespace springfit::server
