// job.submit (server/rpc/rpc_service.h): a submission validated, prepared once (its Problem kept
// for its run), bounded by the server's limits, and recorded, with job.preparing notices while
// it takes long and an idempotent retry's answer.
#include "server/rpc/rpc_service.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <memory>
#include <thread>

#include <spdlog/spdlog.h>

#include "engine/api/identify.h"
#include "engine/api/input_error.h"
#include "engine/api/problem.h"
#include "engine/api/scene.h"
#include "proto/names.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "server/rpc/params.h"
#include "server/rpc/token.h"
#include "server/store/unix_time.h"

namespace springfit::server {
namespace rpc = proto::rpc;
using proto::Json;

namespace {

// job.preparing notifications to a submitter while its scene is prepared, this often.
constexpr int kPreparingNoticeSeconds = 5;
// How long a retry (the same idempotency key) waits for a first submission being prepared
// before it is answered busy.
constexpr int kRetryWaitSeconds = 60;

// job.preparing to a submitter whose job takes a while: after a second, then about every
// kPreparingNoticeSeconds (its answer timeout can count from the last one, however long the
// preparation). Most scenes are prepared before the first: their submitters see the answer
// alone.
class PreparingNotices {
 public:
  PreparingNotices(const SessionContext& session, std::int64_t id)
      : session_(session),
        id_(id),
        started_(std::chrono::steady_clock::now()),
        next_(started_ + std::chrono::seconds(1)) {}
  void Poll() {
    const auto now = std::chrono::steady_clock::now();
    if (!session_.notify_now || now < next_) return;
    next_ = now + std::chrono::seconds(kPreparingNoticeSeconds);
    Json params;
    params["job_id"] = id_;
    params["seconds"] = std::chrono::duration<double>(now - started_).count();
    session_.notify_now(rpc::Notification("job.preparing", params));
  }

