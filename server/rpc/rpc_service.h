// The daemon's JSON-RPC methods (proto/RPC.md): request validation, authentication, the
// method table and every handler. No sockets: a network session hands it whole messages
// and sends back what it returns, and the tests call it directly.
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "proto/json_reader.h"
#include "proto/rpc.h"
#include "server/jobs/scheduler.h"
#include "server/store/job_store.h"
#include "server/web/metrics.h"

namespace springfit::server {

struct ServiceLimits {
  int max_nodes = 100000;   // nodes per scene
  int max_genes = 2000000;  // candidate springs per scene
  // Candidate springs a scene's spec may ask for, estimated before they are generated
  // (engine/model/candidates.h EstimateCandidateCount: k n for k nearest, counted for a radius).
  std::int64_t max_candidates = 4000000;
  int max_population = 10000;  // a genetic search's population
  // Population times genes: the bytes of one generation's genomes (100 MB by default).
  std::int64_t max_population_genes = 100000000;
  int max_generations = 100000000;  // a job's generation limit
  int max_queued = 10000;           // queued jobs, all clients together
  int max_batch = 100;              // requests in one JSON-RPC batch
  int max_page = 10000;             // rows or jobs in one job.trace / job.list answer
  int max_watches = 100;            // job.watch subscriptions open on one connection
  // Bytes of jobs in one job.list answer: a page ends early (with its cursor) beyond it, so
  // that a listing always fits a client's message limit.
  std::size_t max_list_bytes = std::size_t{4} << 20;
};

struct ServiceOptions {
  std::string token;  // empty: no authentication
  ServiceLimits limits;
  int workers = 1;             // for server.info
  int max_running = 1;         // for server.info
  Metrics* metrics = nullptr;  // requests and errors by method, when set
};

// What the service knows of one connection.
struct SessionContext {
  bool authenticated = false;
  // Sends a notification on this connection after any response being written (posts; must
  // not block). Unset: notifications are dropped.
  std::function<void(const proto::Json&)> notify;
  // The same, sent at once, before the answer being prepared (a request's own progress:
  // job.preparing). Unset: dropped.
  std::function<void(const proto::Json&)> notify_now;
  std::vector<std::uint64_t> watches;
  // Per watch (same order): set once its job.finished was sent. Finished watches are dropped
  // at the next job.watch, so max_watches bounds the open ones only.
  std::vector<std::shared_ptr<std::atomic<bool>>> watch_finished;
  // Watches whose job has not finished yet (read by the connection's idle timer).
  std::size_t OpenWatches() const {
    std::size_t open = 0;
    for (const auto& finished : watch_finished) open += finished->load() ? 0 : 1;
    return open;
  }
  // Wrong tokens presented on this connection: the first is logged, the kMaxWrongTokens-th
  // closes it (a guesser must reconnect, within --max-connections).
  int wrong_tokens = 0;
  // Set by the connection when it closes: a submission still being prepared for it stops,
  // and its job is dropped (it was never acknowledged).
  std::shared_ptr<std::atomic<bool>> peer_gone = std::make_shared<std::atomic<bool>>(false);
  bool close = false;  // set by the service: close after this answer
};

inline constexpr int kMaxWrongTokens = 5;

class RpcService {
 public:
  RpcService(JobStore& store, Scheduler& scheduler, ServiceOptions options);
  // A token is set: a connection must present it (session.auth) before any job method.
  bool requires_token() const { return !options_.token.empty(); }

  // A framed message parsed, not yet handled. The daemon parses on its request threads and
  // hands what prepares a scene to its preparation threads (tcp_server.cpp), by the method
  // the message names, not by how its text spells it.
  struct ParsedMessage {
    proto::Json message;
    proto::rpc::IdLiterals ids;
    std::string parse_error;      // the answer to a text that is not JSON (message unset)
    bool prepares_scene = false;  // a job.submit request, alone or in a batch
  };
  static ParsedMessage Parse(std::string_view text);
  // The response text of a parsed message ("" when there is none: notifications only).
  // Never throws.
  std::string Handle(const ParsedMessage& parsed, SessionContext& session);
  // Parse() then Handle().
  std::string HandleMessage(std::string_view text, SessionContext& session);
  // The same for a parsed message; null when there is no response.
  proto::Json HandleJson(const proto::Json& message, SessionContext& session);
  // The connection closed: its watches end.
  void EndSession(SessionContext& session);

  bool stopping() const { return stopping_.load(); }
  void set_stopping() { stopping_.store(true); }

 private:
  proto::Json HandleRequest(const proto::Json& request, SessionContext& session);
  // The error response for the exception being handled (call inside a catch block): the
  // client's errors named, the store's and the server's with an incident number in the log.
  proto::Json ErrorOfCurrentException(const proto::Json& id, const std::string& method);
  proto::Json Dispatch(const std::string& method, const proto::Json& params,
                       SessionContext& session);

  proto::Json ServerInfo();
  proto::Json SessionAuth(const proto::Json& params, SessionContext& session);
  proto::Json JobSubmit(const proto::Json& params, SessionContext& session);
  // Records the submission as a job being prepared, under the server's queue bound; a retry
  // (an idempotency key already used) finds the earlier job, after waiting for its preparation
  // to end.
  JobStore::Created CreateJob(NewJob& job, const SessionContext& session);
  // Prepares a job just created `preparing` (its reference solved, its candidates laid out):
  // queues it, or returns it cancelled (a cancel came meanwhile), or drops it and throws the
  // error its submitter gets (an invalid scene, a bound, a shutdown, a lost connection).
  // `scene_notices`: the prepared scene's (SceneNotices), for the submitter.
  JobRecord Prepare(const JobStore::Created& created, ValidScene scene,
                    const SessionContext& session, std::vector<std::string>& scene_notices);
  // A retry of a submission being prepared (its idempotency key) waits, bounded, for that
  // preparation's end: the job as it then is, or nothing when it was dropped.
  std::optional<JobRecord> WaitWhilePreparing(std::int64_t id, const SessionContext& session);
  // A preparation stopped (cancelled, the lease lost, a shutdown, the submitter gone): the job
  // cancelled, or an error thrown for its submitter. Sets `outcome` when the job stays.
  JobRecord PreparationStopped(const Lease& lease, const Scheduler::Preparation& control,
                               JobRecord& r, std::optional<JobRecord>& outcome);
  proto::Json JobGet(const proto::Json& params);
  proto::Json JobResult(const proto::Json& params);
  proto::Json JobTrace(const proto::Json& params);
  proto::Json JobScene(const proto::Json& params);
  proto::Json JobImprovements(const proto::Json& params);
  proto::Json JobList(const proto::Json& params);
  proto::Json JobCancel(const proto::Json& params);
  proto::Json JobDelete(const proto::Json& params);
  proto::Json JobWatch(const proto::Json& params, SessionContext& session);

  // The job of params.job_id with its live progress, or kNoSuchJob.
  JobRecord RequireJob(const proto::Json& params);

  JobStore& store_;
  Scheduler& scheduler_;
  ServiceOptions options_;
  std::atomic<bool> stopping_{false};
  std::atomic<std::uint64_t> incidents_{0};  // internal errors so far, numbered in the log
};

}  // namespace springfit::server
