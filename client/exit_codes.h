// Exit codes of the springfit program (documented in README.md, "Exit codes").
#pragma once

#include "engine/api/result.h"

namespace springfit::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;       // an operation failed (I/O, unexpected error)
inline constexpr int kExitInvalidInput = 2;  // an invalid scene, topology file or option value
inline constexpr int kExitJobFailed = 3;     // the job failed (its error is printed)
inline constexpr int kExitNotFound = 4;      // no such job on the server
inline constexpr int kExitConnection = 5;  // the server cannot be reached, or the connection broke
inline constexpr int kExitUnauthorized = 6;  // the server wants a (different) token
inline constexpr int kExitCancelled = 7;     // the job was cancelled
inline constexpr int kExitBusy = 8;  // a server limit: queue full, too many connections, too large
inline constexpr int kExitWrongState = 9;  // e.g. the result of a job that has not finished
// run, submit --wait, watch, result: the result's verdict is unusable (engine/identification/
// verdict.h: a mechanism, no equilibrium, or worse than the rest shape); the result is still
// written.
inline constexpr int kExitUnusable = 10;
// run, submit --wait, watch, result: a usable model that does not meet a hard request (a spring
// budget, a target error); a WARNING line says which.
inline constexpr int kExitUnmetRequest = 11;
// run, submit --wait, watch, result: a usable model, every request met, that its certificate
// or its judgement as the simulator runs it finds worse than the closed-form recipe somewhere
// (or fitted to a linear reference past small strain); a WARNING line says each.
inline constexpr int kExitDoubtful = 12;
inline constexpr int kExitUsage = 64;  // bad command line (unknown option, missing argument)
inline constexpr int kExitInterrupted =
    130;  // stopped by SIGINT/SIGTERM (run: the result so far is still written)

// The exit code of a result's verdict: usable 0, unmet_request 11, unusable 10, doubtful 12.
inline int ExitCodeOfVerdict(Verdict verdict) {
  switch (verdict) {
    case Verdict::kUsable:
      return kExitOk;
    case Verdict::kUnmetRequest:
      return kExitUnmetRequest;
    case Verdict::kUnusable:
      return kExitUnusable;
    case Verdict::kDoubtful:
      return kExitDoubtful;
  }
  return kExitUnusable;
}

}  // namespace springfit::cli