 private:
  const SessionContext& session_;
  std::int64_t id_;
  std::chrono::steady_clock::time_point started_;
  std::chrono::steady_clock::time_point next_;
};

rpc::RpcError InvalidScene(const InputError& e) {
  Json data;
  data["path"] = e.path();
  return rpc::RpcError(rpc::kInvalidScene, std::string("invalid scene: ") + e.what(), data);
}

// A preparing job's lease lapsed (the store did not answer the heartbeats in time) and the
// job was swept: nothing of the submission remains.
rpc::RpcError RecordLost() {
  return rpc::RpcError(rpc::kStoreUnavailable,
                       "store unavailable: the submission's record was lost while its scene was "
                       "prepared (its lease could not be renewed); nothing was queued");
}

// The submission's own fields: label, priority, idempotency key (into the record), and the seed
// when given.
NewJob ReadSubmission(const Json& params, std::optional<std::uint64_t>& seed) {
  NewJob job;
  JobRecord& r = job.record;
  if (const Json* v = OptionalParam(params, "label"))
    r.label = ReadBoundedString(*v, ParamPath("label"));
  if (const Json* v = OptionalParam(params, "priority")) {
    r.priority = proto::ReadInt(*v, ParamPath("priority"));
    if (r.priority < -1000 || r.priority > 1000)
      throw InputError(ParamPath("priority"), "must be in [-1000, 1000]");
  }
  if (const Json* v = OptionalParam(params, "idempotency_key")) {
    r.idempotency_key = ReadBoundedString(*v, ParamPath("idempotency_key"));
    if (r.idempotency_key.empty())
      throw InputError(ParamPath("idempotency_key"), "must not be empty");
  }
  if (const Json* v = OptionalParam(params, "seed"))
    seed = proto::ReadUint64(*v, ParamPath("seed"));
  return job;
}

// The scene at the door, with the submission's seed, in time linear in its size: its structure
// (ValidScene, the one validation of a submission) and every bound known before it is
// prepared. A scene refused here leaves no job.
ValidScene SceneAtTheDoor(const Json& params, std::optional<std::uint64_t> seed,
                          const ServiceLimits& limits) {
  const Json& scene_json = proto::RequiredMember(params, "params", "scene");
  if (!scene_json.is_object())
    throw InputError(ParamPath("scene"), "expected a scene object (proto/SCENE.md)");
  // The name is shown in every listing and log line: bounded before anything is built.
  if (const auto name = scene_json.find("name");
      name != scene_json.end() && name->is_string() &&
      name->get_ref<const std::string&>().size() > kMaxLabelBytes) {
    Json data;
    data["path"] = "scene.name";
    throw rpc::RpcError(
        rpc::kInvalidScene,
        "invalid scene: scene.name: longer than " + std::to_string(kMaxLabelBytes) + " bytes",
        data);
  }
  try {
    Scene scene = proto::SceneFromJson(scene_json);
    if (scene.node_count() > limits.max_nodes)
      LimitExceeded("max_nodes", scene.node_count(), limits.max_nodes);
    if (scene.search.max_generations > limits.max_generations)
      LimitExceeded("max_generations", scene.search.max_generations, limits.max_generations);
    if (scene.search.population && *scene.search.population > limits.max_population)
      LimitExceeded("max_population", *scene.search.population, limits.max_population);
    // Before any candidate is generated: a spec asking for billions of pairs is refused here.
    const std::int64_t candidates = EstimateCandidateCount(scene, limits.max_candidates);
    if (candidates > limits.max_candidates)
      LimitExceeded("max_candidates", candidates, limits.max_candidates);
    if (seed) scene.search.seed = *seed;
    return ValidScene(std::move(scene));
  } catch (const InputError& e) {
    throw InvalidScene(e);
  }
}

// The answer to a submission whose idempotency key names an earlier job. The key names one
// submission: a retry must ask for the same computation (the scene with its search settings,
// and the seed), or a pipeline that changed its scene would silently get the old job's
// result. Label and priority stay the first submission's.
Json AnswerRetry(JobStore& store, const NewJob& job, const JobRecord& old) {
  std::string differs;
  if (old.seed != job.record.seed) differs = "seed";
  const std::optional<std::string> old_scene = store.GetScene(old.id);
  if (old_scene && *old_scene != job.scene_json)
    differs += std::string(differs.empty() ? "" : ", ") + "scene";
  if (!differs.empty()) {
    Json data;
    data["path"] = "params.idempotency_key";
    data["job_id"] = old.id;
    throw rpc::RpcError(rpc::kInvalidParams,
                        "params.idempotency_key: already used by job " + std::to_string(old.id) +
                            " with a different " + differs +
                            " (a key names one submission; use a new key for a new one)",
                        data);
  }
  if (old.state == JobState::kPreparing) {
    Json data;
    data["job_id"] = old.id;
    throw rpc::RpcError(rpc::kBusy,
                        "busy: job " + std::to_string(old.id) +
                            " of this idempotency key is still being prepared (its first "
                            "submission is not answered yet); retry",
                        data);
  }
  Json j;
  j["created"] = false;
  j["job"] = proto::JobToJson(old);
  return j;
}

// The bounds known once a scene is prepared: its genes, what the run asks of its probes
// (CheckRunBounds), and the bytes a genetic search would hold per generation (population x
// genes). Returns the search options resolved.
SearchOptions CheckPreparedBounds(const Problem& problem, const ServiceLimits& limits) {
  if (problem.gene_count() > limits.max_genes)
    LimitExceeded("max_genes", problem.gene_count(), limits.max_genes);
  SearchOptions options = ResolveSearchOptions(problem.scene().search, problem.gene_count());
  try {
    CheckRunBounds(problem, options);  // (probes too few, or more memory than the machine has)
  } catch (const InputError& e) {
    throw InvalidScene(e);
  }
  const std::int64_t population_genes =
      static_cast<std::int64_t>(options.population) * problem.gene_count();
  if (population_genes > limits.max_population_genes)
    LimitExceeded("max_population_genes", population_genes, limits.max_population_genes);
  return options;
}

}  // namespace

Json RpcService::JobSubmit(const Json& params, SessionContext& session) {
  proto::ExpectKeys(params, "params", {"scene", "label", "priority", "seed", "idempotency_key"});
  if (stopping()) throw rpc::RpcError(rpc::kBusy, "busy: the server is shutting down");
  std::optional<std::uint64_t> seed;
  NewJob job = ReadSubmission(params, seed);
  ValidScene valid = SceneAtTheDoor(params, seed, options_.limits);
  const Scene& scene = valid.scene();
  JobRecord& r = job.record;
  r.seed = scene.search.seed;
  r.scene_name = scene.name;
  r.strategy = proto::StrategyName(scene.search.strategy);
  r.max_generations = scene.search.max_generations;
  r.created_at = UnixNow();
  job.scene_json = proto::SceneToJson(scene).dump();
  const JobStore::Created created = CreateJob(job, session);
  if (!created.created) return AnswerRetry(store_, job, created.job);
  std::vector<std::string> notices;
  const JobRecord prepared = Prepare(created, std::move(valid), session, notices);
  Json j;
  j["created"] = true;
  j["job"] = proto::JobToJson(prepared);
  // What `springfit run` says of the scene before it runs (its result says it again).
  j["notices"] = notices;
  return j;
}

JobStore::Created RpcService::CreateJob(NewJob& job, const SessionContext& session) {
  // The job exists from here, `preparing`: listed, and cancellable through any daemon, while
  // its reference is solved (seconds to minutes for a large scene).
  job.preparing_owner = scheduler_.owner();
  job.lease_seconds = scheduler_.lease_seconds();
  JobStore::Created created = store_.CreateJob(job, options_.limits.max_queued);
  // A retry of a submission still being prepared waits for its outcome (the first may yet
  // be refused, and its job then vanishes: the retry then submits anew).
  for (int round = 0; !created.created && !created.queue_full &&
                      created.job.state == JobState::kPreparing && round < 2;
       ++round) {
    std::optional<JobRecord> now = WaitWhilePreparing(created.job.id, session);
    if (now) {
      created.job = *now;
    } else {
      created = store_.CreateJob(job, options_.limits.max_queued);
    }
  }
  if (created.queue_full) {
    throw rpc::RpcError(rpc::kBusy, "busy: " + std::to_string(options_.limits.max_queued) +
                                        " jobs are queued already");
  }
  return created;
}

std::optional<JobRecord> RpcService::WaitWhilePreparing(std::int64_t id,
                                                        const SessionContext& session) {
  PreparingNotices notices(session, id);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(kRetryWaitSeconds);
  while (std::chrono::steady_clock::now() < deadline) {
    if (stopping()) throw rpc::RpcError(rpc::kBusy, "busy: the server is shutting down");
    if (session.peer_gone && session.peer_gone->load())
      throw rpc::RpcError(rpc::kBusy, "busy: the connection closed");
    std::optional<JobRecord> job = store_.GetJob(id);
    if (!job || job->state != JobState::kPreparing) return job;
    notices.Poll();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return store_.GetJob(id);
}

JobRecord RpcService::Prepare(const JobStore::Created& created, ValidScene scene,
                              const SessionContext& session,
                              std::vector<std::string>& scene_notices) {
  const Lease& lease = created.lease;
  const std::int64_t id = lease.job_id;
  JobRecord r = created.job;
  const auto control = scheduler_.PreparationStarted(lease);
  // Whatever ends the preparation, the job leaves it: queued or cancelled, or else dropped
  // (never acknowledged: the submitter gets an error, or has gone).
  std::optional<JobRecord> outcome;
  struct Ending {
    RpcService& service;
    const Lease& lease;
    std::optional<JobRecord>& outcome;
    ~Ending() {
      bool dropped = false;
      if (!outcome) {
        try {
          service.store_.DropPreparing(lease);
          dropped = true;
        } catch (const std::exception& e) {
          // The next claim deletes it once its lease, no longer renewed, expires (and the
          // monitor then tells its watchers).
          spdlog::warn("job {}: cannot drop the refused submission now ({})", lease.job_id,
                       e.what());
        }
      }
      try {
        service.scheduler_.PreparationEnded(lease.job_id, outcome, dropped);
      } catch (const std::exception& e) {  // (out of memory telling the watchers)
        spdlog::error("job {}: {}", lease.job_id, e.what());
      }
    }
  } ending{*this, lease, outcome};

  PreparingNotices notices(session, id);
  const std::shared_ptr<const std::atomic<bool>> peer_gone = session.peer_gone;
  const auto stop_requested = [&] {
    return control->cancel.load() || control->lease_lost.load() || stopping() ||
           (peer_gone && peer_gone->load());
  };
  Interruption interruption(
      [&] {
        notices.Poll();
        return stop_requested();
      },
      0.1);
  std::shared_ptr<const Problem> problem;
  try {
    problem =
        std::make_shared<const Problem>(std::move(scene), EquilibriumOptions{}, &interruption);
  } catch (const InputError& e) {
    throw InvalidScene(e);
  } catch (const Interrupted&) {
    return PreparationStopped(lease, *control, r, outcome);
  }
  if (stop_requested()) return PreparationStopped(lease, *control, r, outcome);
  const SearchOptions options = CheckPreparedBounds(*problem, options_.limits);
  scene_notices = SceneNotices(*problem);
  r.genes = problem->gene_count();
  // The strategy that runs, `default` resolved (the stored scene keeps what was asked), and its
  // generation limit: none (0) where its rows count a fit's steps (a continuous job showed
  // "generation 0/1000" in the Python client's watch).
  r.strategy = proto::StrategyName(ResolvedStrategy(options.strategy, problem->scene()));
  r.max_generations = proto::ProgressCountsSteps(r.strategy) ? 0 : options.max_generations;
  try {
    r.state = store_.FinishPreparing(lease, r);
  } catch (const LeaseLost&) {
    throw RecordLost();
  }
  if (r.state == JobState::kCancelled) r.finished_at = UnixNow();
  outcome = r;
  if (r.state == JobState::kCancelled) {
    // (A cancel reached the store after the last heartbeat: it wins.)
    spdlog::info("job {} cancelled while being prepared ({})", id, r.scene_name);
    return r;
  }
  spdlog::info("job {} queued ({}, label '{}', priority {}, seed {})", id, r.scene_name, r.label,
               r.priority, r.seed);
  scheduler_.JobSubmitted(id, std::move(problem));
  return r;
}

// The preparation stopped, or a stop came after its last check (then too, the job is not
// queued for a submitter that has gone or a server that stops): cancelled, or dropped with the
// error its submitter gets.
JobRecord RpcService::PreparationStopped(const Lease& lease, const Scheduler::Preparation& control,
                                         JobRecord& r, std::optional<JobRecord>& outcome) {
  if (control.cancel.load() && !control.lease_lost.load()) {
    r.state = JobState::kCancelled;
    r.finished_at = UnixNow();
    try {
      store_.MarkFinished(lease, {r.state, "", "", std::nullopt, r.finished_at, ""});
    } catch (const LeaseLost&) {
      throw RecordLost();
    }
    spdlog::info("job {} cancelled while being prepared ({})", lease.job_id, r.scene_name);
    outcome = r;
    return r;
  }
  if (control.lease_lost.load()) throw RecordLost();
  if (stopping()) throw rpc::RpcError(rpc::kBusy, "busy: the server is shutting down");
  spdlog::info("job {}: its submitter went away while it was prepared; dropped", lease.job_id);
  throw rpc::RpcError(rpc::kBusy, "busy: the connection closed");
}

}  // namespace springfit::server
