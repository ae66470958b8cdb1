// The error reporting every command shares.
#pragma once

#include <functional>
#include <string>

namespace springfit::cli {

// Runs `body`, turning an exception into one line on stderr and an exit code: an InputError
// ("springfit: FILE: path: message") into kExitInvalidInput, a lost or refused connection
// into kExitConnection, a server's error into its code's (ExitCodeOfRemoteError), anything
// else into kExitFailure.
int RunReportingErrors(const std::string& context, const std::function<int()>& body);

// The exit code of a JSON-RPC error code from the server (exit_codes.h).
int ExitCodeOfRemoteError(int code);

}  // namespace springfit::cli
