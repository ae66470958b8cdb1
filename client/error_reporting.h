// The error reporting every command shares.
#pragma once

#include <functional>
#include <string>




namespace springfit::cli {

// Runs `body`, turning an InputError into one line on stderr ("springfit: FILE: path:
// message") and kExitInvalidInput, and any other exception into kExitFailure.
int RunReportingErrors(const std::string& context, const std::function<int()>& body);

}  // namespace springfit::cli
