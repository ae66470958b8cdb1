// The daemon's web dashboard, read-only (springfitd --http; README "The dashboard"): pages of
// jobs, progress and figures, the downloads of a job, /healthz and /metrics. Plain requests
// and answers, no sockets: http_server.h carries them, and tests call Handle directly.
//
// Pages are server-rendered HTML with springfit's own SVG figures; nothing is fetched from
// elsewhere, and they work without JavaScript but for the live update of a running job's
// progress (a request a second). Every piece of user text is escaped.
//
// With a token (--token-file) every route but /healthz and /login asks for it: an
// `Authorization: Bearer TOKEN` header, or the HttpOnly cookie the login form sets.
#pragma once
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "engine/api/problem.h"
#include "server/jobs/scheduler.h"
#include "server/mutex.h"
#include "server/store/job_store.h"
#include "server/web/metrics.h"

namespace springfit::server {

struct HttpRequest {
  std::string method;                          // GET, POST, ...
  std::string target;                          // path and query, as sent
  std::map<std::string, std::string> headers;  // names in lower case
  std::string body;
};

struct HttpResponse {
  int status = 200;
  std::string content_type = "text/plain; charset=utf-8";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers;  // extra ones
};

struct DashboardOptions {
  std::string token;   // empty: no authentication
  int page_size = 50;  // jobs per page of /
  // Scenes kept prepared for the topology figures (preparing a large one takes a while).
  int cached_problems = 4;
  // A topology figure larger than this is linked from the job's page (an <img> the browser
  // fetches), not inlined: a 3D mesh's springs make megabytes of SVG.
  std::size_t max_inline_figure_bytes = 256 * 1024;
};

class Dashboard {
 public:
  Dashboard(JobStore& store, Scheduler& scheduler, Metrics& metrics, DashboardOptions options);

  // Never throws: errors are answers (404, 400, 503 when the store does not answer, 500).
  HttpResponse Handle(const HttpRequest& request);
  void Count(int status) { metrics_.CountHttpRequest(status); }

 private:
  HttpResponse Route(const HttpRequest& request, const std::string& path,
                     const std::map<std::string, std::string>& query);
  bool Authorized(const HttpRequest& request) const;
  HttpResponse Login(const HttpRequest& request);
  HttpResponse Health();
  HttpResponse MetricsText();
  HttpResponse ListView(const std::map<std::string, std::string>& query);
  HttpResponse JobView(const JobRecord& job);
  // The model's figure (the result's, or the best so far), inline or linked when large.
  std::string ModelSection(const JobRecord& job, bool result);
  HttpResponse Progress(const JobRecord& job);
  HttpResponse ErrorPlot(const JobRecord& job);
  HttpResponse Topology(const JobRecord& job, const std::string& which);
  HttpResponse ResultJson(const JobRecord& job);
  HttpResponse TraceCsv(const JobRecord& job);
  HttpResponse Model(const JobRecord& job, const std::string& extension);

  // The job's record with its live progress when it runs here.
  JobRecord Live(JobRecord job) const;
  std::string PhaseText(std::int64_t id) const;
  std::shared_ptr<const Problem> ProblemOf(const JobRecord& job);
  std::string ErrorPlotSvg(const JobRecord& job);
  // The topology figure of the result (finished jobs) or of the best so far; empty when
  // there is none yet.
  std::string TopologySvg(const JobRecord& job, bool result);

  JobStore& store_;
  Scheduler& scheduler_;
  Metrics& metrics_;
  DashboardOptions options_;
  Mutex problems_mutex_;
  // Newest last.
  std::vector<std::pair<std::int64_t, std::shared_ptr<const Problem>>> problems_
      SF_GUARDED_BY(problems_mutex_);
};

}  // namespace springfit::server
