// springfitd's version: what server.info reports and what a checkpoint records of the engine
// that wrote it.
#pragma once

namespace springfit::server {

inline constexpr const char* kVersion = "0.3.0";

}  // namespace springfit::server
