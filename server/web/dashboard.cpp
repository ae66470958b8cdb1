#include "server/web/dashboard.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <initializer_list>
#include <limits>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "engine/api/analysis.h"
#include "engine/api/input_error.h"
#include "figures/error_plot.h"
#include "figures/topology_figure.h"
#include "io/model_writers.h"
#include "io/spring_model.h"
#include "io/xml_text.h"
#include "proto/job.h"
#include "proto/outcome_codec.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "server/rpc/token.h"
#include "server/store/unix_time.h"

namespace springfit::server {
namespace {

using io::XmlEscape;
using proto::Json;

constexpr const char* kCookie = "springfit_token";
constexpr int kMaxTraceRows = 100000;  // the error plot's rows at most

HttpResponse Text(int status, std::string body) {
  HttpResponse r;
  r.status = status;
  r.body = std::move(body);
  return r;
}

HttpResponse Content(std::string type, std::string body) {
  HttpResponse r;
  r.content_type = std::move(type);
  r.body = std::move(body);
  return r;
}

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// application/x-www-form-urlencoded and query strings: '+' is a space, %XX a byte.
std::string PercentDecode(std::string_view s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '+') {
      out += ' ';
    } else if (s[i] == '%' && i + 2 < s.size() && HexValue(s[i + 1]) >= 0 &&
               HexValue(s[i + 2]) >= 0) {
      out += static_cast<char>(HexValue(s[i + 1]) * 16 + HexValue(s[i + 2]));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

std::string PercentEncode(std::string_view s) {
  std::string out;
  for (const unsigned char c : s) {
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~') {
      out += static_cast<char>(c);
    } else {
      out += fmt::format("%{:02X}", c);
    }
  }
  return out;
}

std::map<std::string, std::string> ParseForm(std::string_view text) {
  std::map<std::string, std::string> fields;
  while (!text.empty()) {
    const std::size_t amp = text.find('&');
    const std::string_view pair = text.substr(0, amp);
    const std::size_t eq = pair.find('=');
    if (!pair.empty()) {
      fields[PercentDecode(pair.substr(0, eq))] =
          eq == std::string_view::npos ? "" : PercentDecode(pair.substr(eq + 1));
    }
    if (amp == std::string_view::npos) break;
    text.remove_prefix(amp + 1);
  }
  return fields;
}

std::string CookieValue(const std::string& header, std::string_view name) {
  std::string_view rest = header;
  while (!rest.empty()) {
    const std::size_t semi = rest.find(';');
    std::string_view item = rest.substr(0, semi);
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    if (item.size() > name.size() && item.substr(0, name.size()) == name &&
        item[name.size()] == '=') {
      return PercentDecode(item.substr(name.size() + 1));
    }
    if (semi == std::string_view::npos) break;
    rest.remove_prefix(semi + 1);
  }
  return "";
}

std::string UtcTime(double unix_seconds) {
  if (unix_seconds <= 0.0) return "-";
  const std::time_t t = static_cast<std::time_t>(unix_seconds);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M:%S UTC", &tm);
  return text;
}

std::string Seconds(double s) {
  if (s < 0) return "-";
  if (s < 120) return fmt::format("{:.1f} s", s);
  if (s < 7200) return fmt::format("{:.1f} min", s / 60);
  return fmt::format("{:.1f} h", s / 3600);
}

double Elapsed(const JobRecord& job) {
  if (job.started_at <= 0.0) return -1.0;
  return (job.finished_at > 0.0 ? job.finished_at : UnixNow()) - job.started_at;
}

std::string ErrorText(double e) {
  if (!std::isfinite(e)) return "-";
  return fmt::format("{:.4g}", e);
}

// A genetic run's generation of its limit; a continuous run's step (its rows are the fit's
// steps, not generations: no limit to show).
std::string GenerationText(const JobRecord& job) {
  if (proto::ProgressCountsSteps(job.strategy))
    return job.progress ? fmt::format("step {}", job.progress->generation) : "-";
  return job.progress ? fmt::format("{} / {}", job.progress->generation, job.max_generations)
                      : fmt::format("- / {}", job.max_generations);
}

std::string Page(const std::string& title, const std::string& body) {
  return R"(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>)" +
         XmlEscape(title) + R"( - springfitd</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>
body{font:14px/1.45 system-ui,sans-serif;margin:1.5em 2em;color:#222;max-width:1400px}
a{color:#1d5fa8}table{border-collapse:collapse}td,th{padding:3px 10px;border-bottom:1px solid #ddd;text-align:left;vertical-align:top}
th{background:#f3f3f3}.state{padding:1px 7px;border-radius:8px;font-size:12px;background:#eee}
.running{background:#d7ecff}.succeeded{background:#d9f3d9}.failed{background:#f8d4d4}.cancelled{background:#eee}.queued{background:#fff2c8}.preparing{background:#efe3ff}
figure{margin:1em 0}figure svg{max-width:100%;height:auto;border:1px solid #eee}nav{margin-bottom:1em}
.num{text-align:right;font-variant-numeric:tabular-nums}form.filter input,form.filter select{margin-right:.6em}
</style></head><body><nav><a href="/">springfitd jobs</a> · <a href="/metrics">metrics</a> · <a href="/healthz">health</a></nav>
)" + body +
         "\n</body></html>\n";
}

std::string StateBadge(JobState s) {
  const std::string name(proto::JobStateName(s));
  return "<span class=\"state " + name + "\">" + name + "</span>";
}

// The jobs of a listing whose rows cannot be read: set aside by the store, one incident each.
std::string QuarantinedTable(const std::vector<QuarantinedJob>& quarantined) {
  if (quarantined.empty()) return "";
  std::string body =
      "<h2>Quarantined</h2>\n<p>Their rows in the store cannot be read: they are never run, "
      "and the other jobs go on. Repair or delete them in the store.</p>\n<table "
      "id=\"quarantined\"><tr><th>job</th><th>incident</th><th>since</th><th>reason</th>"
      "<th>state before</th></tr>\n";
  for (const QuarantinedJob& q : quarantined) {
    body += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
                        q.job_id, q.incident, UtcTime(q.quarantined_at), XmlEscape(q.reason),
                        XmlEscape(q.previous_state));
  }
  return body + "</table>\n";
}

// The number at a path of object members in `j`, or nothing where a member is missing or not a
// number. (A const Json's operator[] on a missing member is undefined behaviour: the result
// card reads stored results, which may lack any member.)
std::optional<double> NumberAt(const Json& j, std::initializer_list<const char*> path) {
  const Json* at = &j;
  for (const char* key : path) {
    if (!at->is_object()) return std::nullopt;
    const auto it = at->find(key);
    if (it == at->end()) return std::nullopt;
    at = &*it;
  }
  if (!at->is_number()) return std::nullopt;
  return at->get<double>();
}

std::string Row(const std::string& key, const std::string& value_html) {
  return "<tr><th>" + XmlEscape(key) + "</th><td>" + value_html + "</td></tr>\n";
}

// The live update: a request a second while the job is queued or running; the page reloads
// once when it ends, to show the result. data-updates counts the updates received (the
// browser test reads it).
// The result card: the verdict and the numbers that matter first, in the words of `springfit
// run` (engine/api/verdict.h), then the regularisation and the certificate's bound
// from the result, then every search setting submitted.
std::string ResultCard(const Outcome& o, const Json& result, const Json& search) {
  std::string body = "<table id=\"result-card\">\n";
  body += Row("verdict", "<strong class=\"verdict " + std::string(VerdictName(o.verdict)) + "\">" +
                             std::string(VerdictName(o.verdict)) + "</strong>");
  for (const std::string& line : o.unmet) body += Row("WARNING", XmlEscape(line));
  for (const std::string& line : o.doubts) body += Row("WARNING", XmlEscape(line));
  if (const std::string what = o.WhatToTry(); !what.empty())
    body += Row("what to try", XmlEscape(what));
  if (!o.reason.empty()) body += Row("no usable model", XmlEscape(o.reason));
  body += Row("springs",
              std::to_string(o.springs) +
                  (o.unseen_springs > 0
                       ? fmt::format(" (+{} between held nodes, in exports)", o.unseen_springs)
                       : std::string()));
  // (A linear response: what the simulator shows first, the small-load limit the fit judged by
  // beside it; the words of the headline.)
  if (o.simulated_rms_error) {
    body += Row("E as simulated (named cases, nonlinear springs)",
                ErrorText(*o.simulated_rms_error) +
                    (o.baseline_simulated_rms_error
                         ? " (baseline " + ErrorText(*o.baseline_simulated_rms_error) + ")"
                         : std::string()));
  }
  body += Row(o.simulated_rms_error ? "E small-load (named cases)" : "E (named cases)",
              o.rms_error ? ErrorText(*o.rms_error) : "- (no equilibrium)");
  if (o.baseline_rms_error) {
    body += Row("baseline E", ErrorText(*o.baseline_rms_error));
    if (o.rms_error && *o.baseline_rms_error > 0.0)
      body += Row("E / baseline", ErrorText(*o.rms_error / *o.baseline_rms_error));
  }
  if (o.held_out_rms_error) {
    std::string text = "median " + ErrorText(*o.held_out_rms_error);
    if (o.held_out_p95) text += ", worst 5% above " + ErrorText(*o.held_out_p95);
    if (o.baseline_held_out_rms_error)
      text += " (baseline median " + ErrorText(*o.baseline_held_out_rms_error) + ")";
    body += Row("E on held-out " + o.held_out_of, text);
  }
  if (const auto g = result.find("generalization"); g != result.end() && g->is_object()) {
    if (const auto low = NumberAt(*g, {"lambda_min"}), high = NumberAt(*g, {"lambda_max"});
        low && high)
      body += Row("generalised eigenvalues",
                  fmt::format("[{}, {}]", ErrorText(*low), ErrorText(*high)));
    // A nonlinear response: the held-out probes and named cases at fractions of the named
    // loads' size, every model nonlinear (proto/RUN.md, generalization.amplitudes).
    for (const auto& a : g->value("amplitudes", proto::Json::array())) {
      const auto median = NumberAt(a, {"model", "median"});
      if (!median) continue;
      std::string text = "median " + ErrorText(*median);
      if (const auto p95 = NumberAt(a, {"model", "p95"}))
        text += ", worst 5% above " + ErrorText(*p95);
      if (const auto baseline = NumberAt(a, {"baseline", "median"}))
        text += " (baseline median " + ErrorText(*baseline) + ")";
      body +=
          Row(fmt::format("E nonlinear at {:.0f}% of the loads", 100.0 * a.value("amplitude", 0.0)),
              text);
    }
    // Tool pushes and grasps (imposed displacements): the shape and the force the tool feels
    // (proto/RUN.md, generalization.tool_pushes).
    for (const auto& t : g->value("tool_pushes", proto::Json::array())) {
      const auto median = NumberAt(t, {"model", "median"});
      const auto force = NumberAt(t, {"model_force", "median"});
      if (!median || !force) continue;
      std::string text =
          "median E " + ErrorText(*median) + ", tool force error " + ErrorText(*force);
      const auto baseline = NumberAt(t, {"baseline", "median"});
      const auto baseline_force = NumberAt(t, {"baseline_force", "median"});
      if (baseline && baseline_force)
        text += " (baseline " + ErrorText(*baseline) + ", " + ErrorText(*baseline_force) + ")";
      if (t.value("model_inverted", 0) > 0)
        text += fmt::format("; {} invert an element", t.value("model_inverted", 0));
      text +=
          fmt::format(" over {} pushes and {} grasps", t.value("pushes", 0), t.value("grasps", 0));
      body +=
          Row(fmt::format("tool push at {:.0f}% of the loads", 100.0 * t.value("amplitude", 0.0)),
              text);
    }
    // The nonlinear fit's choosing error at the load range's sizes (generalization.fit.nonlinear).
    if (const auto returned = NumberAt(*g, {"fit", "nonlinear", "choosing_rms_error"})) {
      std::string text =
          fmt::format("{} Gauss-Newton steps: choosing E ",
                      static_cast<long long>(
                          NumberAt(*g, {"fit", "nonlinear", "gauss_newton_steps"}).value_or(0.0)));
      if (const auto start = NumberAt(*g, {"fit", "nonlinear", "start_choosing_rms_error"}))
        text += ErrorText(*start) + " at rest-linear fit, ";
      text += ErrorText(*returned) + " returned";
      if (const auto base = NumberAt(*g, {"fit", "nonlinear", "baseline_choosing_rms_error"}))
        text += " (baseline " + ErrorText(*base) + ")";
      text += proto::NonlinearFitNotes(g->at("fit").at("nonlinear"));
      body += Row("nonlinear fit", text);
    }
    if (const auto strength = NumberAt(*g, {"fit", "regularization"}))
      body += Row("regularisation", ErrorText(*strength));
  } else if (const auto c = result.find("continuous"); c != result.end() && c->is_object()) {
    if (const auto strength = NumberAt(*c, {"regularization", "strength"}))
      body += Row("regularisation", ErrorText(*strength));
  }
  if (result.contains("ran") && result["ran"].is_string())
    body += Row("strategy that ran", XmlEscape(result["ran"].get<std::string>()));
  if (const std::string units = proto::UnitsText(result.value("units", proto::Json()));
      !units.empty())
    body += Row("units", XmlEscape(units));
  // What was asked (the scene's search settings; none: every default), then the options the
  // strategy that ran read (proto::RunOptionsToJson).
  std::string asked;
  if (search.is_object())
    for (const auto& [key, value] : search.items())
      asked += (asked.empty() ? "" : ", ") + key + " " + value.dump();
  body += Row("settings submitted", XmlEscape(asked.empty() ? "none (the defaults)" : asked));
  if (const auto options = result.find("options"); options != result.end() && options->is_object())
    for (const auto& [key, value] : options->items())
      body += Row("option: " + key, XmlEscape(value.dump()));
  return body + "</table>\n";
}

constexpr const char* kLiveScript = R"(<script>
(function () {
  var live = document.getElementById('live');
  if (!live) return;
  var id = live.getAttribute('data-job'), updates = 0;
  function set(key, value) { var e = document.getElementById('p-' + key); if (e) e.textContent = value; }
  function poll() {
    fetch('/jobs/' + id + '/progress.json', {cache: 'no-store', credentials: 'same-origin'})
      .then(function (r) { return r.ok ? r.json() : null; })
      .then(function (p) {
        if (p) {
          ['state', 'generation', 'phase', 'best', 'elapsed', 'evaluations'].forEach(function (k) { set(k, p[k]); });
          live.setAttribute('data-generation', p.generation_number);
          live.setAttribute('data-updates', ++updates);
          if (updates % 5 === 0) {
            fetch('/jobs/' + id + '/error.svg', {cache: 'no-store', credentials: 'same-origin'})
              .then(function (r) { return r.ok ? r.text() : null; })
              .then(function (svg) {
                // (Without the file's XML declaration, which HTML would keep as a comment.)
                if (svg) document.getElementById('error-plot').innerHTML = svg.replace(/^<\?xml[^>]*>\s*/, '');
              });
          }
          if (p.final) { location.reload(); return; }
        }
        setTimeout(poll, 1000);
      })
      .catch(function () { setTimeout(poll, 1000); });
  }
  setTimeout(poll, 1000);
})();
</script>)";

// An SVG document inlined in HTML: its XML declaration dropped.
std::string Inline(const std::string& svg) {
  const std::size_t start = svg.find("<svg");
  return start == std::string::npos ? svg : svg.substr(start);
}

// The job's settings and times, as submitted and run.
std::string SettingsTable(const JobRecord& job) {
  std::string body = "<h2>Job</h2>\n<table id=\"settings\">\n";
  body += Row("label", XmlEscape(job.label));
  body += Row("strategy", XmlEscape(job.strategy));
  body += Row("seed", std::to_string(job.seed));
  body += Row("genes", std::to_string(job.genes));
  body += Row("priority", std::to_string(job.priority));
  body += Row("idempotency key", XmlEscape(job.idempotency_key));
  body += Row("created", UtcTime(job.created_at));
  body += Row("started", UtcTime(job.started_at));
  body += Row("finished", UtcTime(job.finished_at));
  if (job.state == JobState::kFailed) body += Row("error", XmlEscape(job.error));
  if (job.exact) body += Row("exact", *job.exact ? "yes" : "no");
  return body + "</table>\n";
}

// How the run stopped and what the load cases do not tell apart (`identifiability`). Where
// the groups were not analysed no count is claimed, and the reason is shown.
std::string IdentifiabilityTable(const Json& r) {
  std::string body = "<h2>Identifiability</h2>\n<table id=\"identifiability\">\n";
  if (r.contains("stop")) body += Row("stop", XmlEscape(r.value("stop", "")));
  if (r.contains("stop_message") && r["stop_message"].is_string())
    body += Row("why", XmlEscape(r["stop_message"].get<std::string>()));
  if (const auto id = r.find("identifiability"); id != r.end() && id->is_object()) {
    const Json& rep = *id;
    // The springs between held nodes apart, in check's and run's words (outcome.unseen_springs).
    const int held = r.contains("outcome") && r["outcome"].is_object()
                         ? r["outcome"].value("unseen_springs", 0)
                         : 0;
    if (held > 0)
      body += Row("between held nodes",
                  XmlEscape(fmt::format("{} springs (both nodes held in every load case: {})", held,
                                        proto::HeldSpringsText(r.contains("baseline") &&
                                                               r["baseline"].is_object()))));
    body += Row("unseen springs (no load case changes their length)",
                std::to_string(rep.value("unseen", Json::array()).size()) +
                    (held > 0 ? fmt::format(" besides the {} between held nodes", held) : ""));
    if (rep.contains("rank") && rep["rank"].is_number())
      body += Row("rank of the analysed groups", std::to_string(rep["rank"].get<int>()));
    const Json groups = rep.value("groups", Json::array());
    // (Where the groups were not analysed no count is claimed, and the reason is shown.)
    const bool analysed = !rep.contains("analysed") || rep["analysed"] != false;
    const auto why = rep.find("not_analysed");
    body += Row("groups of springs the loads do not tell apart",
                analysed ? std::to_string(groups.size())
                         : XmlEscape(GroupsNotAnalysedText(why != rep.end() && why->is_string()
                                                               ? why->get<std::string>()
                                                               : std::string())));
    int shown = 0;
    for (const Json& g : groups) {
      if (++shown > 10) break;
      std::string text = std::to_string(g.value("springs", Json::array()).size()) + " springs";
      if (g.contains("suggestion") && g["suggestion"].is_string())
        text += ": " + g["suggestion"].get<std::string>();
      body += Row("group " + std::to_string(shown), XmlEscape(text));
    }
  }
  return body + "</table>\n";
}

}  // namespace

Dashboard::Dashboard(JobStore& store, Scheduler& scheduler, Metrics& metrics,
                     DashboardOptions options)
    : store_(store), scheduler_(scheduler), metrics_(metrics), options_(std::move(options)) {}

bool Dashboard::Authorized(const HttpRequest& request) const {
  if (options_.token.empty()) return true;
  if (const auto a = request.headers.find("authorization"); a != request.headers.end()) {
    const std::string prefix = "Bearer ";
    if (a->second.compare(0, prefix.size(), prefix) == 0 &&
        SameToken(options_.token, a->second.substr(prefix.size()))) {
      return true;
    }
  }
  if (const auto c = request.headers.find("cookie"); c != request.headers.end()) {
    const std::string value = CookieValue(c->second, kCookie);
    if (!value.empty() && SameToken(options_.token, value)) return true;
  }
  return false;
}

HttpResponse Dashboard::Handle(const HttpRequest& request) {
  try {
    const std::size_t q = request.target.find('?');
    const std::string path = request.target.substr(0, q);
    const std::map<std::string, std::string> query =
        q == std::string::npos ? std::map<std::string, std::string>{}
                               : ParseForm(std::string_view(request.target).substr(q + 1));
    if (path == "/healthz") return Health();
    if (path == "/login") return Login(request);
    if (request.method != "GET" && request.method != "HEAD") {
      HttpResponse r = Text(405, "only GET here\n");
      r.headers.emplace_back("Allow", "GET, HEAD");
      return r;
    }
    if (!Authorized(request)) {
      const auto accept = request.headers.find("accept");
      if (accept != request.headers.end() &&
          accept->second.find("text/html") != std::string::npos) {
        HttpResponse r = Text(303, "log in first\n");
        r.headers.emplace_back("Location", "/login");
        return r;
      }
      HttpResponse r = Text(401, "unauthorized: the daemon's token is required\n");
      r.headers.emplace_back("WWW-Authenticate", "Bearer realm=\"springfitd\"");
      return r;
    }
    return Route(request, path, query);
  } catch (const StoreUnavailable& e) {
    return Text(503, std::string("store unavailable, try again: ") + e.what() + "\n");
  } catch (const InputError& e) {
    return Text(400, std::string(e.what()) + "\n");
  } catch (const StoreCorrupt& e) {
    // A quarantined job's was logged once, by the store that quarantined it.
    if (e.incident() == 0) spdlog::error("http {}: {}", request.target.substr(0, 200), e.what());
    return Text(500, std::string("the store holds a damaged record: ") + e.what() + "\n");
  } catch (const std::exception& e) {
    spdlog::error("http {}: {}", request.target.substr(0, 200), e.what());
    return Text(500, std::string("internal error: ") + e.what() + "\n");
  }
}

HttpResponse Dashboard::Route(const HttpRequest&, const std::string& path,
                              const std::map<std::string, std::string>& query) {
  if (path == "/") return ListView(query);
  if (path == "/metrics") return MetricsText();
  const std::string prefix = "/jobs/";
  if (path.compare(0, prefix.size(), prefix) != 0) return Text(404, "not found\n");
  const std::string rest = path.substr(prefix.size());
  const std::size_t slash = rest.find('/');
  const std::string id_text = rest.substr(0, slash);
  const std::string what = slash == std::string::npos ? "" : rest.substr(slash + 1);
  if (id_text.empty() || id_text.size() > 18 ||
      !std::all_of(id_text.begin(), id_text.end(), [](unsigned char c) { return std::isdigit(c); }))
    return Text(404, "not found\n");
  const std::optional<JobRecord> stored = store_.GetJob(std::stoll(id_text));
  if (!stored) return Text(404, "no such job: " + id_text + "\n");
  const JobRecord job = Live(*stored);
  if (what.empty()) return JobView(job);
  if (what == "progress.json") return Progress(job);
  if (what == "error.svg") return ErrorPlot(job);
  if (what == "topology.svg") {
    const auto of = query.find("of");
    return Topology(job, of == query.end() ? "result" : of->second);
  }
  if (what == "result.json") return ResultJson(job);
  if (what == "trace.csv") return TraceCsv(job);
  for (const char* ext : {"vtu", "vtk", "scn", "json"}) {
    if (what == std::string("model.") + ext) return Model(job, ext);
  }
  return Text(404, "not found\n");
}

// Where a job running here is inside its step (Scheduler::Phase): "fit, 12.3 s, E 0.05", and
// the time the phase has left at most where it says ("probe_fit, 7.5 s, E 0.21, ETA <= 0:10",
// as the CLI's progress line).
std::string Dashboard::PhaseText(std::int64_t id) const {
  const std::optional<Scheduler::LivePhase> phase = scheduler_.Phase(id);
  if (!phase) return "-";
  std::string text = phase->phase + ", " + Seconds(phase->wall_seconds);
  if (std::isfinite(phase->rms_error)) text += ", E " + ErrorText(phase->rms_error);
  if (std::isfinite(phase->eta_seconds) && phase->eta_seconds >= 0.0)
    text += ", ETA <= " + proto::ClockText(phase->eta_seconds);
  return text;
}

JobRecord Dashboard::Live(JobRecord job) const {
  if (job.state == JobState::kRunning) {
    if (auto live = scheduler_.LiveProgress(job.id)) job.progress = live;
  }
  return job;
}

HttpResponse Dashboard::Login(const HttpRequest& request) {
  std::string message;
  if (request.method == "POST") {
    const std::map<std::string, std::string> form = ParseForm(request.body);
    const auto token = form.find("token");
    if (!options_.token.empty() && token != form.end() &&
        SameToken(options_.token, token->second)) {
      HttpResponse r = Text(303, "logged in\n");
      r.headers.emplace_back("Location", "/");
      r.headers.emplace_back("Set-Cookie", std::string(kCookie) + "=" +
                                               PercentEncode(token->second) +
                                               "; HttpOnly; SameSite=Strict; Path=/");
      return r;
    }
    message = options_.token.empty() ? "<p>This daemon asks for no token.</p>"
                                     : "<p><strong>Wrong token.</strong></p>";
  }
  HttpResponse r = Content(
      "text/html; charset=utf-8",
      Page(
          "log in",
          "<h1>springfitd</h1>" + message +
              R"(<form method="post" action="/login"><label>Token <input type="password" name="token" autocomplete="current-password"></label> <button type="submit">Log in</button></form>)"));
  if (!message.empty() && !options_.token.empty()) r.status = 401;
  return r;
}

HttpResponse Dashboard::Health() {
  try {
    store_.CountQueued();
    return Text(200, "ok\n");
  } catch (const std::exception& e) {
    return Text(503, std::string("store unavailable: ") + e.what() + "\n");
  }
}

HttpResponse Dashboard::MetricsText() {
  Metrics::Gauges g;
  g.running_here = scheduler_.running();
  try {
    g.jobs = store_.CountJobs();
    const auto queued = g.jobs->find(JobState::kQueued);
    g.queued = queued == g.jobs->end() ? 0 : queued->second;
  } catch (const std::exception&) {
    g.store_up = false;
  }
  return Content("text/plain; version=0.0.4; charset=utf-8", metrics_.Render(g));
}

HttpResponse Dashboard::ListView(const std::map<std::string, std::string>& query) {
  JobFilter filter;
  filter.newest_first = true;
  filter.limit = options_.page_size;
  std::string state_name, label;
  if (const auto s = query.find("state"); s != query.end() && !s->second.empty()) {
    state_name = s->second;
    filter.state = proto::ParseJobState(state_name);
    if (!filter.state) throw InputError("state", "unknown state '" + state_name + "'");
  }
  if (const auto l = query.find("label"); l != query.end() && !l->second.empty()) {
    label = l->second.substr(0, 200);
    filter.label = label;
  }
  if (const auto c = query.find("cursor"); c != query.end() && !c->second.empty()) {
    if (c->second.size() > 18 || !std::all_of(c->second.begin(), c->second.end(),
                                              [](unsigned char ch) { return std::isdigit(ch); }))
      throw InputError("cursor", "not a job id");
    filter.after_id = std::stoll(c->second);
  }
  const JobPage page = store_.ListJobs(filter);
  std::string body = "<h1>Jobs</h1>\n<form class=\"filter\" method=\"get\" action=\"/\">State ";
  body += "<select name=\"state\"><option value=\"\">any</option>";
  for (const JobState state : proto::AllJobStates()) {
    const std::string_view s = proto::JobStateName(state);
    body += fmt::format("<option{}>{}</option>", state_name == s ? " selected" : "", s);
  }
  body += "</select> Label <input name=\"label\" value=\"" + XmlEscape(label) +
          "\"> <button type=\"submit\">Filter</button></form>\n";
  body +=
      "<table id=\"jobs\"><tr><th>job</th><th>label</th><th>scene</th><th>state</th>"
      "<th>strategy</th><th class=\"num\">genes</th><th class=\"num\">generation</th>"
      "<th>verdict</th><th class=\"num\">springs</th><th class=\"num\">E</th>"
      "<th class=\"num\">elapsed</th><th>exact</th></tr>\n";
  for (const JobRecord& stored : page.jobs) {
    const JobRecord job = Live(stored);
    body += fmt::format(
        "<tr><td><a href=\"/jobs/{0}\">{0}</a></td><td>{1}</td><td>{2}</td><td>{3}</td>"
        "<td>{4}</td><td class=\"num\">{5}</td><td class=\"num\">{6}</td><td>{7}</td>"
        "<td class=\"num\">{8}</td><td class=\"num\">{9}</td><td class=\"num\">{10}</td>"
        "<td>{11}</td></tr>\n",
        job.id, XmlEscape(job.label), XmlEscape(job.scene_name), StateBadge(job.state),
        XmlEscape(job.strategy), job.genes, GenerationText(job),
        job.outcome ? std::string(VerdictName(job.outcome->verdict)) : "-",
        job.outcome ? std::to_string(job.outcome->springs) : "-", proto::JobErrorText(job),
        Seconds(Elapsed(job)), job.exact ? (*job.exact ? "yes" : "no") : "-");
  }
  body += "</table>\n";
  if (page.jobs.empty() && page.quarantined.empty()) body += "<p>No jobs.</p>\n";
  body += QuarantinedTable(page.quarantined);
  if (page.next_cursor) {
    std::string next = "/?cursor=" + std::to_string(*page.next_cursor);
    if (!state_name.empty()) next += "&state=" + PercentEncode(state_name);
    if (!label.empty()) next += "&label=" + PercentEncode(label);
    body += "<p><a id=\"older\" href=\"" + XmlEscape(next) + "\">older jobs</a></p>\n";
  }
  return Content("text/html; charset=utf-8", Page("jobs", body));
}

std::shared_ptr<const Problem> Dashboard::ProblemOf(const JobRecord& job) {
  {
    MutexLock lock(problems_mutex_);
    for (const auto& [id, problem] : problems_) {
      if (id == job.id) return problem;
    }
  }
  const std::optional<std::string> scene = store_.GetScene(job.id);
  if (!scene) throw std::runtime_error("the job's scene is missing from the store");
  auto problem = std::make_shared<const Problem>(proto::SceneFromText(*scene));
  MutexLock lock(problems_mutex_);
  problems_.emplace_back(job.id, problem);
  while (static_cast<int>(problems_.size()) > std::max(1, options_.cached_problems))
    problems_.erase(problems_.begin());
  return problem;
}

std::string Dashboard::ErrorPlotSvg(const JobRecord& job) {
  figures::ErrorCurve curve;
  curve.label = "job " + std::to_string(job.id);
  for (const TraceRow& row : store_.GetTrace(job.id, -1, kMaxTraceRows))
    curve.points.emplace_back(row.wall_seconds, std::sqrt(row.best_normalized_error));
  if (curve.points.empty()) return "";
  return figures::RenderErrorPlot({curve}, "job " + std::to_string(job.id) + ": " + job.scene_name);
}

std::string Dashboard::TopologySvg(const JobRecord& job, bool result) {
  // What to draw first: the scene is prepared (seconds for a large one) only when there is
  // something (never for a job still being prepared).
  std::optional<std::string> text;
  std::vector<Improvement> improvements;
  if (result) {
    text = store_.GetResult(job.id);
    if (!text) return "";
  } else {
    improvements = store_.GetImprovements(job.id, {.last = true});  // the best so far
    if (improvements.empty()) return "";
  }
  const std::shared_ptr<const Problem> problem = ProblemOf(job);
  figures::TopologyFigureInput input;
  input.title = "job " + std::to_string(job.id) + ": " + job.scene_name;
  if (result) {
    const proto::StoredResult typed = proto::StoredResultFromJson(proto::ParseJson(*text));
    proto::ExpectResultOfScene(typed, *problem);
    input.springs = typed.springs;
    input.stiffness = typed.stiffness;
    input.note = typed.stop == "cancelled" ? "cancelled: the best topology so far" : "result";
  } else {
    input.springs = problem->SpringsOfGenome(improvements.back().genome);
    input.note = "best so far, generation " + std::to_string(improvements.back().generation);
  }
  return figures::RenderTopologyFigure(*problem, input);
}

std::string Dashboard::ModelSection(const JobRecord& job, bool result) {
  std::string body;
  try {
    const std::string best = TopologySvg(job, result);
    body += result ? "<h2>Model</h2>\n" : "<h2>Best topology so far</h2>\n";
    // A large figure (a 3D mesh's springs: megabytes of SVG) is a file the browser fetches,
    // not part of the page.
    std::string figure;
    if (best.empty()) {
      figure = "<p>No model evaluated yet.</p>";
    } else if (best.size() > options_.max_inline_figure_bytes) {
      figure = fmt::format(
          "<img src=\"/jobs/{}/topology.svg?of={}\" alt=\"the model's springs\" "
          "style=\"max-width:100%\"><p><a href=\"/jobs/{}/topology.svg?of={}\">the figure</a> "
          "({} KB)</p>",
          job.id, result ? "result" : "best", job.id, result ? "result" : "best",
          best.size() / 1024);
    } else {
      figure = Inline(best);
    }
    body += "<figure id=\"topology\">" + figure + "</figure>\n";
  } catch (const std::exception& e) {
    body += "<p>The topology figure cannot be drawn: " + XmlEscape(e.what()) + "</p>\n";
  }
  return body;
}

HttpResponse Dashboard::JobView(const JobRecord& job) {
  const bool final = proto::IsFinal(job.state);
  std::string body = fmt::format("<h1>Job {} · {} {}</h1>\n", job.id, XmlEscape(job.scene_name),
                                 StateBadge(job.state));
  std::string result_json;
  if (final) {
    if (auto r = store_.GetResult(job.id)) result_json = *r;
  }
  const Json result = result_json.empty() ? Json::object() : proto::ParseJson(result_json);
  if (job.outcome) {
    Json search;
    try {
      if (const auto scene = store_.GetScene(job.id))
        search = proto::ParseJson(*scene).value("search", Json::object());
    } catch (const std::exception&) {
    }
    body += "<h2>Result</h2>\n" + ResultCard(*job.outcome, result, search);
  }
  body += SettingsTable(job);
  body += "<h2>Progress</h2>\n";
  body += fmt::format(
      "<table id=\"live\" data-job=\"{}\" data-generation=\"{}\" data-initial-generation=\"{}\" "
      "data-updates=\"0\" data-final=\"{}\">\n",
      job.id, job.progress ? job.progress->generation : -1,
      job.progress ? job.progress->generation : -1, final ? "true" : "false");
  body += Row("state",
              "<span id=\"p-state\">" + std::string(proto::JobStateName(job.state)) + "</span>");
  body += Row(proto::ProgressCountsSteps(job.strategy) ? "progress" : "generation",
              "<span id=\"p-generation\">" + GenerationText(job) + "</span>");
  body += Row("phase", "<span id=\"p-phase\">" + XmlEscape(PhaseText(job.id)) + "</span>");
  body += Row("E (relative RMS nodal error)",
              "<span id=\"p-best\">" + proto::JobErrorText(job) + "</span>");
  body += Row("evaluations", "<span id=\"p-evaluations\">" +
                                 (job.progress ? std::to_string(job.progress->evaluations) : "-") +
                                 "</span>");
  body += Row("elapsed", "<span id=\"p-elapsed\">" + Seconds(Elapsed(job)) + "</span>");
  body += "</table>\n";

  body += "<h2>Error against time</h2>\n<figure id=\"error-plot\">";
  const std::string plot = ErrorPlotSvg(job);
  body += plot.empty() ? "<p>No generation stored yet.</p>" : Inline(plot);
  body += "</figure>\n";

  body += ModelSection(job, !result_json.empty());
  if (!result_json.empty()) body += IdentifiabilityTable(result);
  body += "<h2>Downloads</h2>\n<ul id=\"downloads\">";
  const std::string base = "/jobs/" + std::to_string(job.id);
  if (!result_json.empty())
    body += "<li><a href=\"" + base + "/result.json\">result (JSON)</a></li>";
  body += "<li><a href=\"" + base + "/trace.csv\">trace (CSV)</a></li>";
  if (!result_json.empty()) {
    body += "<li>model: <a href=\"" + base + "/model.vtu\">VTU (ParaView)</a>, <a href=\"" + base +
            "/model.vtk\">VTK</a>, <a href=\"" + base + "/model.scn\">SOFA scene</a>, <a href=\"" +
            base + "/model.json\">JSON</a></li>";
  }
  body += "</ul>\n";
  if (!final) body += kLiveScript;
  return Content("text/html; charset=utf-8", Page("job " + std::to_string(job.id), body));
}

HttpResponse Dashboard::Progress(const JobRecord& job) {
  Json p;
  p["job_id"] = job.id;
  p["state"] = proto::JobStateName(job.state);
  p["final"] = proto::IsFinal(job.state);
  p["generation"] = GenerationText(job);
  p["generation_number"] = job.progress ? job.progress->generation : -1;
  p["best"] = proto::JobErrorText(job);
  p["phase"] = PhaseText(job.id);
  p["evaluations"] = job.progress ? std::to_string(job.progress->evaluations) : "-";
  p["elapsed"] = Seconds(Elapsed(job));
  return Content("application/json", p.dump());
}

HttpResponse Dashboard::ErrorPlot(const JobRecord& job) {
  const std::string svg = ErrorPlotSvg(job);
  if (svg.empty()) return Text(404, "no generation stored yet\n");
  return Content("image/svg+xml", svg);
}

HttpResponse Dashboard::Topology(const JobRecord& job, const std::string& which) {
  if (which != "best" && which != "result") throw InputError("of", "'best' or 'result'");
  const std::string svg = TopologySvg(job, which == "result");
  if (svg.empty()) return Text(404, which == "result" ? "no result\n" : "no model yet\n");
  return Content("image/svg+xml", svg);
}

HttpResponse Dashboard::ResultJson(const JobRecord& job) {
  const std::optional<std::string> result = store_.GetResult(job.id);
  if (!result) return Text(404, "job " + std::to_string(job.id) + " has no result\n");
  Json j = proto::ParseJson(*result);
  j["state"] = proto::JobStateName(job.state);
  HttpResponse r = Content("application/json", j.dump(2) + "\n");
  r.headers.emplace_back("Content-Disposition",
                         "attachment; filename=\"job-" + std::to_string(job.id) + ".json\"");
  return r;
}

HttpResponse Dashboard::TraceCsv(const JobRecord& job) {
  std::string csv = proto::TraceCsvHeader() + "\n";
  int after = -1;
  while (true) {
    const std::vector<TraceRow> rows = store_.GetTrace(job.id, after, 10000);
    for (const TraceRow& row : rows) csv += proto::TraceRowToCsv(row) + "\n";
    if (rows.size() < 10000) break;
    after = rows.back().generation;
  }
  HttpResponse r = Content("text/csv; charset=utf-8", csv);
  r.headers.emplace_back("Content-Disposition",
                         "attachment; filename=\"job-" + std::to_string(job.id) + "-trace.csv\"");
  return r;
}

HttpResponse Dashboard::Model(const JobRecord& job, const std::string& extension) {
  const std::optional<std::string> text = store_.GetResult(job.id);
  if (!text) return Text(404, "job " + std::to_string(job.id) + " has no result\n");
  const std::shared_ptr<const Problem> problem = ProblemOf(job);
  const proto::StoredResult typed = proto::StoredResultFromJson(proto::ParseJson(*text));
  proto::ExpectResultOfScene(typed, *problem);
  const io::SpringModel model = io::ModelOfResult(*problem, typed);
  std::string body, type = "application/octet-stream";
  if (extension == "vtu") {
    body = io::VtuText(model);
    type = "application/xml";
  } else if (extension == "vtk") {
    body = io::VtkLegacyText(model);
  } else if (extension == "scn") {
    body = io::SofaSceneText(model);
    type = "application/xml";
  } else {
    body = io::ModelJsonText(model);
    type = "application/json";
  }
  HttpResponse r = Content(type, body);
  r.headers.emplace_back(
      "Content-Disposition",
      "attachment; filename=\"job-" + std::to_string(job.id) + "-model." + extension + "\"");
  return r;
}

}  // namespace springfit::server
