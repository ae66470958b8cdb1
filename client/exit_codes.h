// Exit codes of the springfit program (documented in README.md, "Exit codes").
#pragma once

namespace springfit::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;       // an operation failed (I/O, unexpected error)
inline constexpr int kExitInvalidInput = 2;  // an invalid scene, topology file or option value
inline constexpr int kExitUsage = 64;
inline constexpr int kExitInterrupted = 130;  // stopped by SIGINT/SIGTERM (the result so far is still written)        // bad command line (unknown option, missing argument)

}  // namespace springfit::cli
