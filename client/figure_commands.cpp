// springfit render | plot: figures of a result, from a result file (`run -o`, `result -o`)
// or from a daemon's job (README.md, "Figures").
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "client/remote_job.h"
#include "client/result_source.h"
#include "engine/api/identify.h"
#include "engine/api/input_error.h"
#include "figures/error_plot.h"
#include "figures/topology_figure.h"
#include "figures/tradeoff_plot.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"

namespace springfit::cli {
namespace {
using namespace springfit::figures;  // the figures this command draws
using proto::Json;

std::string Describe(const proto::StoredResult& result) {
  std::string s = result.scene + ", strategy " + result.strategy;
  if (result.seed) s += ", seed " + std::to_string(*result.seed);
  return s;
}

void WriteSvg(const std::string& path, const std::string& svg) {
  std::ofstream out(path);
  out << svg;
  out.close();
  if (!out) throw std::runtime_error("cannot write " + path);
}

// -o of render and plot: they write SVG, and a name that says otherwise (a .png a viewer would
// refuse) is a command-line error rather than an SVG under that name.
const CLI::Validator kSvgName(
    [](std::string& name) -> std::string {
      std::string ext = std::filesystem::path(name).extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      return ext == ".svg" ? std::string()
                           : "'" + name + "' does not end in .svg (render and plot write SVG)";
    },
    "FILE.svg");

struct RenderArgs {
  ServerOptions server;
  std::string source;
  std::string output;
  std::string scene_path;
  std::vector<int> load_cases;
  double magnify = 0.0;
  bool node_numbers = false;  // --node-numbers
  bool rest = false;          // --rest
};

int Render(const RenderArgs& a) {
  const ResultWithScene loaded = LoadResultWithScene(a.source, a.server, a.scene_path);
  const proto::StoredResult& typed = loaded.result;
  const Problem& problem = *loaded.problem;
  const std::string& where = loaded.where;

  TopologyFigureInput input;
  input.title = Describe(typed) + " (" + where + ")";
  input.springs = typed.springs;
  input.stiffness = typed.stiffness;
  if (typed.stop == "cancelled") input.note = "cancelled: the best topology so far";
  TopologyFigureOptions options;
  options.load_cases = a.load_cases;
  options.magnify = a.magnify;
  options.node_numbers = a.node_numbers;
  options.rest_topology = a.rest;
  WriteSvg(a.output, RenderTopologyFigure(problem, input, options));
  return kExitOk;
}

struct PlotArgs {
  ServerOptions server;
  std::vector<std::string> sources;
  std::string output;
  std::string title;
  bool tradeoff = false;
  std::string x = "seconds";  // --x
};

// `plot --tradeoff`: the sparsity path of each result (strategy continuous).
int PlotTradeoff(const PlotArgs& a) {
  std::vector<TradeoffCurve> curves;
  std::unique_ptr<RpcClient> client;
  for (const std::string& text : a.sources) {
    const ResultSource source = ParseResultSource(text);
    Json result;
    std::string where;
    if (source.job_id) {
      if (!client) client = std::make_unique<RpcClient>(a.server);
      result = client->Call("job.result", JobIdParams(*source.job_id));
      where = "job " + std::to_string(*source.job_id);
    } else {
      result = ReadResultFile(source.name);
      where = std::filesystem::path(source.name).filename().string();
    }
    const proto::StoredResult typed = TypedResult(result, where);
    if (typed.path.empty()) {
      throw InputError("continuous.path",
                       where +
                           " has no sparsity path: only strategy continuous (default on an "
                           "FEM reference) traces one");
    }
    TradeoffCurve curve;
    curve.label = where + ": " + Describe(typed);
    for (const auto& p : typed.path) curve.points.emplace_back(p.springs, p.rms_error);
    if (typed.chosen) curve.chosen = static_cast<std::size_t>(*typed.chosen);
    if (typed.rms_error)
      curve.returned = {static_cast<int>(typed.springs.size()), *typed.rms_error};
    curve.baseline_error = typed.baseline_rms_error;
    curve.baseline_springs = typed.baseline_springs;
    curves.push_back(std::move(curve));
  }
  const std::string title = a.title.empty() ? "Error against model size" : a.title;
  WriteSvg(a.output, RenderTradeoffPlot(curves, title));
  return kExitOk;
}

// A trace row's position along plot --x: wall seconds, generations or evaluations.
double XOf(const TraceRow& row, const std::string& x) {
  if (x == "generations") return row.generation;
  if (x == "evaluations") return static_cast<double>(row.evaluations);
  return row.wall_seconds;
}

ErrorCurve CurveOf(const std::vector<TraceRow>& rows, std::string label, const std::string& x) {
  ErrorCurve curve;
  curve.label = std::move(label);
  double best = std::numeric_limits<double>::infinity();
  for (const TraceRow& row : rows) {
    // Exact recovery as the search counts it (proto/RUN.md), drawn as 0.
    const double e = row.best_normalized_error <= kExactNormalizedError
                         ? 0.0
                         : std::sqrt(row.best_normalized_error);
    if (e < best || curve.points.empty()) curve.points.emplace_back(XOf(row, x), e);
    best = std::min(best, e);
  }
  // The last row too, so that a curve runs to the end of its run.
  if (!rows.empty() && curve.points.back().first < XOf(rows.back(), x)) {
    curve.points.emplace_back(XOf(rows.back(), x), best);
  }
  return curve;
}

int Plot(const PlotArgs& a) {
  if (a.tradeoff) return PlotTradeoff(a);
  std::vector<ErrorCurve> curves;
  std::unique_ptr<RpcClient> client;
  for (const std::string& text : a.sources) {
    const ResultSource source = ParseResultSource(text);
    std::vector<TraceRow> rows;
    std::string label;
    if (source.job_id) {
      if (!client) client = std::make_unique<RpcClient>(a.server);
      const Json job = client->Call("job.get", JobIdParams(*source.job_id));
      rows = FetchTrace(*client, *source.job_id);
      label = "job " + std::to_string(*source.job_id) + ": " +
              job.value("scene", std::string("?")) + ", strategy " +
              job.value("strategy", std::string("?")) + ", seed " + job["seed"].dump();
    } else {
      const proto::StoredResult result = TypedResult(ReadResultFile(source.name), source.name);
      if (!result.trace) {
        throw InputError(
            "",
            source.name + " has no trace: write the result with -o (springfit run -o, result -o)");
      }
      rows = *result.trace;
      label = std::filesystem::path(source.name).filename().string() + ": " + Describe(result);
    }
    if (rows.empty() && source.job_id) {
      throw RemoteError(proto::rpc::kWrongState, "job " + text + " has no trace rows yet (queued)",
                        nullptr);
    }
    if (rows.empty()) throw InputError("trace", source.name + ": the trace is empty");
    curves.push_back(CurveOf(rows, std::move(label), a.x));
  }
  ErrorPlotOptions options;
  const char* against = a.x == "generations"   ? "generations"
                        : a.x == "evaluations" ? "evaluations"
                                               : "wall time";
  options.x_label = a.x == "seconds" ? "wall time (s)" : against;
  const std::string title =
      a.title.empty() ? std::string("Normalized error against ") + against : a.title;
  WriteSvg(a.output, RenderErrorPlot(curves, title, options));
  return kExitOk;
}

}  // namespace

void RegisterFigureCommands(CLI::App& app, int& exit_code) {
  {
    auto args = std::make_shared<RenderArgs>();
    auto* cmd = app.add_subcommand(
        "render", "Draw the reference and the identified topology under each load case (SVG)");
    cmd->add_option("RESULT_OR_ID", args->source, "A result file (run -o, result -o) or a job id")
        ->required();
    cmd->add_option("-o,--output", args->output, "The SVG file to write")
        ->required()
        ->check(kSvgName);
    cmd->add_option("--scene", args->scene_path,
                    "The scene, for a result file that does not carry it");
    cmd->add_option("--case", args->load_cases, "Only this load case (repeatable; default: all)");
    cmd->add_option("--magnify", args->magnify,
                    "Draw displacements this many times their size (default: automatic)")
        ->check(CLI::PositiveNumber);
    cmd->add_flag("--node-numbers", args->node_numbers, "Write each node's index beside it");
    auto* rest = cmd->add_flag("--rest", args->rest,
                               "The two topologies at rest only, one pair of panels (the paper's "
                               "Figures 1 and 3)");
    rest->excludes(cmd->get_option("--case"));
    rest->excludes(cmd->get_option("--magnify"));
    AddServerFlags(cmd, args->server);
    cmd->callback([args, &exit_code] {
      exit_code = RunReportingErrors("render", [&] { return Render(*args); });
    });
  }
  {
    auto args = std::make_shared<PlotArgs>();
    auto* cmd = app.add_subcommand("plot",
                                   "Draw the best E against wall time, log scales, or with "
                                   "--tradeoff E against the number of springs (SVG)");
    cmd->add_option("RESULT_OR_ID", args->sources,
                    "Result files (run -o, result -o) or job ids, one curve each")
        ->required();
    cmd->add_option("-o,--output", args->output, "The SVG file to write")
        ->required()
        ->check(kSvgName);
    cmd->add_option("--title", args->title, "The plot's title");
    cmd->add_option("--x", args->x,
                    "The horizontal axis: seconds (wall time), generations (the paper's Figure "
                    "2) or evaluations")
        ->check(CLI::IsMember({"seconds", "generations", "evaluations"}))
        ->capture_default_str();
    cmd->add_flag("--tradeoff", args->tradeoff,
                  "The sparsity path instead (strategy continuous): E against springs, the "
                  "returned model and the closed-form baseline marked");
    AddServerFlags(cmd, args->server);
    cmd->callback([args, &exit_code] {
      exit_code = RunReportingErrors("plot", [&] { return Plot(*args); });
    });
  }
}

}  // namespace springfit::cli
